/* sd_studio.c -- WebAssembly entry points of the C runtime for the studio page.
 *
 * The page runs the C runtime (sd_render.c, sd_pad.c, sd_exact.c, sd_image.c) unchanged; this
 * file only loads a binary table image (`shapedisplay export --format bin`) that the page put
 * in linear memory and exposes the renderer's buffers. One table and one renderer per
 * instance: the AudioWorklet plays, a second instance on the page's thread answers the hover
 * read-out with the same lookup (sd_sample_slots).
 *
 * Memory: the page asks sdw_reserve(n) for n bytes past the static data (the linear memory
 * grows if needed), copies the image there and calls sdw_load; sd_image_load binds the table
 * in place. Nothing is allocated per tick. All positions in metres, times in seconds.
 */
#include <stddef.h>
#include <stdint.h>
#include "sd_runtime.h"

extern unsigned char __heap_base;

static sd_image_t IMG;
static sd_renderer_t R;
static sd_config_t C;
static double samples[SD_NSLOT];

#define PAGE 65536u
/* Exported to JavaScript under the function's own name. */
#define SDW_EXPORT(name) __attribute__((export_name(#name)))

/* Address of n bytes of scratch memory (8-byte aligned, as images must be), or 0 if the
 * memory cannot grow. */
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

/* Load the table image of `size` bytes at `data` (from sdw_reserve) and initialise the renderer
 * with the image's settings, the given tick and audio rates, burst policy and pad model.
 * Returns SD_OK, an SD_ERR_IMAGE_* code (the image) or an SD_ERR_* code (the renderer). */
SDW_EXPORT(sdw_load) int sdw_load(const void *data, uint32_t size, double tick_rate, double audio_rate, int policy,
                                  int model)
{
    int rc = sd_image_load(&IMG, data, size);
    if (rc != SD_OK) return rc;
    sd_image_config(&IMG, &C);
    C.tick_rate = tick_rate;
    C.audio_rate = audio_rate;
    C.policy = policy;
    C.model = model;
    return sd_renderer_init(&R, &IMG.table, &C);
}

/* Bind the image for the read-out only (no renderer). */
SDW_EXPORT(sdw_bind) int sdw_bind(const void *data, uint32_t size) { return sd_image_load(&IMG, data, size); }

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
    sd_sample_slots(&IMG.table, x, y, samples);
    return samples;
}
