/* sd_wasm.c -- the WebAssembly face of the runtime (sd_runtime.wasm, built by `make wasm`).
 *
 * One renderer per module instance, all state static. The module imports nothing (no WASI
 * calls are referenced), so an AudioWorklet instantiates it with an empty import object;
 * sd_wasm.js wraps these exports. Pointers are byte offsets into the module's memory.
 *
 *   sd_wasm_stage(bytes)         where to write a table image of `bytes` bytes (8-aligned); never
 *                                the active table's bytes, so a bad image leaves the playing table intact
 *   sd_wasm_load(ptr, size)      validate and bind the image written at ptr (sd_image_load). On
 *                                success it becomes the active table (the first one's settings become
 *                                the configuration; later ones keep model, policy, rates and a pad block
 *                                given to configure) and the renderer restarts; on failure the previous
 *                                table keeps playing.
 *   sd_wasm_scratch(bytes)       scratch memory after the active image, for sd_wasm_run's arrays
 *                                (valid until the next sd_wasm_stage)
 *   sd_wasm_pad_block(n)         where to write the pad parameters of the next sd_wasm_configure: n doubles,
 *                                the fields of sd_pad_params_t in order (PAD_PARAMS in layouts.py, as the Python
 *                                model derives them: shapedisplay.studio.wasm.table_payload); 0 if n is not
 *                                SD_NPAD. The image carries only the basic pad parameters: models other than
 *                                exact and jump play from such a block.
 *   sd_wasm_configure(model, policy, tick_rate, audio_rate)   override settings and restart; with the pad
 *                                parameters written after sd_wasm_pad_block if it was called since the last
 *                                configure, else the present ones (the image's, or the last block given for
 *                                this model: SD_ERR_ARG for a model other than exact and jump without one)
 *   sd_wasm_set(index, value)    override one stored setting (SD_IP_* index); restart
 *   sd_wasm_step(x, y)           one tick at cursor (x, y) m; returns the drive
 *   sd_wasm_run(xy, n, outs, audio, cap)   n ticks from xy[2n]; per-tick outputs to outs[n][15]
 *                                (0 = not wanted), audio samples to audio[cap]; returns samples
 *                                written (-1: cap too small, stopped before the tick that would overflow)
 *   sd_wasm_outputs(), sd_wasm_audio(), sd_wasm_audio_count()   last tick's outputs / samples
 *   sd_wasm_audio_cap()          most samples one tick writes (ceil(audio_rate / tick_rate) + 2)
 *   sd_wasm_counter(i)           0 clipped, 1 events, 2 events dropped, 3 position faults, 4 ticks
 *   sd_wasm_tick_events()        stick-to-slip events of the last tick (those still in the event ring);
 *   sd_wasm_event_times(), sd_wasm_event_amplitudes()   where their times (s) and amplitudes start
 *   sd_wasm_sample(x, y)         bilinear value of every slot (SD_NSLOT doubles) at (x, y) m: a read-out
 *                                with the renderer's own lookup
 *   sd_wasm_step_press(x, y, p)  one tick at cursor (x, y) m pressing with p N (docs/reactive.md)
 *   sd_wasm_restart(t0)          a new run keeping the reactive widgets' states (a flipped toggle stays flipped)
 *   sd_wasm_react_count()        reaction events waiting in the queue
 *   sd_wasm_react_pop()          the oldest as 4 doubles {kind (SD_EV_*), widget, t (s), value}, 0 if none
 *   sd_wasm_react_n(), sd_wasm_react_states()   reactive widgets played, and their states: n records of
 *                                SD_NREACT_STATE doubles (REACT_STATE fields in order)
 *
 * Real-time rule: after load/configure nothing allocates or grows memory; a step is bounded work.
 */
#include <stdint.h>
#include <string.h>
#include "sd_runtime.h"

/* per-tick outputs as an array of doubles (sd_outputs_t holds reals only, sd_layout.h); the
 * single-precision build (-DSD_SINGLE, for tests) widens them into double mirrors */
#define SD_NOUT ((int32_t)(sizeof(sd_outputs_t) / sizeof(sd_real)))

#define EXPORT(name) __attribute__((export_name(#name)))

static sd_image_t img, staged;
static sd_renderer_t R;
static sd_config_t cfg;
static int loaded, ready;
static double samples[SD_NSLOT];

/* the pad parameters as a block of doubles, one per field of sd_pad_params_t (integers as exact doubles) */
#define SD_COUNT_FIELD(kind, name) +1
#define SD_NPAD (0 SD_FIELDS_PAD_PARAMS(SD_COUNT_FIELD))
static double pad_in[SD_NPAD];
static int pad_given;       /* sd_wasm_pad_block called since the last configure */
static int pad_model = -1;  /* the model whose block cfg.pad holds (-1: the image's parameters) */
#ifdef SD_SINGLE
static double out_d[SD_NOUT], audio_d[SD_AUDIO_BLOCK_MAX], ev_t_d[SD_EVENT_RING], ev_a_d[SD_EVENT_RING];

static void widen_outputs(double *dst, const sd_outputs_t *o)
{
    int n = 0;
#define SD_WIDEN(kind, name) dst[n++] = (double)o->name;
    SD_FIELDS_OUTPUTS(SD_WIDEN)
#undef SD_WIDEN
}
#endif
static uintptr_t act_lo, act_hi;          /* the active image's bytes */

extern unsigned char __heap_base;

static uintptr_t align8(uintptr_t p) { return (p + 7u) & ~(uintptr_t)7u; }

/* Make [p, p + bytes) part of linear memory (set-up only: memory.grow). */
static uint32_t region(uintptr_t p, uint32_t bytes)
{
    uintptr_t have = (uintptr_t)__builtin_wasm_memory_size(0) * 65536u, need = p + bytes;
    if (bytes > (1u << 30)) return 0;
    if (need > have && __builtin_wasm_memory_grow(0, (need - have + 65535u) / 65536u) == (size_t)-1) return 0;
    return (uint32_t)p;
}

EXPORT(sd_wasm_stage) uint32_t sd_wasm_stage(uint32_t bytes)
{
    uintptr_t base = align8((uintptr_t)&__heap_base);
    if (act_hi == 0 || base + bytes <= act_lo) return region(base, bytes);
    return region(align8(act_hi), bytes);
}

EXPORT(sd_wasm_scratch) uint32_t sd_wasm_scratch(uint32_t bytes)
{
    uintptr_t base = align8((uintptr_t)&__heap_base);
    return region(align8(act_hi > base ? act_hi : base), bytes);
}

static int restart(void)
{
    int rc = sd_renderer_init(&R, &img.table, &cfg);
    ready = rc == SD_OK;
    return rc;
}

EXPORT(sd_wasm_load) int sd_wasm_load(uint32_t ptr, uint32_t size)
{
    int rc = sd_image_load(&staged, (const void *)(uintptr_t)ptr, size), s;
    if (rc != SD_OK) return rc;                    /* the active table is untouched */
    img = staged;
    for (s = 0; s < SD_NSLOT; s++)                 /* the copy's slots point at its own channels */
        if (img.table.slot[s]) img.table.slot[s] = &img.ch[s];
    act_lo = ptr;
    act_hi = (uintptr_t)ptr + size;
    if (!loaded) {
        sd_image_config(&img, &cfg);
    } else {                                       /* a table swapped into a running player */
        sd_config_t keep = cfg;
        sd_image_config(&img, &cfg);
        if (pad_model >= 0) cfg.pad = keep.pad;
        cfg.model = keep.model;
        cfg.policy = keep.policy;
        cfg.tick_rate = keep.tick_rate;
        cfg.audio_rate = keep.audio_rate;
    }
    loaded = 1;
    return restart();
}

EXPORT(sd_wasm_pad_block) uint32_t sd_wasm_pad_block(int32_t n)
{
    if (n != SD_NPAD) return 0;
    pad_given = 1;
    return (uint32_t)(uintptr_t)pad_in;
}

/* cfg.pad from the block, field by field; SD_ERR_PARAM (nothing changed) for a NaN, or for an integer
 * field that is not a whole number within +-2^53 */
static int take_pad_block(void)
{
    sd_pad_params_t p;
    int k = 0;
#define SD_TAKE_F64(name) if (pad_in[k] != pad_in[k]) return SD_ERR_PARAM; p.name = (sd_real)pad_in[k++];
#define SD_TAKE_I64(name) if (!(pad_in[k] >= -9007199254740992.0 && pad_in[k] <= 9007199254740992.0) \
        || pad_in[k] != (double)(int64_t)pad_in[k]) return SD_ERR_PARAM; p.name = (int64_t)pad_in[k++];
#define SD_TAKE(kind, name) SD_TAKE_##kind(name)
    SD_FIELDS_PAD_PARAMS(SD_TAKE)
#undef SD_TAKE
#undef SD_TAKE_I64
#undef SD_TAKE_F64
    cfg.pad = p;
    return SD_OK;
}

EXPORT(sd_wasm_configure) int sd_wasm_configure(int model, int policy, double tick_rate, double audio_rate)
{
    int given = pad_given, rc;
    pad_given = 0;
    if (!loaded) return SD_ERR_ARG;
    if (given) {
        if ((rc = take_pad_block()) != SD_OK) return rc;
        pad_model = model;
    } else if (model != SD_MODEL_EXACT && model != SD_MODEL_JUMP && model != pad_model) {
        return SD_ERR_ARG;                         /* the image does not carry this model's parameters */
    }
    cfg.model = model;
    cfg.policy = policy;
    cfg.tick_rate = (sd_real)tick_rate;
    cfg.audio_rate = (sd_real)audio_rate;
    return restart();
}

EXPORT(sd_wasm_set) int sd_wasm_set(int index, double value)
{
    sd_real *p[] = {&cfg.pad.mass, &cfg.pad.stiffness, &cfg.pad.damping, &cfg.pad.burst_gain,
                   &cfg.pad.max_stick_period, &cfg.mu_s, &cfg.mu_k, &cfg.k_mu, &cfg.skin_target, &cfg.tick_rate,
                   &cfg.audio_rate, &cfg.carrier_hz, &cfg.rise_s, &cfg.decay_s};
    if (!loaded || index < 0 || index >= (int)(sizeof p / sizeof p[0])) return SD_ERR_ARG;
    *p[index] = (sd_real)value;
    return restart();
}

EXPORT(sd_wasm_reset) void sd_wasm_reset(double t0)
{
    if (ready) sd_renderer_reset(&R, (sd_real)t0);
}

/* A new run that keeps the reactive widgets' states (sd_react_restart). */
EXPORT(sd_wasm_restart) void sd_wasm_restart(double t0)
{
    if (ready) sd_react_restart(&R, (sd_real)t0);
}

EXPORT(sd_wasm_step) double sd_wasm_step(double x, double y)
{
    return ready ? (double)sd_renderer_step(&R, (sd_real)x, (sd_real)y) : 0.0;
}

EXPORT(sd_wasm_run) int32_t sd_wasm_run(uint32_t xy_ptr, int32_t n, uint32_t outs_ptr, uint32_t audio_ptr, int32_t cap)
{
    const double *xy = (const double *)(uintptr_t)xy_ptr;
    double *outs = (double *)(uintptr_t)outs_ptr, *audio = (double *)(uintptr_t)audio_ptr;
    int32_t i, written = 0;
    if (!ready || n < 0) return -1;
    for (i = 0; i < n; i++) {
        if (written + R.audio_cap > cap) return -1;
        sd_renderer_step(&R, (sd_real)xy[2 * i], (sd_real)xy[2 * i + 1]);
#ifdef SD_SINGLE
        if (outs) widen_outputs(outs + (size_t)i * SD_NOUT, &R.out);
        if (audio && R.n_audio > 0) {
            long a;
            for (a = 0; a < R.n_audio; a++) audio[written + a] = (double)R.audio[a];
            written += (int32_t)R.n_audio;
        }
#else
        if (outs) memcpy(outs + (size_t)i * SD_NOUT, &R.out, sizeof R.out);
        if (audio && R.n_audio > 0) {
            memcpy(audio + written, R.audio, (size_t)R.n_audio * sizeof(double));
            written += (int32_t)R.n_audio;
        }
#endif
    }
    return written;
}

#ifdef SD_SINGLE
EXPORT(sd_wasm_outputs) uint32_t sd_wasm_outputs(void)
{
    widen_outputs(out_d, &R.out);
    return (uint32_t)(uintptr_t)out_d;
}
EXPORT(sd_wasm_audio) uint32_t sd_wasm_audio(void)
{
    long a;
    for (a = 0; a < R.n_audio; a++) audio_d[a] = (double)R.audio[a];
    return (uint32_t)(uintptr_t)audio_d;
}
#else
EXPORT(sd_wasm_outputs) uint32_t sd_wasm_outputs(void) { return (uint32_t)(uintptr_t)&R.out; }
EXPORT(sd_wasm_audio) uint32_t sd_wasm_audio(void) { return (uint32_t)(uintptr_t)R.audio; }
#endif
EXPORT(sd_wasm_audio_count) int32_t sd_wasm_audio_count(void) { return ready ? (int32_t)R.n_audio : 0; }
EXPORT(sd_wasm_audio_cap) int32_t sd_wasm_audio_cap(void) { return ready ? (int32_t)R.audio_cap : 0; }
EXPORT(sd_wasm_n_outputs) int32_t sd_wasm_n_outputs(void) { return SD_NOUT; }
EXPORT(sd_wasm_param) double sd_wasm_param(int index)
{
    return loaded && index >= 0 && index < SD_IMAGE_NPARAM ? img.params[index] : 0.0;
}

EXPORT(sd_wasm_counter) double sd_wasm_counter(int which)
{
    switch (which) {
    case 0: return (double)R.run.clipped;
    case 1: return (double)R.run.events_total;
    case 2: return (double)R.run.events_dropped;
    case 3: return (double)R.position_faults;
    case 4: return (double)R.run.tick;
    default: return 0.0;
    }
}

/* The last tick's new events are the newest entries of the renderer's event ring. */
EXPORT(sd_wasm_tick_events) int32_t sd_wasm_tick_events(void)
{
    long n = ready ? (long)R.out.events : 0;
    return (int32_t)(n < R.run.n_recent ? n : R.run.n_recent);
}
#ifdef SD_SINGLE
/* absolute times in double (the ring counts from the epoch in this build) */
EXPORT(sd_wasm_event_times) uint32_t sd_wasm_event_times(void)
{
    long i, n = sd_wasm_tick_events(), i0 = (long)R.run.n_recent - n;
    for (i = 0; i < n; i++) ev_t_d[i] = sd_event_time(&R, i0 + i);
    return (uint32_t)(uintptr_t)ev_t_d;
}
EXPORT(sd_wasm_event_amplitudes) uint32_t sd_wasm_event_amplitudes(void)
{
    long i, n = sd_wasm_tick_events(), i0 = (long)R.run.n_recent - n;
    for (i = 0; i < n; i++) ev_a_d[i] = (double)R.ev_a[i0 + i];
    return (uint32_t)(uintptr_t)ev_a_d;
}
#else
EXPORT(sd_wasm_event_times) uint32_t sd_wasm_event_times(void)
{
    return (uint32_t)(uintptr_t)(R.ev_t + (R.run.n_recent - sd_wasm_tick_events()));
}
EXPORT(sd_wasm_event_amplitudes) uint32_t sd_wasm_event_amplitudes(void)
{
    return (uint32_t)(uintptr_t)(R.ev_a + (R.run.n_recent - sd_wasm_tick_events()));
}
#endif

EXPORT(sd_wasm_step_press) double sd_wasm_step_press(double x, double y, double press)
{
    return ready ? (double)sd_renderer_step_press(&R, (sd_real)x, (sd_real)y, (sd_real)press) : 0.0;
}

#define SD_NREACT_STATE (0 SD_FIELDS_REACT_STATE(SD_COUNT_FIELD))
static double react_ev[4], react_st[SD_MAX_REACTIVE * SD_NREACT_STATE];

EXPORT(sd_wasm_react_count) int32_t sd_wasm_react_count(void) { return ready ? (int32_t)R.react.count : 0; }

EXPORT(sd_wasm_react_pop) uint32_t sd_wasm_react_pop(void)
{
    sd_react_event_t e;
    if (!ready || !sd_react_pop(&R, &e)) return 0;
    react_ev[0] = (double)e.kind;
    react_ev[1] = (double)e.widget;
    react_ev[2] = sd_react_event_time(&R, &e);
    react_ev[3] = (double)e.value;
    return (uint32_t)(uintptr_t)react_ev;
}

EXPORT(sd_wasm_react_n) int32_t sd_wasm_react_n(void) { return ready ? R.react.n : 0; }
EXPORT(sd_wasm_react_state_size) int32_t sd_wasm_react_state_size(void) { return SD_NREACT_STATE; }

EXPORT(sd_wasm_react_states) uint32_t sd_wasm_react_states(void)
{
    int i, k = 0;
    for (i = 0; ready && i < R.react.n; i++) {
        const sd_react_state_t *st = &R.react.state[i];
#define SD_WIDEN_STATE(kind, name) react_st[k++] = (double)st->name;
        SD_FIELDS_REACT_STATE(SD_WIDEN_STATE)
#undef SD_WIDEN_STATE
    }
    return (uint32_t)(uintptr_t)react_st;
}

EXPORT(sd_wasm_sample) uint32_t sd_wasm_sample(double x, double y)
{
    int s;
    if (!loaded) {
        for (s = 0; s < SD_NSLOT; s++) samples[s] = 0.0;
    } else {
        sd_real v[SD_NSLOT];
        sd_sample_slots(&img.table, (sd_real)x, (sd_real)y, v);
        for (s = 0; s < SD_NSLOT; s++) samples[s] = (double)v[s];
    }
    return (uint32_t)(uintptr_t)samples;
}
