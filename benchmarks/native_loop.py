"""The native per-tick loop of the C runtime that bench_wasm.py and bench_engine.py time beside WebAssembly.

``sd_loop PAYLOAD LOOPS``: the payload as the M4 harness reads it (tests/runtime_vectors.image_payload);
every loop from a reset, the CPU time of the sd_renderer_step loop alone (the audio summed so it is not
optimised away), printed as a JSON list of seconds. Uses only the runtime's public API of every version.
"""
LOOP_C = r"""
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include "sd_runtime.h"
static sd_image_t img;
static sd_renderer_t R;
static double cpu_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}
int main(int argc, char **argv)
{
    FILE *f;
    long size, n, i, k, loops;
    double *buf, *xy, acc = 0.0, rates[2], t0;
    int64_t v[3];
    sd_config_t C;
    if (argc != 3 || !(f = fopen(argv[1], "rb"))) return 2;
    loops = atol(argv[2]);
    fseek(f, 0, SEEK_END);
    size = ftell(f);
    fseek(f, 0, SEEK_SET);
    buf = malloc((size_t)size + 8);
    if (!buf || fread(buf, 1, (size_t)size, f) != (size_t)size) return 2;
    memcpy(v, buf, 8);
    if (sd_image_load(&img, buf + 1, (size_t)v[0]) != SD_OK) return 3;
    xy = buf + 1 + (v[0] + 7) / 8;
    memcpy(v, xy, 16);
    memcpy(rates, xy + 2, 16);
    sd_image_config(&img, &C);
    C.policy = (int)v[0];
    C.model = (int)v[1];
    C.tick_rate = rates[0];
    C.audio_rate = rates[1];
    memcpy(v, xy + 4, 8);
    n = (long)v[0];
    if (sd_renderer_init(&R, &img.table, &C) != SD_OK) return 4;
    printf("[");
    for (k = 0; k < loops; k++) {
        sd_renderer_reset(&R, 0);
        t0 = cpu_s();
        for (i = 0; i < n; i++) {
            long j;
            sd_renderer_step(&R, xy[5 + i], xy[5 + n + i]);
            for (j = 0; j < R.n_audio; j++) acc += R.audio[j];
        }
        printf("%s%.9f", k ? ", " : "", cpu_s() - t0);
    }
    printf("]\n");
    fprintf(stderr, "checksum %g\n", acc);
    return 0;
}
"""
