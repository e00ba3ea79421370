/* tool_bench.c -- ticks per second of the C runtime on the host (jump model).
 *
 *   sd_bench [ticks]
 *
 * Table: the published tent profile (N1 = 0.5 N, N2 = 2.5 N over 15..45 mm, 241 samples of
 * 0.25 mm, uint16 codes); pad and burst of the bundled handheld-stick profile; cursor going
 * back and forth over the tent at 100 mm/s, 10 kHz ticks. Rates are ticks per second of CPU
 * time (CLOCK_PROCESS_CPUTIME_ID). Prints one line per configuration:
 *   pad      sd_jump_tick alone at 100 mm/s, N = 1.5 N (the model kernel)
 *   exact    sd_exact_tick alone, same inputs
 *   drive    sd_renderer_step with audio_rate 0: lookup + model + burst drive per tick
 *   audio48k sd_renderer_step with 48 kHz audio synthesis (about 5 audio samples per tick)
 */
#define _POSIX_C_SOURCE 199309L   /* clock_gettime */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "sd_runtime.h"

#define COLS 241

/* CPU time of this process: on a shared machine, time spent descheduled is not counted. */
static double now_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static uint16_t codes[COLS];
static const int32_t blocks[1][5] = {{0, 0, 1, COLS, 0}};
static sd_renderer_t R;
static volatile double sink;

static double stroke_x(long i)
{
    /* triangle wave 5..55 mm at 100 mm/s, 10 kHz ticks: period 1 s = 10000 ticks */
    long p = i % 10000;
    double u = p < 5000 ? (double)p / 5000.0 : (double)(10000 - p) / 5000.0;
    return 0.005 + 0.050 * u;
}

static double bench_render(const sd_table_t *T, sd_config_t *C, long n)
{
    long i;
    double t0, acc = 0.0;
    if (sd_renderer_init(&R, T, C) != SD_OK) {
        fprintf(stderr, "sd_bench: init failed\n");
        exit(2);
    }
    for (i = 0; i < 20000; i++) acc += sd_renderer_step(&R, stroke_x(i), 0.0);   /* warm caches */
    sd_renderer_reset(&R, 0.0);
    t0 = now_s();
    for (i = 0; i < n; i++) acc += sd_renderer_step(&R, stroke_x(i), 0.0);
    t0 = now_s() - t0;
    sink = acc;
    printf("  (%ld events)", (long)R.run.events_total);
    return (double)n / t0;
}

int main(int argc, char **argv)
{
    long n = argc > 1 ? atol(argv[1]) : 20000000L, i;
    sd_channel_t nf;
    sd_table_t T;
    sd_config_t C;
    double lo = 0.5, hi = 2.5, scale = (hi - lo) / 65535.0, t0, rate;
    static double ev_t[4096], ev_a[4096];
    sd_pad_state_t S;
    sd_pad_t P;
    int s, n_ev = 0;
    memset(&C, 0, sizeof C);
    memset(&T, 0, sizeof T);          /* members not set below (no reactions) are zero */
    for (i = 0; i < COLS; i++) {
        double x = (double)i * 0.25e-3, v;
        if (x < 0.015 || x > 0.045) v = lo;
        else if (x < 0.030) v = lo + (hi - lo) * (x - 0.015) / 0.015;
        else v = hi - (hi - lo) * (x - 0.030) / 0.015;
        codes[i] = (uint16_t)floor((v - lo) / scale + 0.5);
    }
    nf.codes = codes;
    nf.dtype = SD_U16;
    nf.scale = scale;
    nf.offset = lo;
    nf.background = 0.0;
    T.grid.rows = 1;
    T.grid.cols = COLS;
    T.grid.dx = T.grid.dy = 0.25e-3;
    T.grid.x0 = T.grid.y0 = 0.0;
    T.n_blocks = 1;
    T.blocks = blocks;
    T.tile_rows = T.tile_cols = T.tiles_y = T.tiles_x = 0;
    T.tile_start = T.tile_list = NULL;
    for (s = 0; s < SD_NSLOT; s++) T.slot[s] = NULL;
    T.slot[SD_SLOT_NORMAL_FORCE] = &nf;
    C.pad.mass = 1.0e-6;
    C.pad.stiffness = 2000.0;
    C.pad.damping = 0.01;
    C.pad.burst_gain = 0.25;
    C.pad.max_stick_period = 0.0;
    C.mu_s = 0.5;
    C.mu_k = 0.3;
    C.k_mu = 0.0;
    C.skin_target = 0.0;
    C.normal_force_constant = 0.0;
    C.tick_rate = 10000.0;
    C.carrier_hz = 300.0;
    C.rise_s = 0.005;
    C.decay_s = 0.030;
    C.policy = SD_RETRIGGER;
    C.model = SD_MODEL_JUMP;

    /* the model kernel alone: 100 mm/s, N = 1.5 N */
    sd_pad_prepare(&P, &C.pad);
    sd_pad_reset(&S);
    t0 = now_s();
    for (i = 0; i < n; i++) {
        n_ev = sd_jump_tick(&S, &P, (double)i * 1e-4, 1e-4, 0.1, 1.5, 0.5, 0.3, 1.0, ev_t, ev_a, 4096, 0);
    }
    rate = (double)n / (now_s() - t0);
    sink = S.x + n_ev;
    printf("pad      %.1f Mticks/s\n", rate / 1e6);
    sd_pad_reset(&S);
    t0 = now_s();
    for (i = 0; i < n / 10; i++) {
        n_ev = sd_exact_tick(&S, &P, (double)i * 1e-4, 1e-4, 0.1, 1.5, 0.5, 0.3, 1.0, ev_t, ev_a, 4096, 0);
    }
    rate = (double)(n / 10) / (now_s() - t0);
    sink = S.x + n_ev;
    printf("exact    %.1f Mticks/s\n", rate / 1e6);

    C.audio_rate = 0.0;
    rate = bench_render(&T, &C, n);
    printf("\ndrive    %.1f Mticks/s\n", rate / 1e6);
    C.audio_rate = 48000.0;
    rate = bench_render(&T, &C, n / 4);
    printf("\naudio48k %.1f Mticks/s\n", rate / 1e6);
    return 0;
}
