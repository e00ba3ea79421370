/* tool_play_header.c -- play a table compiled into the program from its C header export.
 *
 * This is how firmware binds a table: export it with
 *     shapedisplay export TABLE --format c -o table.h --name sd_table
 * and compile this file (or your firmware's equivalent) with
 *     cc -std=c99 -O2 -ffp-contract=off -DSD_TABLE_HEADER='"table.h"' \
 *        tool_play_header.c sd_*.c -lm   (every runtime source but sd_wasm.c)
 * The header is enough on its own: sd_table_bind() fills the table and the whole configuration
 * (pad, friction, slope-friction gain K_mu, burst, rates) from it; any channel code type works.
 * It plays the jump model; -DSD_PLAY_MODEL=SD_MODEL_KARNOPP (or _EXACT, _STRIBECK) plays another with
 * the parameters the header carries for it (sd_table_use_model()).
 *
 *   sd_play_header AUDIO_RATE IN OUT [TOGGLE STATE]
 * IN: i64 n, f64 x[n], f64 y[n] (cursor per tick, m); OUT: f64 drive[n], i64 n_audio, f64 audio[n_audio]
 * (little-endian on every host). With -DSD_SINGLE it plays the single-precision build.
 * TOGGLE STATE: indices (SD_TABLE_TOGGLE_<ID>, SD_TABLE_TOGGLE_<ID>_<STATE>) of a toggle state to
 * switch to before playing, with sd_table_set_state().
 * Memory: the renderer is a static object; nothing is allocated by the runtime.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sd_runtime.h"
#ifndef SD_TABLE_HEADER
#error "define SD_TABLE_HEADER, e.g. -DSD_TABLE_HEADER='\"table.h\"'"
#endif
#include SD_TABLE_HEADER

static sd_renderer_t R;
static int32_t blocks[SD_TABLE_N_BLOCKS][5];   /* writable copy: toggles switch by offset */
static FILE *in, *out;

/* The files are little-endian on every host: values are assembled from and split into bytes. */
static int rd_u64(uint64_t *v)
{
    unsigned char b[8];
    int i;
    if (fread(b, 1, 8, in) != 8) return 0;
    for (*v = 0, i = 7; i >= 0; i--) *v = *v << 8 | b[i];
    return 1;
}

static void wr_u64(uint64_t v)
{
    unsigned char b[8];
    int i;
    for (i = 0; i < 8; i++, v >>= 8) b[i] = (unsigned char)(v & 0xffu);
    fwrite(b, 1, 8, out);
}

static void wr_f64(double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    wr_u64(u);
}

static int rd_reals(sd_real *a, int64_t n)
{
    int64_t i;
    for (i = 0; i < n; i++) {
        uint64_t u;
        double d;
        if (!rd_u64(&u)) return 0;
        memcpy(&d, &u, sizeof d);
        a[i] = (sd_real)d;
    }
    return 1;
}

int main(int argc, char **argv)
{
    sd_table_t T;
    sd_config_t C;
    int64_t n, i, n_audio = 0;
    uint64_t nu;
    sd_real *x, *y;
    long a;
    int rc;
    if (argc != 4 && argc != 6) {
        fprintf(stderr, "usage: sd_play_header AUDIO_RATE IN OUT [TOGGLE STATE]\n");
        return 2;
    }
    sd_table_bind(&T, &C, blocks);
#ifdef SD_PLAY_MODEL
    if (sd_table_use_model(&C, SD_PLAY_MODEL) != 0) {
        fprintf(stderr, "sd_play_header: the header carries no parameters for model %d\n", (int)SD_PLAY_MODEL);
        return 2;
    }
#endif
    C.audio_rate = (sd_real)atof(argv[1]);
    if (argc == 6 && sd_table_set_state(blocks, atoi(argv[4]), atoi(argv[5])) != 0) {
        fprintf(stderr, "sd_play_header: no toggle %s state %s\n", argv[4], argv[5]);
        return 2;
    }
    rc = sd_renderer_init(&R, &T, &C);
    if (rc != SD_OK) {
        fprintf(stderr, "sd_play_header: sd_renderer_init failed (%d)\n", rc);
        return 3;
    }
    in = fopen(argv[2], "rb");
    out = fopen(argv[3], "wb");
    if (!in || !out || !rd_u64(&nu)) return 2;
    n = (int64_t)nu;
    if (n < 1 || n > 100000000) return 2;
    x = (sd_real *)malloc((size_t)n * sizeof(sd_real));
    y = (sd_real *)malloc((size_t)n * sizeof(sd_real));
    if (!x || !y || !rd_reals(x, n) || !rd_reals(y, n)) return 2;
    for (i = 0; i < n; i++) wr_f64((double)sd_renderer_step(&R, x[i], y[i]));
    /* second pass for the audio stream (the renderer is deterministic from reset) */
    sd_renderer_reset(&R, 0);
    for (i = 0; i < n; i++) {
        sd_renderer_step(&R, x[i], y[i]);
        n_audio += R.n_audio;
    }
    wr_u64((uint64_t)n_audio);
    sd_renderer_reset(&R, 0);
    for (i = 0; i < n; i++) {
        sd_renderer_step(&R, x[i], y[i]);
        for (a = 0; a < R.n_audio; a++) wr_f64((double)R.audio[a]);
    }
    fclose(in);
    return fclose(out) == 0 ? 0 : 2;
}
