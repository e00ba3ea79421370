/* sd_layout.h -- memory layouts and numberings shared with the Python runtime.
 *
 * GENERATED from shapedisplay/runtime/layouts.py and the model registry by `make generate`;
 * do not edit. tests/test_layouts.py checks that this file is current and that a C compiler
 * places every member at the offset numpy gives it. */
#ifndef SD_LAYOUT_H
#define SD_LAYOUT_H

#include <stdint.h>

/* pad models (ids shared with shapedisplay.runtime.models.MODELS) */
enum {
    SD_MODEL_EXACT = 0,
    SD_MODEL_JUMP = 1,
    SD_MODEL_KARNOPP = 2,
    SD_MODEL_STRIBECK = 3,
    SD_MODEL_EULER = 4,
    SD_MODEL_RK4 = 5,
    SD_MODEL_TANH = 6,
    SD_NMODEL = 7
};

/* burst overlap policies */
enum { SD_RETRIGGER = 0, SD_ADD = 1, SD_MAX = 2 };

/* renderer slots: the table channels the renderer reads */
enum {
    SD_SLOT_NORMAL_FORCE = 0,
    SD_SLOT_FRICTION_SCALE = 1,
    SD_SLOT_BURST_GAIN = 2,
    SD_SLOT_GRAD_X = 3,
    SD_SLOT_GRAD_Y = 4,
    SD_SLOT_LATERAL_X = 5,
    SD_SLOT_LATERAL_Y = 6,
    SD_SLOT_SKIN_STRETCH = 7,
    SD_SLOT_BREAKAWAY_FORCE = 8,
    SD_SLOT_KINETIC_FORCE = 9,
    SD_NSLOT = 10
};

/* PAD_STATE */
typedef struct {
    double phase;                   /* 0 stick, 1 slip */
    double x;                       /* spring stretch (pad displacement from rest relative to the finger), m */
    double v;                       /* pad velocity, m/s */
    double s;                       /* sign of the friction force in slip */
    double f;                       /* friction force on the pad at the end of the last tick, N */
    double age;                     /* time in the current stick phase while the surface moves, s */
    double work_friction;           /* work of friction on the pad during the last tick, J (exact model) */
    double work_damping;            /* energy dissipated by the damper during the last tick, J (exact model) */
    double slip_left;               /* remaining slip time, s (jump model; inf = steady sliding) */
    double x_restick;               /* spring stretch at the coming re-stick, m (jump model) */
    double diverged_at;             /* time an explicit baseline blew up, s (when diverged != 0) */
    int64_t diverged;               /* 1 once an explicit baseline blew up (outputs frozen at zero) */
    int64_t truncated;              /* ticks cut at the safety cap on phase changes */
    int64_t n_events;               /* stick-to-slip events in the last tick */
    int64_t memo_valid;             /* 1 if the memo_* fields hold the last re-stick of the jump model */
    double memo_s;                  /* memo input: slip direction */
    double memo_x;                  /* memo input: spring stretch at breakaway, m */
    double memo_v;                  /* memo input: surface velocity, m/s */
    double memo_muk;                /* memo input: kinetic coefficient */
    double memo_n;                  /* memo input: normal force, N */
    double memo_slip_time;          /* memo output: slip time, s */
    double memo_x_restick;          /* memo output: spring stretch at re-stick, m */
} sd_pad_state_t;

/* PAD_PARAMS */
typedef struct {
    double mass;                    /* pad mass m, kg */
    double stiffness;               /* pad stiffness k, N/m */
    double damping;                 /* pad damping c, N s/m */
    double burst_gain;              /* B: burst amplitude per newton of breakaway force */
    double max_stick_period;        /* force a slip after this long stuck, s (0 = off) */
    double substep;                 /* largest integration substep, s (stribeck, tanh) */
    double karnopp_spring;          /* Karnopp virtual spring k_K, N/m */
    double karnopp_v_threshold;     /* Karnopp re-stick speed v_T, m/s */
    double stribeck_a;              /* Stribeck decay a */
    double stribeck_b;              /* Stribeck viscous term b */
    double stribeck_p;              /* pre-maximum slope p */
    double stribeck_d;              /* pre-maximum width d */
    int64_t stribeck_variant;       /* 0 Stribeck curve, 1 with pre-maximum static region */
    double contactor_amplitude;     /* lateral contactor amplitude, m */
    double contactor_omega;         /* lateral contactor angular frequency, rad/s */
    double tanh_eps;                /* tanh regularisation width (breakaway slip speed), m/s */
} sd_pad_params_t;

/* GRID */
typedef struct {
    int32_t rows;                   /* canvas samples along y */
    int32_t cols;                   /* canvas samples along x; sample (r, c) at (x0 + c dx, y0 + r dy) */
    double dx;                      /* sample spacing along x, m */
    double dy;                      /* sample spacing along y, m */
    double x0;                      /* x of column 0, m */
    double y0;                      /* y of row 0, m */
} sd_grid_t;

/* RENDER_CONFIG */
typedef struct {
    sd_pad_params_t pad;            /* pad model parameters */
    double mu_s;                    /* device static friction coefficient */
    double mu_k;                    /* device kinetic friction coefficient */
    double k_mu;                    /* slope friction gain (table meta mapping.slope_friction_gain) */
    double skin_target;             /* default skin-stretch target, m */
    double normal_force_constant;   /* N of a table without a normal_force channel, N (C: the channel is required) */
    double tick_rate;               /* Hz, 100 .. 192000 */
    double audio_rate;              /* Hz, 1000 .. 384000 (C: 0 = no audio, drive per tick only) */
    double carrier_hz;              /* burst carrier frequency, Hz */
    double rise_s;                  /* burst envelope rise, s */
    double decay_s;                 /* burst envelope decay, s */
    int32_t policy;                 /* burst overlap policy (SD_RETRIGGER, SD_ADD, SD_MAX) */
    int32_t model;                  /* pad model id (SD_MODEL_*) */
} sd_config_t;

/* RUN_STATE */
typedef struct {
    double tick;                    /* ticks since reset (the next tick's number) */
    double xp;                      /* cursor x at the previous tick, m */
    double yp;                      /* cursor y at the previous tick, m */
    double ax;                      /* pad axis x (follows the motion; a reversal gives a negative pad speed) */
    double ay;                      /* pad axis y */
    double t0;                      /* cursor time of tick 0, s */
    int64_t next_sample;            /* index of the next audio sample */
    int64_t n_recent;               /* bursts held in the event ring */
    int64_t clipped;                /* audio samples limited to full scale */
    int64_t events_total;           /* stick-to-slip events since reset */
    int64_t events_dropped;         /* events that did not fit the event ring */
} sd_run_state_t;

/* OUTPUTS */
typedef struct {
    double t;                       /* tick time, s */
    double x;                       /* cursor x, m */
    double y;                       /* cursor y, m */
    double vx;                      /* cursor velocity x, m/s */
    double vy;                      /* cursor velocity y, m/s */
    double normal_force;            /* N */
    double friction_force;          /* friction on the pad, N, signed along the pad axis */
    double state;                   /* 0 stick, 1 slip at the end of the tick */
    double lateral_x;               /* lateral-force cue x, N */
    double lateral_y;               /* lateral-force cue y, N */
    double skin_stretch;            /* skin stretch, m */
    double events;                  /* stick-to-slip events in the tick */
    double drive;                   /* burst drive at the tick time, in [-1, 1] */
    double audio_samples;           /* audio samples written for the tick */
    double pad_speed;               /* surface speed along the pad axis, m/s */
} sd_outputs_t;

/* BURST_STATE */
typedef struct {
    int64_t i_in;                   /* events entered (their time has passed) */
    int64_t i_mid;                  /* events whose burst turned from rise to decay (add) */
    int64_t i_out;                  /* events whose burst ended (add) */
    double te;                      /* start of the playing envelope segment, s (retrigger, max) */
    double e0;                      /* envelope at the segment's start (retrigger, max) */
    double a;                       /* peak of the segment (retrigger, max) */
    double tref;                    /* reference time of add's running sums, s */
    double ra;                      /* add: sum of the rising bursts' peaks */
    double rat;                     /* add: sum of peak * (event time - tref) of the rising bursts, s */
    double q0;                      /* add: decays q0 - 2 q1 x + q2 x^2, x = (t - tref) / decay */
    double q1;                      /* add: see q0 */
    double q2;                      /* add: see q0 */
    double cc;                      /* carrier cos at the last sample written */
    double cs;                      /* carrier sin at the last sample written */
    int64_t cj;                     /* index + 1 of the last sample written (-1 before the first) */
    double rc;                      /* rotation per sample: cos(2 pi carrier / audio rate) */
    double rs;                      /* rotation per sample: sin(2 pi carrier / audio rate) */
} sd_burst_state_t;

#endif
