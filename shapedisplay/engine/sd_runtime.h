/* sd_runtime.h -- portable C99 runtime of the shapedisplay stick-slip renderer.
 *
 * Plays a friction-envelope table: bilinear table lookup, every pad model, and the
 * vibrotactile burst at every stick-to-slip event. The one implementation of the renderer:
 * the Python package binds it (shapedisplay.render.Renderer), the studio runs its
 * WebAssembly build, firmware includes this header.
 *
 * Real-time rules: all memory is provided by the caller (tables are const arrays, e.g. from
 * `shapedisplay export --format c`, or a buffer received over the device link); nothing is
 * allocated after sd_renderer_init; sd_renderer_tick does bounded work per stick-slip
 * event and never blocks. Units are SI (m, s, N, kg, Hz).
 */
#ifndef SD_RUNTIME_H
#define SD_RUNTIME_H

#include <stddef.h>
#include <stdint.h>
#include "sd_layout.h"

#ifdef __cplusplus
extern "C" {
#endif

/* Phase changes (stick or slip phases) one pad tick may take: at most SD_PHASES_BASE + h * phase_rate
 * (sd_pad_t; phase_rate = 4 omega / pi, omega the damped frequency of the pad, or its natural frequency
 * when it is not under-damped), never more than SD_MAX_EVENTS_PER_TICK. A stick-slip cycle is two
 * phases and its slip lasts at least a quarter of the damped period, pi / (2 omega): a tick of length h
 * holds at most 4 h omega / pi of them, plus the phases cut by the tick's edges. A tick that reaches the
 * cap stops there and counts it (pad state `truncated`). Measured on a
 * sweep of V up to 1000 m/s, N up to 1000 N, h up to 10 ms: at most 0.25 of the cap; the degenerate pad
 * (exact model, c = 0, mu_k = mu_s, under reversals) takes no zero-length phases either. */
#define SD_PHASES_BASE 32
#define SD_MAX_EVENTS_PER_TICK 200000L
/* Newton/bisection steps of the exact model's re-stick polish (measured at most 46 in double) */
#define SD_POLISH_MAX 64

/* ------------------------------------------------------------------ pad model */
/* The parameters (sd_pad_params_t) and the state (sd_pad_state_t) of a pad model are laid out in
 * sd_layout.h, generated from the Python runtime's definitions (shapedisplay/render/layouts.py). */

/* A pad model's parameters with the constants derived from them at load (sd_pad_prepare). */
typedef struct {
    sd_pad_params_t p;
    sd_real sig, wn2, disc, wd, tp, e_tp;   /* c/2m, k/m, sig^2 - wn2, damped frequency, pi/wd, exp(-sig tp) */
    sd_real sq;                            /* sqrt(disc) of an over-damped pad (disc > 0), else 0 */
    sd_real phase_rate;                    /* 4 omega / pi: bound on phase changes per second (SD_PHASES_BASE) */
    int under;                             /* under-damped (disc < 0) */
} sd_pad_t;

/* A fresh state: stuck, spring relaxed, no normal-force cap. */
void sd_pad_reset(sd_pad_state_t *S);
/* Copy the parameters and compute the derived pad constants; required before a tick. */
void sd_pad_prepare(sd_pad_t *P, const sd_pad_params_t *params);

/* One tick of a pad model: advance [t0, t0 + h] at surface velocity V (m/s), normal force N,
 * coefficients mus/muk and burst-gain multiplier gain. Stick-to-slip events (time s, burst
 * amplitude) are written to ev_t/ev_a[n_ev..cap-1]; returns the new event count (it may exceed
 * cap: the extra events are counted, not stored). */
typedef int (*sd_tick_fn)(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                          sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev);

/* The quasi-static jump model. */
int sd_jump_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                 sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev);

/* The exact event-driven pad model. */
int sd_exact_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                  sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev);

/* The Imaizumi pad with Stribeck friction on a vibrating contactor, plain curve and pre-maximum variant
 * (sd_stribeck.c). */
int sd_stribeck_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                     sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev);

/* The modified Karnopp virtual spring, every event located inside the tick (sd_karnopp.c). */
int sd_karnopp_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                    sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev);

/* The comparison baselines of the accuracy and stability reports (sd_baselines.c): the Konyo pad with
 * tanh-regularised Coulomb friction and one explicit step per tick, forward Euler
 * or RK4, which set the state's `diverged` when they blow up. */
int sd_tanh_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                 sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev);
int sd_euler_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                  sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev);
int sd_rk4_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev);

/* The tick function of model id SD_MODEL_*, or NULL if the C runtime does not implement it. */
sd_tick_fn sd_model_tick(int model);

/* Closed-form slip outcome : slip time (inf = steady sliding) and the
 * spring stretch at re-stick. */
void sd_jump_restick(sd_real m, sd_real c, sd_real k, sd_real s, sd_real xb, sd_real V, sd_real muk, sd_real N,
                     sd_real *slip_time, sd_real *x_restick);

/* ------------------------------------------------------------------ tables */
/* Code types of a stored channel (value = offset + scale * code; float channels store values). */
enum { SD_U8 = 0, SD_U16 = 1, SD_F32 = 2, SD_F64 = 3 };

typedef struct {
    const void *codes;     /* n_values codes, all patches back to back */
    int dtype;             /* SD_U8 .. SD_F64 */
    sd_real scale, offset;  /* value = offset + scale * code (integer codes) */
    sd_real background;     /* value outside every block */
} sd_channel_t;

/* A friction-envelope table: the arrays of `shapedisplay export --format c` plug in directly:
 *   sd_channel_t n = {NAME_normal_force_codes, SD_U16, NAME_normal_force_scale, ...};
 *   sd_table_t T = {{NAME_ROWS, NAME_COLS, NAME_dx_m, NAME_dy_m, NAME_x0_m, NAME_y0_m},
 *                   NAME_N_BLOCKS, NAME_blocks, {&n, 0, ...}};                                  */
typedef struct {
    sd_grid_t grid;                     /* canvas: rows, cols, spacing, origin (sd_layout.h) */
    int32_t n_blocks;
    const int32_t (*blocks)[5];         /* row0, col0, rows, cols, offset; never overlapping */
    const sd_channel_t *slot[SD_NSLOT]; /* NULL = channel not stored */
    /* Optional coarse index of the blocks (O(1) lookup; a table image always has one). With
     * tile_start NULL a lookup scans the blocks. Canvas tile (i, j) covers rows
     * [i*tile_rows, (i+1)*tile_rows) and cols [j*tile_cols, ...); it lists the blocks overlapping it:
     * tile_list[tile_start[i*tiles_x + j] .. tile_start[i*tiles_x + j + 1] - 1]. */
    int32_t tile_rows, tile_cols, tiles_y, tiles_x;
    const uint32_t *tile_start, *tile_list;
    /* Optional reactive widgets (docs/reactive.md): n_react definitions and the keyframes of their moving
     * parts; a table image's reaction section (sd_image_load) or a header's NAME_react arrays. None:
     * n_react 0 (a table that plays as before, whatever the press). */
    int32_t n_react, n_react_keys;
    const sd_react_def_t *react;
    const sd_react_key_t *react_keys;
} sd_table_t;

sd_real sd_channel_value(const sd_channel_t *ch, long idx);
long sd_cell_index(const sd_table_t *T, long r, long c);
void sd_sample_slots(const sd_table_t *T, sd_real x, sd_real y, sd_real *out);
/* As sd_sample_slots, with n_ov blocks read at other code offsets: block ov_block[i] at ov_off[i] (a toggle in
 * its other state). */
void sd_sample_slots_ov(const sd_table_t *T, sd_real x, sd_real y, sd_real *out, const int32_t *ov_block,
                        const int32_t *ov_off, int n_ov);
sd_real sd_envelope(sd_real tau, sd_real rise, sd_real decay);
/* A tick's model inputs from the slot values sampled at the cursor (vals[SD_NSLOT]; a slot the table does
 * not store is read from the settings): normal force N >= 0, static and kinetic coefficients (table scale
 * or forces, plus the one-sided slope term along the motion (vx, vy) at `speed`; mu_k <= mu_s) and the
 * burst-gain multiplier. */
void sd_derive(const sd_table_t *T, const sd_config_t *C, const sd_real *vals, sd_real vx, sd_real vy, sd_real speed,
               sd_real *N_out, sd_real *mus_out, sd_real *muk_out, sd_real *gain_out);
#ifndef SD_SINGLE
/* Offline burst audio of sorted events (times s, peak amplitudes) with the renderer's bursts and carrier:
 * n samples at t_start + j / rate into out, or the envelope alone (envelope_only); returns samples clipped. */
long sd_render_events(const sd_real *ev_t, const sd_real *ev_a, long n_ev, sd_real t_start, sd_real rate,
                      int64_t n, sd_real carrier, sd_real rise, sd_real decay, int policy, int envelope_only,
                      sd_real *out);
#endif

/* ------------------------------------------------------------------ renderer */
#ifndef SD_EVENT_RING
#define SD_EVENT_RING 4096      /* bursts remembered (smaller saves RAM) */
#endif
#ifndef SD_AUDIO_BLOCK_MAX
#define SD_AUDIO_BLOCK_MAX 4096 /* audio samples per tick, >= ceil(audio_rate / tick_rate) + 2 */
#endif
#ifndef SD_MAX_REACTIVE
#define SD_MAX_REACTIVE 32      /* reactive widgets played; a table's further ones are counted, not played */
#endif
#ifndef SD_MAX_KEYS
#define SD_MAX_KEYS 64          /* keyframes a table image may hold (all moving parts together) */
#endif
#ifndef SD_REACT_QUEUE
#define SD_REACT_QUEUE 64       /* reaction events held until the host takes them (oldest dropped beyond) */
#endif
/* Detent ticks one tick may fire (a thumb dragged across more detents in one tick fires this many). */
#define SD_DETENTS_PER_TICK 4

enum { SD_OK = 0, SD_ERR_ARG = -1, SD_ERR_TABLE = -2, SD_ERR_PARAM = -3 };

/* Largest h * omega_n = sqrt(stiffness / mass) / tick_rate of a pad (devices.H_OMEGA_MAX): sd_renderer_init refuses more. */
#define SD_H_OMEGA_MAX 1000.0

/* Cursor positions farther than this from the origin (m), and non-finite ones, are faults: the
 * renderer holds the last valid position and counts them (position_faults). */
#ifndef SD_POSITION_LIMIT_M
#define SD_POSITION_LIMIT_M 1000.0   /* (a double constant: the runtime casts it to sd_real) */
#endif

/* The renderer settings (sd_config_t), its counters (sd_run_state_t) and per-tick outputs
 * (sd_outputs_t) are laid out in sd_layout.h, as the Python renderer's records. cfg.model is an
 * SD_MODEL_* id of a model with a C tick (sd_model_tick); cfg.audio_rate 0 = no audio. */
#ifdef SD_SINGLE
/* The time base of the single-precision build. A float cannot hold absolute times (at 1000 s its
 * resolution is 61 us, half a 10 kHz tick), so ticks and audio samples are counted in integers and
 * every real time of the tick path (event times, the burst state) is measured from an epoch, a tick
 * at most about 62.5 ms back (1 s for rates whose ratio needs it) that moves on by epoch_ticks: the
 * live event times are then shifted by the epoch's length (at most SD_EVENT_RING / 2 subtractions,
 * once per epoch). The carrier phase is a 64-bit fixed-point fraction of a cycle, exact modulo 2^64,
 * so the phase error after n samples is n 2^-54 cycles (1e-8 after a day at 48 kHz). */
typedef struct {
    int64_t tick;                 /* ticks since reset (the next tick's number) */
    int64_t epoch;                /* the tick whose time is 0 for ev_t and the burst state */
    int64_t epoch_sample;         /* audio sample index at the epoch (an exact sample time) */
    int64_t epoch_ticks;          /* ticks per epoch: a multiple of tick_rate / gcd(tick_rate, audio_rate) */
    int64_t epoch_samples;        /* audio samples per epoch: epoch_ticks * audio_rate / tick_rate */
    int64_t sample_floor;         /* floor(tick * audio_rate / tick_rate) */
    uint32_t sample_rem;          /* (tick * audio_rate) mod tick_rate */
    uint32_t tick_hz, audio_hz;   /* the rates, integers in this build */
    uint64_t dphase_sample;       /* carrier phase per audio sample, 2^-64 cycles */
    uint64_t dphase_tick;         /* carrier phase per tick, 2^-64 cycles */
    int64_t drive_k;              /* tick of the carrier (dc, ds) below, -1 none */
    sd_real h, inv_audio, epoch_s;   /* 1 / tick rate, 1 / audio rate, epoch length (s) */
    sd_real dc, ds;               /* carrier cos/sin at tick drive_k */
    sd_real tick_rc, tick_rs;     /* carrier rotation per tick */
} sd_clock_t;
#endif

/* The reactions of a renderer (docs/reactive.md): the widgets' states (REACT_STATE, sd_layout.h), the
 * event queue, the press and the click in progress. Part of sd_renderer_t, so owned by the caller; sized
 * at compile time (SD_MAX_REACTIVE, SD_REACT_QUEUE), nothing allocated. */
typedef struct {
    int32_t n;                              /* reactive widgets played: min(table n_react, SD_MAX_REACTIVE) */
    int32_t skipped;                        /* the table's reactive widgets beyond SD_MAX_REACTIVE (not played) */
    int32_t n_parts, n_ov;                  /* widgets with a moving part; toggles in their other state */
    int32_t part[SD_MAX_REACTIVE];          /* their indices */
    int32_t ov_block[SD_MAX_REACTIVE], ov_off[SD_MAX_REACTIVE];   /* block -> code offset of the state playing */
    int32_t held;                           /* the widget the finger holds (slider thumb, object), -1 none */
    int32_t on_part;                        /* the moving part under the finger in the last tick, -1 none */
    sd_react_state_t state[SD_MAX_REACTIVE];
    sd_real press;                          /* press force of the last tick, N */
    /* the click in progress (the last one started): drive a sin(w tau) (1 - tau / T) for 0 <= tau < T, and
     * N times 1 - d (1 - tau / T_d) for 0 < tau < T_d, tau = t - click_t (the time base of the event ring) */
    int32_t click_on;
    sd_real click_t, click_a, click_w, click_s, drop, drop_s;
    /* the event queue: a ring of SD_REACT_QUEUE events, `count` from `head` (sd_react_pop) */
    sd_react_event_t queue[SD_REACT_QUEUE];
    int64_t head, count, total, dropped;    /* dropped: the oldest events overwritten while the queue was full */
    int64_t tick_events;                    /* events queued in the last tick */
} sd_react_t;

typedef struct {
    const sd_table_t *table;
    sd_config_t cfg;
    sd_pad_t pad_model;                 /* cfg.pad with its derived constants */
    sd_tick_fn tick_fn;                 /* sd_model_tick(cfg.model) */
    sd_pad_state_t pad;
    sd_run_state_t run;                 /* 64-bit counters on every target (int64_t) */
    int64_t position_faults;            /* cursor samples held (non-finite or beyond the limit) */
    sd_real rot_cos, rot_sin;            /* carrier rotation per audio sample (set by sd_renderer_init) */
    long n_audio, audio_cap;
    sd_real ev_t[SD_EVENT_RING], ev_a[SD_EVENT_RING];
    sd_real audio[SD_AUDIO_BLOCK_MAX];   /* audio samples of the last tick: audio[0 .. n_audio-1] */
    sd_outputs_t out;                   /* outputs of the last tick */
    sd_burst_state_t bursts;            /* burst envelope and carrier (sd_layout.h; bursts.py) */
#ifdef SD_SINGLE
    sd_clock_t clock;                   /* integer tick and sample counts, epoch of the real times */
#endif
    sd_react_t react;                   /* reactive widgets: states, event queue, press, click */
} sd_renderer_t;

/* The carrier is re-anchored with sin/cos every this many audio samples (bursts.CARRIER_BLOCK). */
#define SD_CARRIER_BLOCK 64

/* sizeof(sd_renderer_t), for bindings that allocate it from another language. */
size_t sd_renderer_size(void);
/* Validate and bind; returns SD_OK or an SD_ERR_* code. No allocation here or later. */
int sd_renderer_init(sd_renderer_t *R, const sd_table_t *table, const sd_config_t *cfg);
/* Start a new run at cursor time t0 (s). */
void sd_renderer_reset(sd_renderer_t *R, sd_real t0);
/* Continue as if `tick` ticks had been played with the cursor resting at (x, y) m: counters and
 * time move on, the pad is at rest, no burst sounds (long sessions, tests of the counters). */
void sd_renderer_seek(sd_renderer_t *R, int64_t tick, sd_real x, sd_real y);
/* Absolute time (s) of the event in ring slot i (0 <= i < run.n_recent): ev_t holds absolute times in
 * the reference build and times from the epoch in the single-precision build. For hosts and tests:
 * it computes in double, outside the tick path. */
double sd_event_time(const sd_renderer_t *R, long i);
/* One tick with the cursor at (x, y) metres; returns the burst drive in [-1, 1]. Not pressing: as
 * sd_renderer_step_press(R, x, y, 0). */
sd_real sd_renderer_step(sd_renderer_t *R, sd_real x, sd_real y);
/* One tick with the cursor at (x, y) metres pressing with force `press` (N, along z; not finite or < 0:
 * 0). The table's reactive widgets react (docs/reactive.md): events go to the queue (sd_react_pop), a
 * state change (toggle flipped, thumb or object moved) plays from the next tick, moving parts move. */
sd_real sd_renderer_step_press(sd_renderer_t *R, sd_real x, sd_real y, sd_real press);

/* ------------------------------------------------------------------ reactions (sd_react.c) */
/* Take the oldest queued reaction event into *ev: 1, or 0 when the queue is empty. */
int sd_react_pop(sd_renderer_t *R, sd_react_event_t *ev);
/* Time (s) of an event's tick: t0 + tick / tick_rate, in double (for hosts; outside the tick path). */
double sd_react_event_time(const sd_renderer_t *R, const sd_react_event_t *ev);
/* Start a new run at t0 (as sd_renderer_reset) that keeps every reactive widget where it is: a toggle's state,
 * a thumb or object where it was dropped, a moving part's position; nothing pressed or held (a host that
 * starts a run per stroke, as the studio does). */
void sd_react_restart(sd_renderer_t *R, sd_real t0);
/* Private to the renderer (sd_render.c calls them): bind and reset the states; the slot values at (xm, ym)
 * with toggles, moving parts and the held part, and the velocity of the surface under the finger (a tick of
 * length h); the press handling at the end of a tick at time t; the click drive at time t. */
void sd_react_reset(sd_renderer_t *R);
void sd_react_lookup(sd_renderer_t *R, sd_real xm, sd_real ym, sd_real h, sd_real *vals, sd_real *svx, sd_real *svy);
void sd_react_update(sd_renderer_t *R, sd_real x, sd_real y, sd_real press, sd_real t, sd_real h, int64_t tick);
sd_real sd_react_click(const sd_react_t *K, sd_real t);

/* ------------------------------------------------------------------ table image */
/* The flat binary table image (`shapedisplay export TABLE --format bin`, docs/table-image.md):
 * little-endian, versioned, closed by a CRC-32. sd_image_load validates it (every size and
 * offset is bounded before use) and binds an sd_table_t whose arrays point into the image:
 * nothing is copied or allocated. The image must stay in place while the table is used and
 * start at an 8-byte aligned address. */
#define SD_IMAGE_VERSION 2            /* the version written with reactions; version 1 images load too */
#define SD_IMAGE_HEADER_SIZE 560       /* version 1 header */
#define SD_IMAGE_HEADER_SIZE_V2 576    /* version 2: the version 1 header, then the reaction section's place */
#define SD_IMAGE_NPARAM 16
/* Renderer settings stored in the image (runtime/image.py PARAMS). */
enum {
    SD_IP_MASS, SD_IP_STIFFNESS, SD_IP_DAMPING, SD_IP_BURST_GAIN, SD_IP_MAX_STICK, SD_IP_MU_S, SD_IP_MU_K,
    SD_IP_K_MU, SD_IP_SKIN_TARGET, SD_IP_TICK_RATE, SD_IP_AUDIO_RATE, SD_IP_CARRIER, SD_IP_RISE, SD_IP_DECAY,
    SD_IP_NORMAL_FORCE
};
enum {
    SD_ERR_IMAGE_SIZE = -10,     /* shorter than a header, or the size field disagrees */
    SD_ERR_IMAGE_MAGIC = -11,    /* not a table image */
    SD_ERR_IMAGE_VERSION = -12,  /* another format version */
    SD_ERR_IMAGE_CRC = -13,      /* corrupt */
    SD_ERR_IMAGE_LAYOUT = -14,   /* a count, offset or index out of bounds */
    SD_ERR_IMAGE_ALIGN = -15,    /* image not 8-byte aligned in memory */
    SD_ERR_IMAGE_VALUE = -16,    /* a non-finite or out-of-range value */
    SD_ERR_IMAGE_ENDIAN = -17,   /* big-endian host: the codes cannot be used in place */
    SD_ERR_IMAGE_RANGE = -18     /* a channel decodes values beyond sd_real (offset +/- scale x the largest code of
                                    its type), or a grid spacing or origin beyond SD_POSITION_LIMIT_M */
};

typedef struct {
    sd_table_t table;                 /* bound to the image's arrays */
    sd_channel_t ch[SD_NSLOT];        /* table.slot[s] points here when slot s is stored */
    double params[SD_IMAGE_NPARAM];    /* SD_IP_* settings (as stored: float64) */
    int32_t n_values, max_tile_blocks;
    uint32_t image_size;
    const char *meta;                 /* the table file's JSON header (not NUL-terminated) */
    uint32_t meta_len;
    /* the reaction section, converted to sd_real (table.react points here): the first SD_MAX_REACTIVE
     * widgets; react_total counts them all */
    int32_t react_total;
    sd_react_def_t react[SD_MAX_REACTIVE];
    sd_react_key_t react_keys[SD_MAX_KEYS];
} sd_image_t;

/* CRC-32 (IEEE 802.3, as zlib) of n bytes; bitwise, no table (8 shifts per byte). */
uint32_t sd_crc32(const void *data, size_t n);
/* Validate the image of `size` bytes at `data` and bind img->table. Returns SD_OK or SD_ERR_IMAGE_*. */
int sd_image_load(sd_image_t *img, const void *data, size_t size);
/* sizeof(sd_image_t), for bindings that allocate it from another language. */
size_t sd_image_size(void);
/* A renderer configuration from the image's settings (jump model, retrigger policy). */
void sd_image_config(const sd_image_t *img, sd_config_t *cfg);

#ifdef __cplusplus
}
#endif

#endif /* SD_RUNTIME_H */
