/* tool_play_header.c -- play a table compiled into the program from its C header export.
 *
 * This is how firmware binds a table: export it with
 *     shapedisplay export TABLE --format c -o table.h --name sd_table
 * and compile this file (or your firmware's equivalent) with
 *     cc -std=c99 -O2 -ffp-contract=off -DSD_TABLE_HEADER='"table.h"' \
 *        tool_play_header.c sd_render.c sd_pad.c sd_exact.c -lm
 * The header must carry the device parameters (tables compiled for a device profile do).
 * If the table's mapping uses direction-dependent friction, add -DSD_TABLE_K_MU=sd_table_slope_friction_gain.
 *
 *   sd_play_header AUDIO_RATE IN OUT
 * IN: i64 n, f64 x[n], f64 y[n] (cursor per tick, m); OUT: f64 drive[n], i64 n_audio, f64 audio[n_audio].
 * Memory: the renderer is a static object; nothing is allocated by the runtime.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>

#include "sd_runtime.h"
#ifndef SD_TABLE_HEADER
#error "define SD_TABLE_HEADER, e.g. -DSD_TABLE_HEADER='\"table.h\"'"
#endif
#include SD_TABLE_HEADER

#ifndef SD_TABLE_K_MU
#define SD_TABLE_K_MU 0.0
#endif

/* Code type of an exported codes array (the format has uint8, uint16, float32, float64). */
#define SD_DTYPE_OF(a) (sizeof((a)[0]) == 1 ? SD_U8 : sizeof((a)[0]) == 2 ? SD_U16 \
                        : sizeof((a)[0]) == 4 ? SD_F32 : SD_F64)
#define SD_CHANNEL(name) {sd_table_##name##_codes, SD_DTYPE_OF(sd_table_##name##_codes), \
                          sd_table_##name##_scale, sd_table_##name##_offset, sd_table_##name##_background}

#ifdef SD_TABLE_HAS_NORMAL_FORCE
static const sd_channel_t ch_normal_force = SD_CHANNEL(normal_force);
#endif
#ifdef SD_TABLE_HAS_FRICTION_SCALE
static const sd_channel_t ch_friction_scale = SD_CHANNEL(friction_scale);
#endif
#ifdef SD_TABLE_HAS_BURST_GAIN
static const sd_channel_t ch_burst_gain = SD_CHANNEL(burst_gain);
#endif
#ifdef SD_TABLE_HAS_GRAD_X
static const sd_channel_t ch_grad_x = SD_CHANNEL(grad_x);
#endif
#ifdef SD_TABLE_HAS_GRAD_Y
static const sd_channel_t ch_grad_y = SD_CHANNEL(grad_y);
#endif
#ifdef SD_TABLE_HAS_LATERAL_X
static const sd_channel_t ch_lateral_x = SD_CHANNEL(lateral_x);
#endif
#ifdef SD_TABLE_HAS_LATERAL_Y
static const sd_channel_t ch_lateral_y = SD_CHANNEL(lateral_y);
#endif
#ifdef SD_TABLE_HAS_SKIN_STRETCH
static const sd_channel_t ch_skin_stretch = SD_CHANNEL(skin_stretch);
#endif
#ifdef SD_TABLE_HAS_BREAKAWAY_FORCE
static const sd_channel_t ch_breakaway_force = SD_CHANNEL(breakaway_force);
#endif
#ifdef SD_TABLE_HAS_KINETIC_FORCE
static const sd_channel_t ch_kinetic_force = SD_CHANNEL(kinetic_force);
#endif

static sd_renderer_t R;

static void bind(sd_table_t *T)
{
    int s;
    T->rows = SD_TABLE_ROWS;
    T->cols = SD_TABLE_COLS;
    T->dx = sd_table_dx_m;
    T->dy = sd_table_dy_m;
    T->x0 = sd_table_x0_m;
    T->y0 = sd_table_y0_m;
    T->n_blocks = SD_TABLE_N_BLOCKS;
    T->blocks = sd_table_blocks;
    for (s = 0; s < SD_NSLOT; s++) T->slot[s] = NULL;
#ifdef SD_TABLE_HAS_NORMAL_FORCE
    T->slot[SD_SLOT_NORMAL_FORCE] = &ch_normal_force;
#endif
#ifdef SD_TABLE_HAS_FRICTION_SCALE
    T->slot[SD_SLOT_FRICTION_SCALE] = &ch_friction_scale;
#endif
#ifdef SD_TABLE_HAS_BURST_GAIN
    T->slot[SD_SLOT_BURST_GAIN] = &ch_burst_gain;
#endif
#ifdef SD_TABLE_HAS_GRAD_X
    T->slot[SD_SLOT_GRAD_X] = &ch_grad_x;
#endif
#ifdef SD_TABLE_HAS_GRAD_Y
    T->slot[SD_SLOT_GRAD_Y] = &ch_grad_y;
#endif
#ifdef SD_TABLE_HAS_LATERAL_X
    T->slot[SD_SLOT_LATERAL_X] = &ch_lateral_x;
#endif
#ifdef SD_TABLE_HAS_LATERAL_Y
    T->slot[SD_SLOT_LATERAL_Y] = &ch_lateral_y;
#endif
#ifdef SD_TABLE_HAS_SKIN_STRETCH
    T->slot[SD_SLOT_SKIN_STRETCH] = &ch_skin_stretch;
#endif
#ifdef SD_TABLE_HAS_BREAKAWAY_FORCE
    T->slot[SD_SLOT_BREAKAWAY_FORCE] = &ch_breakaway_force;
#endif
#ifdef SD_TABLE_HAS_KINETIC_FORCE
    T->slot[SD_SLOT_KINETIC_FORCE] = &ch_kinetic_force;
#endif
}

int main(int argc, char **argv)
{
    sd_table_t T;
    sd_config_t C;
    FILE *in, *out;
    int64_t n, i, n_audio = 0;
    double *x, *y;
    int rc;
    if (argc != 4) {
        fprintf(stderr, "usage: sd_play_header AUDIO_RATE IN OUT\n");
        return 2;
    }
    bind(&T);
    C.pad.mass = sd_table_pad_mass_kg;
    C.pad.stiffness = sd_table_pad_stiffness_n_per_m;
    C.pad.damping = sd_table_pad_damping_ns_per_m;
    C.pad.burst_gain = sd_table_burst_gain;
    C.pad.max_stick_period = sd_table_max_stick_period_s;
    C.mu_s = sd_table_mu_s;
    C.mu_k = sd_table_mu_k;
    C.k_mu = SD_TABLE_K_MU;
    C.skin_target = 0.0;
    C.tick_rate = sd_table_tick_rate_hz;
    C.audio_rate = atof(argv[1]);
    C.carrier_hz = sd_table_burst_carrier_hz;
    C.rise_s = sd_table_burst_rise_s;
    C.decay_s = sd_table_burst_decay_s;
    C.policy = SD_RETRIGGER;
    C.model = SD_MODEL_JUMP;
    rc = sd_renderer_init(&R, &T, &C);
    if (rc != SD_OK) {
        fprintf(stderr, "sd_play_header: sd_renderer_init failed (%d)\n", rc);
        return 3;
    }
    in = fopen(argv[2], "rb");
    out = fopen(argv[3], "wb");
    if (!in || !out || fread(&n, sizeof n, 1, in) != 1 || n < 1) return 2;
    x = (double *)malloc((size_t)n * sizeof(double));
    y = (double *)malloc((size_t)n * sizeof(double));
    if (!x || !y || fread(x, sizeof(double), (size_t)n, in) != (size_t)n
        || fread(y, sizeof(double), (size_t)n, in) != (size_t)n)
        return 2;
    for (i = 0; i < n; i++) {
        double d = sd_renderer_step(&R, x[i], y[i]);
        fwrite(&d, sizeof d, 1, out);
    }
    /* second pass for the audio stream (the renderer is deterministic from reset) */
    sd_renderer_reset(&R, 0.0);
    for (i = 0; i < n; i++) {
        sd_renderer_step(&R, x[i], y[i]);
        n_audio += R.n_audio;
    }
    fwrite(&n_audio, sizeof n_audio, 1, out);
    sd_renderer_reset(&R, 0.0);
    for (i = 0; i < n; i++) {
        sd_renderer_step(&R, x[i], y[i]);
        fwrite(R.audio, sizeof(double), (size_t)R.n_audio, out);
    }
    fclose(in);
    return fclose(out) == 0 ? 0 : 2;
}
