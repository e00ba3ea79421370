/* tool_vectors.c -- host program that runs the C runtime on test vectors written by Python.
 *
 *   sd_vectors pad    IN OUT   run a pad model (jump or exact) over per-tick inputs (as dispatch.run_ticks)
 *   sd_vectors render IN OUT   render a cursor stroke through a table (as Renderer.step)
 *   sd_vectors image  IN OUT   the same from a binary table image (sd_image_load), settings overridden
 *   sd_vectors seek   IN OUT   as image, the renderer first moved on by i64 ticks (sd_renderer_seek) with
 *                              the cursor at rest at f64 x, y (read after the rates)
 *
 * File layouts (little-endian; f64 = double, i64 = int64) are documented next to the writers
 * in tests/test_c_runtime.py. This program is a test tool: it allocates freely; the runtime
 * it calls does not.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sd_runtime.h"

static FILE *in_f, *out_f;

static void die(const char *msg)
{
    fprintf(stderr, "sd_vectors: %s\n", msg);
    exit(2);
}

static void rd(void *p, size_t size, size_t n)
{
    if (n && fread(p, size, n, in_f) != n) die("input file truncated");
}

static void wr(const void *p, size_t size, size_t n)
{
    if (n && fwrite(p, size, n, out_f) != n) die("cannot write output");
}

static double *rd_f64(int64_t n)
{
    double *a = (double *)malloc((size_t)(n > 0 ? n : 1) * sizeof(double));
    if (!a) die("out of memory");
    rd(a, sizeof(double), (size_t)n);
    return a;
}

static int64_t rd_i64(void)
{
    int64_t v;
    rd(&v, sizeof v, 1);
    return v;
}

static int run_pad(void)
{
    sd_pad_params_t prm;
    sd_pad_t P;
    sd_pad_state_t S;
    sd_tick_fn tick;
    int64_t n, i, model;
    double *t, *V, *N, *mus, *muk, *gain, *of, *ox, *ophase, *ev_t, *ev_a;
    int cap, n_ev = 0;
    rd(&prm, sizeof prm, 1);
    sd_pad_prepare(&P, &prm);
    model = rd_i64();
    tick = sd_model_tick((int)model);
    if (!tick) die("model has no C tick");
    n = rd_i64();
    if (n < 1 || n > 100000000) die("bad tick count");
    t = rd_f64(n); V = rd_f64(n); N = rd_f64(n); mus = rd_f64(n); muk = rd_f64(n); gain = rd_f64(n);
    of = (double *)malloc((size_t)n * sizeof(double));
    ox = (double *)malloc((size_t)n * sizeof(double));
    ophase = (double *)malloc((size_t)n * sizeof(double));
    cap = (int)(2 * n + 64);
    for (;;) {   /* like models.run_kernel: rerun with a larger event buffer if needed */
        ev_t = (double *)malloc((size_t)cap * sizeof(double));
        ev_a = (double *)malloc((size_t)cap * sizeof(double));
        if (!of || !ox || !ophase || !ev_t || !ev_a) die("out of memory");
        n_ev = 0;
        sd_pad_reset(&S);
        for (i = 0; i < n; i++) {
            double h = i > 0 ? t[i] - t[i - 1] : 0.0;
            double t0 = i > 0 ? t[i - 1] : t[0];
            if (h > 0.0) n_ev = tick(&S, &P, t0, h, V[i], N[i], mus[i], muk[i], gain[i], ev_t, ev_a, cap, n_ev);
            of[i] = S.f;
            ophase[i] = S.phase;
            ox[i] = S.x;
        }
        if (n_ev <= cap) break;
        free(ev_t);
        free(ev_a);
        cap = n_ev + 64;
    }
    wr(of, sizeof(double), (size_t)n);
    wr(ophase, sizeof(double), (size_t)n);
    wr(ox, sizeof(double), (size_t)n);
    {
        int64_t ne = n_ev;
        wr(&ne, sizeof ne, 1);
    }
    wr(ev_t, sizeof(double), (size_t)n_ev);
    wr(ev_a, sizeof(double), (size_t)n_ev);
    return 0;
}

static int64_t *rd_i64s(int64_t n)
{
    int64_t *a = (int64_t *)malloc((size_t)(n > 0 ? n : 1) * sizeof(int64_t));
    if (!a) die("out of memory");
    rd(a, sizeof(int64_t), (size_t)n);
    return a;
}

static int play(const sd_table_t *T, const sd_config_t *C);
static int64_t seek_tick = -1;
static double seek_xy[2];

static int run_render(void)
{
    sd_config_t C;
    static sd_table_t T;
    static sd_channel_t ch[SD_NSLOT];
    int64_t n_values, i, s;
    int32_t (*blocks)[5];
    int64_t *blk;
    memset(&T, 0, sizeof T);           /* no block index: lookups scan the blocks */
    rd(&C, sizeof C, 1);
    rd(&T.grid, sizeof T.grid, 1);
    T.n_blocks = (int32_t)rd_i64();
    blk = rd_i64s(5 * (int64_t)T.n_blocks);
    blocks = (int32_t (*)[5])malloc((size_t)(T.n_blocks > 0 ? T.n_blocks : 1) * sizeof *blocks);
    if (!blocks) die("out of memory");
    for (i = 0; i < T.n_blocks; i++)
        for (s = 0; s < 5; s++) blocks[i][s] = (int32_t)blk[5 * i + s];
    T.blocks = (const int32_t (*)[5])blocks;
    n_values = rd_i64();
    for (s = 0; s < SD_NSLOT; s++) {
        int64_t dtype = rd_i64();
        static const size_t width[4] = {1, 2, 4, 8};
        void *codes;
        T.slot[s] = NULL;
        if (dtype < 0) continue;
        if (dtype > 3) die("bad dtype");
        rd(&ch[s].scale, sizeof(double), 1);
        rd(&ch[s].offset, sizeof(double), 1);
        rd(&ch[s].background, sizeof(double), 1);
        codes = malloc((size_t)(n_values > 0 ? n_values : 1) * width[dtype]);
        if (!codes) die("out of memory");
        rd(codes, width[dtype], (size_t)n_values);
        ch[s].codes = codes;
        ch[s].dtype = (int)dtype;
        T.slot[s] = &ch[s];
    }
    return play(&T, &C);
}

/* Initialise the renderer and play the stroke that follows in the input (i64 n, f64 x[n], y[n]);
 * write the per-tick outputs, the audio and the counters. */
static int play(const sd_table_t *T, const sd_config_t *C)
{
    static sd_renderer_t R;          /* large (event ring): not on the stack */
    int64_t n, i, n_audio_total = 0;
    double *x, *y, *audio;
    sd_outputs_t *outs;
    size_t audio_cap;
    int rc;
    n = rd_i64();
    if (n < 1 || n > 100000000) die("bad step count");
    x = rd_f64(n);
    y = rd_f64(n);
    rc = sd_renderer_init(&R, T, C);
    if (rc != SD_OK) {
        fprintf(stderr, "sd_vectors: sd_renderer_init failed (%d)\n", rc);
        return 3;
    }
    if (seek_tick >= 0) sd_renderer_seek(&R, seek_tick, seek_xy[0], seek_xy[1]);
    outs = (sd_outputs_t *)malloc((size_t)n * sizeof(sd_outputs_t));
    audio_cap = (size_t)n * (size_t)(R.audio_cap > 0 ? R.audio_cap : 1);
    audio = (double *)malloc(audio_cap * sizeof(double));
    if (!outs || !audio) die("out of memory");
    for (i = 0; i < n; i++) {
        sd_renderer_step(&R, x[i], y[i]);
        outs[i] = R.out;
        memcpy(audio + n_audio_total, R.audio, (size_t)R.n_audio * sizeof(double));
        n_audio_total += R.n_audio;
    }
    wr(outs, sizeof(sd_outputs_t), (size_t)n);
    wr(&n_audio_total, sizeof n_audio_total, 1);
    wr(audio, sizeof(double), (size_t)n_audio_total);
    {
        int64_t counters[4];
        counters[0] = R.run.clipped;
        counters[1] = R.run.events_total;
        counters[2] = R.run.events_dropped;
        counters[3] = R.position_faults;
        wr(counters, sizeof(int64_t), 4);
    }
    return 0;
}

/* Input: i64 image_size, the image, zero padding to a multiple of 8 bytes; i64 policy, i64 model,
 * f64 tick_rate, f64 audio_rate (override the image's settings); then the stroke as for render. */
static int run_image(int seek)
{
    static sd_image_t img;
    sd_config_t C;
    int64_t size = rd_i64(), policy, model;
    double *buf, rates[2];
    int rc;
    if (size < 0 || size > (int64_t)1 << 30) die("bad image size");
    buf = rd_f64((size + 7) / 8);     /* 8-byte aligned, as sd_image_load requires */
    rc = sd_image_load(&img, buf, (size_t)size);
    if (rc != SD_OK) {
        fprintf(stderr, "sd_vectors: sd_image_load failed (%d)\n", rc);
        return 4;
    }
    policy = rd_i64();
    model = rd_i64();
    rd(rates, sizeof(double), 2);
    if (seek) {
        seek_tick = rd_i64();
        rd(seek_xy, sizeof(double), 2);
    }
    sd_image_config(&img, &C);
    C.policy = (int)policy;
    C.model = (int)model;
    C.tick_rate = rates[0];
    C.audio_rate = rates[1];
    return play(&img.table, &C);
}

int main(int argc, char **argv)
{
    int rc = 2;   /* die() exits; the value only keeps clang's flow analysis satisfied */
    if (argc != 4) die("usage: sd_vectors pad|render|image|seek IN OUT");
    in_f = fopen(argv[2], "rb");
    if (!in_f) die("cannot open input");
    out_f = fopen(argv[3], "wb");
    if (!out_f) die("cannot open output");
    if (strcmp(argv[1], "pad") == 0) rc = run_pad();
    else if (strcmp(argv[1], "render") == 0) rc = run_render();
    else if (strcmp(argv[1], "image") == 0) rc = run_image(0);
    else if (strcmp(argv[1], "seek") == 0) rc = run_image(1);
    else die("mode must be pad, render, image or seek");
    fclose(in_f);
    if (fclose(out_f) != 0) die("cannot write output");
    return rc;
}
