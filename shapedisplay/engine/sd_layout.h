/* sd_layout.h -- memory layouts and numberings shared with the Python runtime.
 *
 * GENERATED from shapedisplay/render/layouts.py and the model registry by `make generate`;
 * do not edit. tests/test_layouts.py checks that this file is current and that a C compiler
 * places every member at the offset numpy gives it. */
#ifndef SD_LAYOUT_H
#define SD_LAYOUT_H

#include <stdint.h>

/* sd_real: the real type of the runtime -- double in the reference build (bit-exact with the
 * Python records, whose reals are float64), float with -DSD_SINGLE (single-precision FPUs). */
#ifndef SD_REAL_DEFINED
#define SD_REAL_DEFINED
#ifdef SD_SINGLE
typedef float sd_real;
#else
typedef double sd_real;
#endif
#endif

/* pad models (ids shared with shapedisplay.render.models.MODELS) */
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

/* reactive widget kinds and reaction events (docs/reactive.md) */
enum { SD_REACT_NONE = 0, SD_REACT_BUTTON = 1, SD_REACT_TOGGLE = 2, SD_REACT_SLIDER = 3, SD_REACT_OBJECT = 4, SD_REACT_SURFACE = 5 };
enum { SD_EV_NONE = 0, SD_EV_PRESS = 1, SD_EV_RELEASE = 2, SD_EV_CLICK = 3, SD_EV_TOGGLE = 4, SD_EV_VALUE = 5, SD_EV_GRAB = 6, SD_EV_DROP = 7, SD_NEV = 8 };

/* PAD_STATE */
typedef struct {
    sd_real phase;                  /* 0 stick, 1 slip */
    sd_real x;                      /* spring stretch (pad displacement from rest relative to the finger), m */
    sd_real v;                      /* pad velocity, m/s */
    sd_real s;                      /* sign of the friction force in slip */
    sd_real f;                      /* friction force on the pad at the end of the last tick, N */
    sd_real age;                    /* time in the current stick phase while the surface moves, s */
    sd_real work_friction;          /* work of friction on the pad during the last tick, J (exact model) */
    sd_real work_damping;           /* energy dissipated by the damper during the last tick, J (exact model) */
    sd_real slip_left;              /* remaining slip time, s (jump model; inf = steady sliding) */
    sd_real x_restick;              /* spring stretch at the coming re-stick, m (jump model) */
    sd_real diverged_at;            /* time an explicit baseline blew up, s (when diverged != 0) */
    int64_t diverged;               /* 1 once an explicit baseline blew up (outputs frozen at zero) */
    int64_t truncated;              /* ticks cut at the safety cap on phase changes */
    int64_t n_events;               /* stick-to-slip events in the last tick */
    int64_t memo_valid;             /* 1 if the memo_* fields hold the last slip outcome (jump and exact models) */
    sd_real memo_s;                 /* memo input: slip direction */
    sd_real memo_x;                 /* memo input: spring stretch at breakaway (exact: at the slip start), m */
    sd_real memo_v;                 /* memo input: surface velocity, m/s */
    sd_real memo_muk;               /* memo input: kinetic coefficient */
    sd_real memo_n;                 /* memo input: normal force, N */
    sd_real memo_slip_time;         /* memo output: slip time, s */
    sd_real memo_x_restick;         /* memo output: spring stretch at re-stick (exact: from the slip equilibrium), m */
    sd_real slip_step;              /* next slip step the last one proposed, s (stribeck exponential steps; 0 = none) */
} sd_pad_state_t;
#define SD_FIELDS_PAD_STATE(X) \
    X(F64, phase) \
    X(F64, x) \
    X(F64, v) \
    X(F64, s) \
    X(F64, f) \
    X(F64, age) \
    X(F64, work_friction) \
    X(F64, work_damping) \
    X(F64, slip_left) \
    X(F64, x_restick) \
    X(F64, diverged_at) \
    X(I64, diverged) \
    X(I64, truncated) \
    X(I64, n_events) \
    X(I64, memo_valid) \
    X(F64, memo_s) \
    X(F64, memo_x) \
    X(F64, memo_v) \
    X(F64, memo_muk) \
    X(F64, memo_n) \
    X(F64, memo_slip_time) \
    X(F64, memo_x_restick) \
    X(F64, slip_step)

/* PAD_PARAMS */
typedef struct {
    sd_real mass;                   /* pad mass m, kg */
    sd_real stiffness;              /* pad stiffness k, N/m */
    sd_real damping;                /* pad damping c, N s/m */
    sd_real burst_gain;             /* B: burst amplitude per newton of breakaway force */
    sd_real max_stick_period;       /* force a slip after this long stuck, s (0 = off) */
    sd_real substep;                /* largest integration substep, s (stribeck, tanh) */
    sd_real karnopp_spring;         /* Karnopp virtual spring k_K, N/m */
    sd_real karnopp_v_threshold;    /* Karnopp re-stick speed v_T, m/s */
    sd_real stribeck_a;             /* Stribeck decay a */
    sd_real stribeck_b;             /* Stribeck viscous term b */
    sd_real stribeck_p;             /* pre-maximum slope p */
    sd_real stribeck_d;             /* pre-maximum width d */
    int64_t stribeck_variant;       /* 0 Stribeck curve, 1 with pre-maximum static region */
    sd_real stribeck_tol;           /* Stribeck slip: local error allowed per step, relative to the pad's scales */
    sd_real contactor_amplitude;    /* lateral contactor amplitude, m */
    sd_real contactor_omega;        /* lateral contactor angular frequency, rad/s */
    sd_real tanh_eps;               /* tanh regularisation width (breakaway slip speed), m/s */
} sd_pad_params_t;
#define SD_FIELDS_PAD_PARAMS(X) \
    X(F64, mass) \
    X(F64, stiffness) \
    X(F64, damping) \
    X(F64, burst_gain) \
    X(F64, max_stick_period) \
    X(F64, substep) \
    X(F64, karnopp_spring) \
    X(F64, karnopp_v_threshold) \
    X(F64, stribeck_a) \
    X(F64, stribeck_b) \
    X(F64, stribeck_p) \
    X(F64, stribeck_d) \
    X(I64, stribeck_variant) \
    X(F64, stribeck_tol) \
    X(F64, contactor_amplitude) \
    X(F64, contactor_omega) \
    X(F64, tanh_eps)

/* GRID */
typedef struct {
    int32_t rows;                   /* canvas samples along y */
    int32_t cols;                   /* canvas samples along x; sample (r, c) at (x0 + c dx, y0 + r dy) */
    sd_real dx;                     /* sample spacing along x, m */
    sd_real dy;                     /* sample spacing along y, m */
    sd_real x0;                     /* x of column 0, m */
    sd_real y0;                     /* y of row 0, m */
} sd_grid_t;
#define SD_FIELDS_GRID(X) \
    X(I32, rows) \
    X(I32, cols) \
    X(F64, dx) \
    X(F64, dy) \
    X(F64, x0) \
    X(F64, y0)

/* RENDER_CONFIG */
typedef struct {
    sd_pad_params_t pad;            /* pad model parameters */
    sd_real mu_s;                   /* device static friction coefficient */
    sd_real mu_k;                   /* device kinetic friction coefficient */
    sd_real k_mu;                   /* slope friction gain (table meta mapping.slope_friction_gain) */
    sd_real skin_target;            /* default skin-stretch target, m */
    sd_real normal_force_constant;  /* N of a table without a normal_force channel, N (C: the channel is required) */
    sd_real tick_rate;              /* Hz, 100 .. 192000 */
    sd_real audio_rate;             /* Hz, 1000 .. 384000 (C: 0 = no audio, drive per tick only) */
    sd_real carrier_hz;             /* burst carrier frequency, Hz */
    sd_real rise_s;                 /* burst envelope rise, s */
    sd_real decay_s;                /* burst envelope decay, s */
    int32_t policy;                 /* burst overlap policy (SD_RETRIGGER, SD_ADD, SD_MAX) */
    int32_t model;                  /* pad model id (SD_MODEL_*) */
} sd_config_t;
#define SD_FIELDS_RENDER_CONFIG(X) \
    X(PAD_PARAMS, pad) \
    X(F64, mu_s) \
    X(F64, mu_k) \
    X(F64, k_mu) \
    X(F64, skin_target) \
    X(F64, normal_force_constant) \
    X(F64, tick_rate) \
    X(F64, audio_rate) \
    X(F64, carrier_hz) \
    X(F64, rise_s) \
    X(F64, decay_s) \
    X(I32, policy) \
    X(I32, model)

/* RUN_STATE */
typedef struct {
    sd_real tick;                   /* ticks since reset (the next tick's number) */
    sd_real xp;                     /* cursor x at the previous tick, m */
    sd_real yp;                     /* cursor y at the previous tick, m */
    sd_real ax;                     /* pad axis x (follows the motion; a reversal gives a negative pad speed) */
    sd_real ay;                     /* pad axis y */
    sd_real t0;                     /* cursor time of tick 0, s */
    int64_t next_sample;            /* index of the next audio sample */
    int64_t n_recent;               /* bursts held in the event ring */
    int64_t clipped;                /* audio samples limited to full scale */
    int64_t events_total;           /* stick-to-slip events since reset */
    int64_t events_dropped;         /* events that did not fit the event ring */
    int64_t value_faults;           /* ticks with a non-finite value replaced: table products overflowing (played without contact), pad state reset, NaN drive played as 0, skin stretch as 0 */
} sd_run_state_t;
#define SD_FIELDS_RUN_STATE(X) \
    X(F64, tick) \
    X(F64, xp) \
    X(F64, yp) \
    X(F64, ax) \
    X(F64, ay) \
    X(F64, t0) \
    X(I64, next_sample) \
    X(I64, n_recent) \
    X(I64, clipped) \
    X(I64, events_total) \
    X(I64, events_dropped) \
    X(I64, value_faults)

/* OUTPUTS */
typedef struct {
    sd_real t;                      /* tick time, s */
    sd_real x;                      /* cursor x, m */
    sd_real y;                      /* cursor y, m */
    sd_real vx;                     /* cursor velocity x, m/s */
    sd_real vy;                     /* cursor velocity y, m/s */
    sd_real normal_force;           /* N */
    sd_real friction_force;         /* friction on the pad, N, signed along the pad axis */
    sd_real state;                  /* 0 stick, 1 slip at the end of the tick */
    sd_real lateral_x;              /* lateral-force cue x, N */
    sd_real lateral_y;              /* lateral-force cue y, N */
    sd_real skin_stretch;           /* skin stretch, m */
    sd_real events;                 /* stick-to-slip events in the tick */
    sd_real drive;                  /* burst drive at the tick time, in [-1, 1] */
    sd_real audio_samples;          /* audio samples written for the tick */
    sd_real pad_speed;              /* speed of the surface under the finger relative to it, along the pad axis, m/s */
    sd_real mu_s;                   /* static friction coefficient of the tick (device, table scale and slope term) */
    sd_real mu_k;                   /* kinetic friction coefficient of the tick */
    sd_real burst_gain;             /* burst-gain multiplier of the tick (table channel, 1 if absent) */
    sd_real press;                  /* press force of the tick, N (along z; 0 = not pressing) */
    sd_real reactions;              /* reaction events queued in the tick (press, release, click, ...) */
} sd_outputs_t;
#define SD_FIELDS_OUTPUTS(X) \
    X(F64, t) \
    X(F64, x) \
    X(F64, y) \
    X(F64, vx) \
    X(F64, vy) \
    X(F64, normal_force) \
    X(F64, friction_force) \
    X(F64, state) \
    X(F64, lateral_x) \
    X(F64, lateral_y) \
    X(F64, skin_stretch) \
    X(F64, events) \
    X(F64, drive) \
    X(F64, audio_samples) \
    X(F64, pad_speed) \
    X(F64, mu_s) \
    X(F64, mu_k) \
    X(F64, burst_gain) \
    X(F64, press) \
    X(F64, reactions)

/* BURST_STATE */
typedef struct {
    int64_t i_in;                   /* events entered (their time has passed) */
    int64_t i_mid;                  /* events whose burst turned from rise to decay (add) */
    int64_t i_out;                  /* events whose burst ended (add) */
    sd_real te;                     /* start of the playing envelope segment, s (retrigger, max) */
    sd_real e0;                     /* envelope at the segment's start (retrigger, max) */
    sd_real a;                      /* peak of the segment (retrigger, max) */
    sd_real tref;                   /* reference time of add's running sums, s */
    sd_real ra;                     /* add: sum of the rising bursts' peaks */
    sd_real rat;                    /* add: sum of peak * (event time - tref) of the rising bursts, s */
    sd_real q0;                     /* add: decays q0 - 2 q1 x + q2 x^2, x = (t - tref) / decay */
    sd_real q1;                     /* add: see q0 */
    sd_real q2;                     /* add: see q0 */
    sd_real cc;                     /* carrier cos at the last sample written */
    sd_real cs;                     /* carrier sin at the last sample written */
    int64_t cj;                     /* index + 1 of the last sample written (-1 before the first) */
    sd_real rc;                     /* rotation per sample: cos(2 pi carrier / audio rate) */
    sd_real rs;                     /* rotation per sample: sin(2 pi carrier / audio rate) */
} sd_burst_state_t;
#define SD_FIELDS_BURST_STATE(X) \
    X(I64, i_in) \
    X(I64, i_mid) \
    X(I64, i_out) \
    X(F64, te) \
    X(F64, e0) \
    X(F64, a) \
    X(F64, tref) \
    X(F64, ra) \
    X(F64, rat) \
    X(F64, q0) \
    X(F64, q1) \
    X(F64, q2) \
    X(F64, cc) \
    X(F64, cs) \
    X(I64, cj) \
    X(F64, rc) \
    X(F64, rs)

/* REACT_DEF */
typedef struct {
    int64_t kind;                   /* SD_REACT_* (what a press does; 0 = nothing) */
    int64_t widget;                 /* index of the widget in the table's scene widgets (an event's widget) */
    int64_t block;                  /* toggle: the block whose patch its state selects (-1 = none) */
    int64_t offset_a;               /* toggle: code offset of the patch of state 0 */
    int64_t offset_b;               /* toggle: code offset of the patch of state 1 */
    int64_t state0;                 /* toggle: state at reset (0 or 1) */
    int64_t part_row0;              /* moving part: canvas row of its patch at rest */
    int64_t part_col0;              /* moving part: canvas column of its patch at rest */
    int64_t part_rows;              /* moving part: rows of its patch (0 = the widget has no moving part) */
    int64_t part_cols;              /* moving part: columns of its patch */
    int64_t part_offset;            /* moving part: code offset of its patch */
    int64_t axis;                   /* slider: 0 the thumb runs along x, 1 along y */
    int64_t n_detents;              /* slider: detents on the track (0 = none) */
    int64_t key0;                   /* moving part: first keyframe */
    int64_t n_keys;                 /* moving part: keyframes (0 = none) */
    int64_t wrap;                   /* moving part: 1 = its content scrolls through its box at (vx, vy), wrapping */
    sd_real x0;                     /* box: left (m); a press inside the box (moved with the part) is the widget's */
    sd_real y0;                     /* box: bottom (m) */
    sd_real x1;                     /* box: right (m) */
    sd_real y1;                     /* box: top (m) */
    sd_real press_n;                /* press threshold, N (0 = the widget does not react to presses) */
    sd_real release_n;              /* release level, N (below press_n: the hysteresis) */
    sd_real click_gain;             /* click drive amplitude, full scale (0 = no click drive) */
    sd_real click_hz;               /* click drive frequency, Hz */
    sd_real click_s;                /* click drive duration, s */
    sd_real drop;                   /* click friction transient: fraction of N dropped at the click (0 = none) */
    sd_real drop_s;                 /* click friction transient: recovery time, s */
    sd_real track0;                 /* slider: lowest thumb centre along the axis, m */
    sd_real track_len;              /* slider: thumb travel, m (value = (centre - track0) / track_len) */
    sd_real thumb_c;                /* slider: thumb centre along the axis at reset, m */
    sd_real thumb_r;                /* slider: thumb radius, m (a press within it grabs the thumb) */
    sd_real cross_c;                /* slider: thumb centre across the axis, m */
    sd_real detent0;                /* slider: thumb centre at the first detent, m */
    sd_real detent_step;            /* slider: thumb travel between detents, m */
    sd_real value_step;             /* slider: change of value that makes a `value` event while dragging */
    sd_real vx;                     /* moving part: content velocity x, m/s (wrap) */
    sd_real vy;                     /* moving part: content velocity y, m/s (wrap) */
    sd_real loop_s;                 /* moving part: keyframe loop period, s (0 = hold the last keyframe) */
} sd_react_def_t;
#define SD_FIELDS_REACT_DEF(X) \
    X(I64, kind) \
    X(I64, widget) \
    X(I64, block) \
    X(I64, offset_a) \
    X(I64, offset_b) \
    X(I64, state0) \
    X(I64, part_row0) \
    X(I64, part_col0) \
    X(I64, part_rows) \
    X(I64, part_cols) \
    X(I64, part_offset) \
    X(I64, axis) \
    X(I64, n_detents) \
    X(I64, key0) \
    X(I64, n_keys) \
    X(I64, wrap) \
    X(F64, x0) \
    X(F64, y0) \
    X(F64, x1) \
    X(F64, y1) \
    X(F64, press_n) \
    X(F64, release_n) \
    X(F64, click_gain) \
    X(F64, click_hz) \
    X(F64, click_s) \
    X(F64, drop) \
    X(F64, drop_s) \
    X(F64, track0) \
    X(F64, track_len) \
    X(F64, thumb_c) \
    X(F64, thumb_r) \
    X(F64, cross_c) \
    X(F64, detent0) \
    X(F64, detent_step) \
    X(F64, value_step) \
    X(F64, vx) \
    X(F64, vy) \
    X(F64, loop_s)

/* REACT_KEY */
typedef struct {
    sd_real t;                      /* time from reset (within the loop), s; non-decreasing */
    sd_real dx;                     /* displacement of the part from rest, x, m */
    sd_real dy;                     /* displacement of the part from rest, y, m */
} sd_react_key_t;
#define SD_FIELDS_REACT_KEY(X) \
    X(F64, t) \
    X(F64, dx) \
    X(F64, dy)

/* REACT_STATE */
typedef struct {
    sd_real pressed;                /* 1 from a press on the widget until its release */
    sd_real state;                  /* toggle: the state whose patch plays (0 or 1) */
    sd_real grabbed;                /* 1 while the finger holds the widget (slider thumb, object) */
    sd_real dx;                     /* moving part: displacement from rest, x, m (wrap: content offset) */
    sd_real dy;                     /* moving part: displacement from rest, y, m */
    sd_real grab_x;                 /* cursor minus the part's displacement at the grab, x, m (slider: along the axis) */
    sd_real grab_y;                 /* cursor minus the part's displacement at the grab, y, m */
    sd_real thumb;                  /* slider: thumb centre along the axis, m */
    sd_real value;                  /* slider: (thumb - track0) / track_len, 0 .. 1 */
    sd_real reported;               /* slider: value of the last `value` event */
    sd_real region;                 /* slider: detents at or below the thumb centre */
    sd_real clock;                  /* moving part: time along its keyframes, s */
} sd_react_state_t;
#define SD_FIELDS_REACT_STATE(X) \
    X(F64, pressed) \
    X(F64, state) \
    X(F64, grabbed) \
    X(F64, dx) \
    X(F64, dy) \
    X(F64, grab_x) \
    X(F64, grab_y) \
    X(F64, thumb) \
    X(F64, value) \
    X(F64, reported) \
    X(F64, region) \
    X(F64, clock)

/* REACT_EVENT */
typedef struct {
    int64_t kind;                   /* SD_EV_* (press, release, click, toggle, value, grab, drop) */
    int64_t widget;                 /* widget index in the table's scene widgets */
    int64_t tick;                   /* tick number (time t0 + tick / tick_rate) */
    sd_real value;                  /* toggle: the new state; value: the slider's value; click: detent number (0 = a press click) */
} sd_react_event_t;
#define SD_FIELDS_REACT_EVENT(X) \
    X(I64, kind) \
    X(I64, widget) \
    X(I64, tick) \
    X(F64, value)

#endif
