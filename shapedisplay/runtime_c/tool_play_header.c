/* tool_play_header.c -- play a table compiled into the program from its C header export.
 *
 * This is how firmware binds a table: export it with
 *     shapedisplay export TABLE --format c -o table.h --name sd_table
 * and compile this file (or your firmware's equivalent) with
 *     cc -std=c99 -O2 -ffp-contract=off -DSD_TABLE_HEADER='"table.h"' \
 *        tool_play_header.c sd_render.c sd_pad.c sd_exact.c sd_image.c -lm
 * The header is enough on its own: sd_table_bind() fills the table and the whole configuration
 * (pad, friction, slope-friction gain K_mu, burst, rates) from it; any channel code type works.
 *
 *   sd_play_header AUDIO_RATE IN OUT [TOGGLE STATE]
 * IN: i64 n, f64 x[n], f64 y[n] (cursor per tick, m); OUT: f64 drive[n], i64 n_audio, f64 audio[n_audio].
 * TOGGLE STATE: indices (SD_TABLE_TOGGLE_<ID>, SD_TABLE_TOGGLE_<ID>_<STATE>) of a toggle state to
 * switch to before playing, with sd_table_set_state().
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

static sd_renderer_t R;
static int32_t blocks[SD_TABLE_N_BLOCKS][5];   /* writable copy: toggles switch by offset */

int main(int argc, char **argv)
{
    sd_table_t T;
    sd_config_t C;
    FILE *in, *out;
    int64_t n, i, n_audio = 0;
    double *x, *y;
    int rc;
    if (argc != 4 && argc != 6) {
        fprintf(stderr, "usage: sd_play_header AUDIO_RATE IN OUT [TOGGLE STATE]\n");
        return 2;
    }
    sd_table_bind(&T, &C, blocks);
    C.audio_rate = atof(argv[1]);
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
