/* fuzz_engine.c -- libFuzzer harness of the C engine: a table image from the input, then a run of
 * ticks with cursor samples from the input. Built for either precision (make fuzz: -DSD_SINGLE too)
 * with -fsanitize=fuzzer,address,undefined.
 *
 * Input: a 16-byte control block, the image, the cursor samples.
 *   [0]     flags: bit 0 keep the image's size field and CRC as given (else they are made right, so
 *           that mutations reach the checks behind the CRC); bit 1 no audio; bit 2 press: the press
 *           force of each tick is read from the input too (a byte, 0 .. 5.1 N), so the reactive
 *           widgets of an image (version 2) are pressed, released, dragged
 *   [1]     pad model (SD_MODEL_*, modulo SD_NMODEL). The models whose work per tick is bounded by
 *           step caps rather than by the tick (tanh: SD_MAX_EVENTS_PER_TICK substeps of a stiff
 *           regularised slope, about 15 ms a tick under the sanitizers; Stribeck: up to 10^5 stick
 *           steps and 2 x 10^4 slip steps, up to 250 ms a tick) get at most SLOW_TICKS and
 *           STRIBECK_TICKS ticks, so that a run of them stays far below the timeout and the fuzzer's
 *           time goes to many inputs, not a few long ones
 *   [2]     burst policy (modulo 3)
 *   [3]     cursor mode (modulo 3): 0 int16 pairs across the table and a margin around it,
 *           1 int16 pairs over +-1 km (jumps inside the position limit), 2 raw sd_real pairs
 *           (NaN, inf, anything)
 *   [4..5]  ticks (u16, at most MAX_TICKS)
 *   [8..11] image length in bytes (u32; cut to what the input holds)
 * A run holds the last sample when the input has no more.
 *
 * What it checks beyond the sanitizers: sd_image_load returns SD_OK or an SD_ERR_IMAGE_* code; a
 * loaded image decodes finite values everywhere (offset + scale x code, background); every output
 * of every tick is finite for any cursor input, the drive and audio samples within [-1, 1]; every
 * reaction event names a kind SD_EV_PRESS .. SD_EV_DROP, the tick played and a finite value, and
 * every reactive widget's state stays finite.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include "../sd_runtime.h"
#include "../sd_math.h"

#define MAX_TICKS 256
#define SLOW_TICKS 8      /* ticks of a tanh run */
#define STRIBECK_TICKS 2  /* ticks of a Stribeck run: one tick of it can take 250 ms under the sanitizers */
#define MAX_IMAGE (1u << 20)

static uint64_t image_buf[MAX_IMAGE / 8];     /* 8-byte aligned, as the loader needs */
static sd_image_t img;
static sd_renderer_t R;

static uint32_t le32(const uint8_t *p)
{
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

static void put32(uint8_t *p, uint32_t v)
{
    p[0] = (uint8_t)v;
    p[1] = (uint8_t)(v >> 8);
    p[2] = (uint8_t)(v >> 16);
    p[3] = (uint8_t)(v >> 24);
}

/* CRC-32 by table (the loader's bitwise one is the one under test; this only makes inputs pass it) */
static uint32_t crc32_fast(const uint8_t *p, size_t n)
{
    static uint32_t table[256];
    static int ready;
    uint32_t c = 0xFFFFFFFFu;
    size_t i;
    if (!ready) {
        uint32_t k, v;
        int b;
        for (k = 0; k < 256; k++) {
            v = k;
            for (b = 0; b < 8; b++) v = (v >> 1) ^ (0xEDB88320u & (0u - (v & 1u)));
            table[k] = v;
        }
        ready = 1;
    }
    for (i = 0; i < n; i++) c = table[(c ^ p[i]) & 0xFFu] ^ (c >> 8);
    return ~c;
}

static int finite_r(sd_real v) { return isfinite(v); }

/* a failed check names itself, then aborts (libFuzzer keeps the input as a crash) */
#define check(ok) do { if (!(ok)) { fprintf(stderr, "fuzz_engine: check failed, line %d: %s\n", __LINE__, #ok); \
                                    abort(); } } while (0)

/* Every value a loaded image can hand the renderer is finite (the loader's range rule). */
static void check_decoded(void)
{
    int s;
    long i;
    for (s = 0; s < SD_NSLOT; s++) {
        const sd_channel_t *ch = img.table.slot[s];
        if (!ch) continue;
        check(finite_r(sd_channel_value(ch, -1)));
        for (i = 0; i < img.n_values; i++) check(finite_r(sd_channel_value(ch, i)));
    }
}

static sd_real sample(const uint8_t **p, const uint8_t *end, int mode, sd_real held, double lo, double span)
{
    if (mode == 2) {
        sd_real v;
        if ((size_t)(end - *p) < sizeof v) return held;
        memcpy(&v, *p, sizeof v);
        *p += sizeof v;
        return v;
    } else {
        int16_t q;
        uint16_t u;
        if (end - *p < 2) return held;
        u = (uint16_t)((*p)[0] | (*p)[1] << 8);
        memcpy(&q, &u, sizeof q);
        *p += 2;
        return (sd_real)(lo + span * ((double)q / 32768.0));
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    uint8_t *img_bytes = (uint8_t *)image_buf;
    const uint8_t *p, *end = data + size;
    sd_config_t cfg;
    uint32_t n_img;
    int flags, mode, rc, k, n_ticks;
    double cx, cy, sx, sy;
    sd_real x = SD_R(0.0), y = SD_R(0.0);
    long j;
    if (size < 16) return 0;
    flags = data[0];
    mode = data[3] % 3;
    n_ticks = (int)((data[4] | data[5] << 8) % (MAX_TICKS + 1));
    n_img = le32(data + 8);
    if (n_img > size - 16) n_img = (uint32_t)(size - 16);
    if (n_img > MAX_IMAGE) n_img = MAX_IMAGE;
    memcpy(img_bytes, data + 16, n_img);
    if (!(flags & 1) && n_img >= SD_IMAGE_HEADER_SIZE + 4 && (n_img & 3u) == 0) {
        put32(img_bytes + 8, n_img);
        put32(img_bytes + n_img - 4, crc32_fast(img_bytes, n_img - 4));
    }
    rc = sd_image_load(&img, img_bytes, n_img);
    check(rc == SD_OK || (rc <= SD_ERR_IMAGE_SIZE && rc >= SD_ERR_IMAGE_RANGE));
    if (rc != SD_OK) return 0;
    check_decoded();

    sd_image_config(&img, &cfg);
    cfg.model = data[1] % SD_NMODEL;
    if (cfg.model == SD_MODEL_TANH && n_ticks > SLOW_TICKS) n_ticks = SLOW_TICKS;
    if (cfg.model == SD_MODEL_STRIBECK && n_ticks > STRIBECK_TICKS) n_ticks = STRIBECK_TICKS;
    cfg.policy = data[2] % 3;
    if (flags & 2) cfg.audio_rate = SD_R(0.0);
    /* A pad the tick cannot resolve (h omega_n > SD_H_OMEGA_MAX: the exact model would search thousands of
     * acceleration zeros a slip; 2.6e34 N/m on 1e-6 kg ran a tick for ever) must be refused at init. */
    rc = sd_renderer_init(&R, &img.table, &cfg);
    if ((double)cfg.pad.stiffness > (double)cfg.pad.mass * (SD_H_OMEGA_MAX * SD_H_OMEGA_MAX)
                                    * (double)cfg.tick_rate * (double)cfg.tick_rate)
        check(rc != SD_OK);
    if (rc != SD_OK) return 0;

    /* mode 0: the table and half its size around it; mode 1: +-1 km */
    sx = (double)img.table.grid.dx * (double)img.table.grid.cols;
    sy = (double)img.table.grid.dy * (double)img.table.grid.rows;
    cx = (double)img.table.grid.x0 + 0.5 * sx;
    cy = (double)img.table.grid.y0 + 0.5 * sy;
    if (mode == 1) {
        cx = cy = 0.0;
        sx = sy = 1000.0;
    }
    p = data + 16 + n_img;
    for (k = 0; k < n_ticks; k++) {
        sd_real d, press = SD_R(0.0);
        const sd_outputs_t *o = &R.out;
        sd_react_event_t ev;
        int w;
        x = sample(&p, end, mode, x, cx, sx);
        y = sample(&p, end, mode, y, cy, sy);
        if ((flags & 4) && p < end) press = (sd_real)(*p++) * SD_R(0.02);
        d = (flags & 4) ? sd_renderer_step_press(&R, x, y, press) : sd_renderer_step(&R, x, y);
        while (sd_react_pop(&R, &ev)) {
            check(ev.kind >= SD_EV_PRESS && ev.kind <= SD_EV_DROP && ev.widget >= 0 && ev.tick == (int64_t)k);
            check(finite_r(ev.value));
        }
        for (w = 0; w < R.react.n; w++) {
            const sd_react_state_t *st = &R.react.state[w];
            check(finite_r(st->dx) && finite_r(st->dy) && finite_r(st->thumb) && finite_r(st->value)
                  && finite_r(st->clock));
        }
        check(finite_r(o->press) && finite_r(o->reactions));
        check(d >= -SD_R(1.0) && d <= SD_R(1.0));
        check(finite_r(o->t) && finite_r(o->x) && finite_r(o->y) && finite_r(o->vx) && finite_r(o->vy));
        check(finite_r(o->normal_force) && finite_r(o->friction_force) && finite_r(o->lateral_x)
              && finite_r(o->lateral_y) && finite_r(o->skin_stretch) && finite_r(o->pad_speed)
              && finite_r(o->mu_s) && finite_r(o->mu_k) && finite_r(o->burst_gain));
        for (j = 0; j < R.n_audio; j++) check(R.audio[j] >= -SD_R(1.0) && R.audio[j] <= SD_R(1.0));
        check(R.pad.f == R.pad.f && R.pad.x == R.pad.x);
    }
    return 0;
}
