/* sd_studio.c -- WebAssembly entry points of the C runtime for the studio page.
 *
 * The page runs the C renderer (sd_render.c, sd_pad.c, sd_exact.c) unchanged; this file only
 * binds a table laid out by the page in linear memory and exposes the renderer's buffers.
 * One table and one renderer per instance: the AudioWorklet plays, a second instance on the
 * page's thread answers the hover read-out with the same lookup (sd_sample_slots).
 *
 * Memory: the page asks sdw_reserve(n) for n bytes past the static data (the linear memory
 * grows once if needed), writes the blocks and channel codes there and binds them; nothing
 * is allocated per tick. All positions in metres, times in seconds.
 */
#include <stddef.h>
#include <stdint.h>
#include "sd_runtime.h"

extern unsigned char __heap_base;

static sd_renderer_t R;
static sd_table_t T;
static sd_channel_t CH[SD_NSLOT];
static sd_config_t C;
static double samples[SD_NSLOT];

#define PAGE 65536u
/* Exported to JavaScript under the function's own name. */
#define SDW_EXPORT(name) __attribute__((export_name(#name)))

/* Address of n bytes of scratch memory (8-byte aligned), or 0 if the memory cannot grow. */
SDW_EXPORT(sdw_reserve) unsigned char *sdw_reserve(uint32_t n)
{
    uintptr_t base = ((uintptr_t)&__heap_base + 7u) & ~(uintptr_t)7u;
    uintptr_t need = base + (uintptr_t)n;
    uintptr_t have = (uintptr_t)__builtin_wasm_memory_size(0) * PAGE;
    if (need > have) {
        uintptr_t pages = (need - have + PAGE - 1u) / PAGE;
        if (__builtin_wasm_memory_grow(0, pages) == (size_t)-1) return 0;
    }
    return (unsigned char *)base;
}

/* Bind the grid and the block list (n_blocks x 5 int32 at `blocks`); clears every channel. */
SDW_EXPORT(sdw_table) void sdw_table(int32_t rows, int32_t cols, double dx, double dy, double x0, double y0, int32_t n_blocks,
               const int32_t *blocks)
{
    int s;
    T.rows = rows;
    T.cols = cols;
    T.dx = dx;
    T.dy = dy;
    T.x0 = x0;
    T.y0 = y0;
    T.n_blocks = n_blocks;
    T.blocks = (const int32_t (*)[5])blocks;
    for (s = 0; s < SD_NSLOT; s++) T.slot[s] = 0;
}

/* Bind renderer slot `slot` to codes of type dtype (SD_U8 .. SD_F64) at `codes`. */
SDW_EXPORT(sdw_channel) int sdw_channel(int slot, const void *codes, int dtype, double scale, double offset, double background)
{
    if (slot < 0 || slot >= SD_NSLOT || dtype < SD_U8 || dtype > SD_F64) return SD_ERR_ARG;
    CH[slot].codes = codes;
    CH[slot].dtype = dtype;
    CH[slot].scale = scale;
    CH[slot].offset = offset;
    CH[slot].background = background;
    T.slot[slot] = &CH[slot];
    return SD_OK;
}

/* Configure and initialise the renderer on the bound table; SD_OK or an SD_ERR_* code. */
SDW_EXPORT(sdw_init) int sdw_init(double mass, double stiffness, double damping, double burst_gain, double max_stick_period,
             double mu_s, double mu_k, double k_mu, double skin_target, double tick_rate, double audio_rate,
             double carrier_hz, double rise_s, double decay_s, int policy, int model)
{
    C.pad.mass = mass;
    C.pad.stiffness = stiffness;
    C.pad.damping = damping;
    C.pad.burst_gain = burst_gain;
    C.pad.max_stick_period = max_stick_period;
    C.mu_s = mu_s;
    C.mu_k = mu_k;
    C.k_mu = k_mu;
    C.skin_target = skin_target;
    C.tick_rate = tick_rate;
    C.audio_rate = audio_rate;
    C.carrier_hz = carrier_hz;
    C.rise_s = rise_s;
    C.decay_s = decay_s;
    C.policy = policy;
    C.model = model;
    return sd_renderer_init(&R, &T, &C);
}

SDW_EXPORT(sdw_reset) void sdw_reset(double t0) { sd_renderer_reset(&R, t0); }
SDW_EXPORT(sdw_step) double sdw_step(double x, double y) { return sd_renderer_step(&R, x, y); }

/* Buffers of the last tick: per-tick outputs (SD_NOUT values), audio samples, event ring. */
SDW_EXPORT(sdw_out) double *sdw_out(void) { return R.out; }
SDW_EXPORT(sdw_audio) double *sdw_audio(void) { return R.audio; }
SDW_EXPORT(sdw_n_audio) int32_t sdw_n_audio(void) { return (int32_t)R.n_audio; }
SDW_EXPORT(sdw_event_times) double *sdw_event_times(void) { return R.ev_t; }
SDW_EXPORT(sdw_event_amplitudes) double *sdw_event_amplitudes(void) { return R.ev_a; }
SDW_EXPORT(sdw_n_recent) int32_t sdw_n_recent(void) { return (int32_t)R.n_rec; }
SDW_EXPORT(sdw_clipped) double sdw_clipped(void) { return (double)R.clipped; }
SDW_EXPORT(sdw_n_out) int32_t sdw_n_out(void) { return SD_NOUT; }
SDW_EXPORT(sdw_n_slots) int32_t sdw_n_slots(void) { return SD_NSLOT; }

/* Bilinear value of every slot at (x, y): the hover read-out. */
SDW_EXPORT(sdw_sample) double *sdw_sample(double x, double y)
{
    sd_sample_slots(&T, x, y, samples);
    return samples;
}
