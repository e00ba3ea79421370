/* tool_vectors.c -- host program that runs the C runtime on test vectors written by Python.
 *
 *   sd_vectors pad    IN OUT   run a pad model (jump or exact) over per-tick inputs (as dispatch.run_ticks);
 *                              the output ends with i64 the ticks cut at the phase cap
 *   sd_vectors render IN OUT   render a cursor stroke through a table (as Renderer.step)
 *   sd_vectors image  IN OUT   the same from a binary table image (sd_image_load), settings overridden
 *   sd_vectors seek   IN OUT   as image, the renderer first moved on by i64 ticks (sd_renderer_seek) with
 *                              the cursor at rest at f64 x, y (read after the rates)
 *   sd_vectors react  IN OUT   as image, with f64 press[n] after the stroke (sd_renderer_step_press); the
 *                              output ends with i64 the reaction events and their REACT_EVENT records
 *                              (i64 kind, widget, tick, f64 value)
 *
 * File layouts (little-endian on every host, read and written byte by byte; f64 = IEEE double,
 * i64 = int64) are documented next to the writers in tests/test_c_runtime.py. Built with
 * -DSD_SINGLE it runs the single-precision runtime (inputs rounded to float, outputs widened).
 * This program is a test tool: it allocates freely; the runtime it calls does not.
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

/* Files are little-endian whatever the host: every value is assembled from its bytes (and written
 * byte by byte), never read into memory as a whole struct. */
static uint64_t rd_u64(void)
{
    unsigned char b[8];
    uint64_t v = 0;
    int i;
    if (fread(b, 1, 8, in_f) != 8) die("input file truncated");
    for (i = 7; i >= 0; i--) v = v << 8 | b[i];
    return v;
}

static double rd_double(void)
{
    uint64_t u = rd_u64();
    double d;
    memcpy(&d, &u, sizeof d);     /* IEEE binary64 with the host's integer byte order */
    return d;
}

static int64_t rd_i64(void) { return (int64_t)rd_u64(); }

static int32_t rd_i32(void)
{
    unsigned char b[4];
    if (fread(b, 1, 4, in_f) != 4) die("input file truncated");
    return (int32_t)((uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24);
}

static void wr_u64(uint64_t v)
{
    unsigned char b[8];
    int i;
    for (i = 0; i < 8; i++, v >>= 8) b[i] = (unsigned char)(v & 0xffu);
    if (fwrite(b, 1, 8, out_f) != 8) die("cannot write output");
}

static void wr_f64(double d)
{
    uint64_t u;
    memcpy(&u, &d, sizeof u);
    wr_u64(u);
}

static void wr_i64(int64_t v) { wr_u64((uint64_t)v); }

/* n reals (f64 in the file) into the runtime's real type */
static sd_real *rd_reals(int64_t n)
{
    sd_real *a = (sd_real *)malloc((size_t)(n > 0 ? n : 1) * sizeof(sd_real));
    int64_t i;
    if (!a) die("out of memory");
    for (i = 0; i < n; i++) a[i] = (sd_real)rd_double();
    return a;
}

static void wr_reals(const sd_real *a, int64_t n)
{
    int64_t i;
    for (i = 0; i < n; i++) wr_f64((double)a[i]);
}

/* The records of layouts.py, field by field (sd_layout.h's SD_FIELDS_* lists; no padding). */
#define RD_F64(name) s->name = (sd_real)rd_double();
#define RD_I64(name) s->name = rd_i64();
#define RD_I32(name) s->name = rd_i32();
#define RD_PAD_PARAMS(name) rd_pad_params(&s->name);
#define RD_FIELD(kind, name) RD_##kind(name)
static void rd_pad_params(sd_pad_params_t *s) { SD_FIELDS_PAD_PARAMS(RD_FIELD) }
static void rd_config(sd_config_t *s) { SD_FIELDS_RENDER_CONFIG(RD_FIELD) }
static void rd_grid(sd_grid_t *s) { SD_FIELDS_GRID(RD_FIELD) }

#define WR_F64(name) wr_f64((double)s->name);
#define WR_FIELD(kind, name) WR_##kind(name)
static void wr_outputs(const sd_outputs_t *s) { SD_FIELDS_OUTPUTS(WR_FIELD) }

static int run_pad(void)
{
    sd_pad_params_t prm;
    sd_pad_t P;
    sd_pad_state_t S;
    sd_tick_fn tick;
    int64_t n, i, model;
    sd_real *t, *V, *N, *mus, *muk, *gain, *of, *ox, *ophase, *ev_t, *ev_a;
    int cap, n_ev = 0;
    rd_pad_params(&prm);
    sd_pad_prepare(&P, &prm);
    model = rd_i64();
    tick = sd_model_tick((int)model);
    if (!tick) die("model has no C tick");
    n = rd_i64();
    if (n < 1 || n > 100000000) die("bad tick count");
    t = rd_reals(n); V = rd_reals(n); N = rd_reals(n); mus = rd_reals(n); muk = rd_reals(n); gain = rd_reals(n);
    of = (sd_real *)malloc((size_t)n * sizeof(sd_real));
    ox = (sd_real *)malloc((size_t)n * sizeof(sd_real));
    ophase = (sd_real *)malloc((size_t)n * sizeof(sd_real));
    cap = (int)(2 * n + 64);
    for (;;) {   /* like models.run_kernel: rerun with a larger event buffer if needed */
        ev_t = (sd_real *)malloc((size_t)cap * sizeof(sd_real));
        ev_a = (sd_real *)malloc((size_t)cap * sizeof(sd_real));
        if (!of || !ox || !ophase || !ev_t || !ev_a) die("out of memory");
        n_ev = 0;
        sd_pad_reset(&S);
        for (i = 0; i < n; i++) {
            sd_real h = i > 0 ? t[i] - t[i - 1] : (sd_real)0;
            sd_real t0 = i > 0 ? t[i - 1] : t[0];
            if (h > 0) n_ev = tick(&S, &P, t0, h, V[i], N[i], mus[i], muk[i], gain[i], ev_t, ev_a, cap, n_ev);
            of[i] = S.f;
            ophase[i] = S.phase;
            ox[i] = S.x;
        }
        if (n_ev <= cap) break;
        free(ev_t);
        free(ev_a);
        cap = n_ev + 64;
    }
    wr_reals(of, n);
    wr_reals(ophase, n);
    wr_reals(ox, n);
    wr_i64(n_ev);
    wr_reals(ev_t, n_ev);
    wr_reals(ev_a, n_ev);
    wr_i64(S.truncated);              /* ticks cut at the phase cap (SD_PHASES_BASE) */
    return 0;
}

static int play(const sd_table_t *T, const sd_config_t *C);
static int64_t seek_tick = -1;
static sd_real seek_xy[2];
static int with_press;          /* react mode: a press force per tick follows the stroke */

static int run_render(void)
{
    sd_config_t C;
    static sd_table_t T;
    static sd_channel_t ch[SD_NSLOT];
    int64_t n_values, i, s;
    int32_t (*blocks)[5];
    memset(&T, 0, sizeof T);           /* no block index: lookups scan the blocks */
    rd_config(&C);
    rd_grid(&T.grid);
    T.n_blocks = (int32_t)rd_i64();
    if (T.n_blocks < 0 || T.n_blocks > 1000000) die("bad block count");
    blocks = (int32_t (*)[5])malloc((size_t)(T.n_blocks > 0 ? T.n_blocks : 1) * sizeof *blocks);
    if (!blocks) die("out of memory");
    for (i = 0; i < T.n_blocks; i++)
        for (s = 0; s < 5; s++) blocks[i][s] = (int32_t)rd_i64();
    T.blocks = (const int32_t (*)[5])blocks;
    n_values = rd_i64();
    if (n_values < 0 || n_values > 100000000) die("bad value count");
    for (s = 0; s < SD_NSLOT; s++) {
        int64_t dtype = rd_i64();
        static const size_t width[4] = {1, 2, 4, 8};
        unsigned char *codes;
        T.slot[s] = NULL;
        if (dtype < 0) continue;
        if (dtype > 3) die("bad dtype");
        ch[s].scale = (sd_real)rd_double();
        ch[s].offset = (sd_real)rd_double();
        ch[s].background = (sd_real)rd_double();
        codes = (unsigned char *)malloc((size_t)(n_values > 0 ? n_values : 1) * width[dtype]);
        if (!codes) die("out of memory");
        if (n_values && fread(codes, width[dtype], (size_t)n_values, in_f) != (size_t)n_values)
            die("input file truncated");
        /* the codes are used in place, as the runtime stores them: little-endian words to host order */
        for (i = 0; i < n_values && dtype > 0; i++) {
            unsigned char *w = codes + (size_t)i * width[dtype];
            uint64_t v = 0;
            int b;
            for (b = (int)width[dtype] - 1; b >= 0; b--) v = v << 8 | w[b];
            if (dtype == 1) {
                uint16_t u = (uint16_t)v;
                memcpy(w, &u, 2);
            } else if (dtype == 2) {
                uint32_t u = (uint32_t)v;
                memcpy(w, &u, 4);
            } else {
                memcpy(w, &v, 8);
            }
        }
        ch[s].codes = codes;
        ch[s].dtype = (int)dtype;
        T.slot[s] = &ch[s];
    }
    return play(&T, &C);
}

/* Initialise the renderer and play the stroke that follows in the input (i64 n, f64 x[n], y[n]);
 * write the per-tick outputs, the audio, the counters, then the stick-to-slip events (i64 count,
 * f64 times (s, absolute), f64 amplitudes). */
static int play(const sd_table_t *T, const sd_config_t *C)
{
    static sd_renderer_t R;          /* large (event ring): not on the stack */
    int64_t n, i, n_audio_total = 0, n_ev = 0, n_rev = 0;
    sd_real *x, *y, *audio, *press = NULL;
    double *ev_t, *ev_a;
    sd_outputs_t *outs;
    sd_react_event_t *rev = NULL;
    size_t audio_cap;
    int rc;
    n = rd_i64();
    if (n < 1 || n > 100000000) die("bad step count");
    x = rd_reals(n);
    y = rd_reals(n);
    if (with_press) {
        press = rd_reals(n);
        rev = (sd_react_event_t *)malloc((size_t)n * 4 * sizeof *rev + sizeof *rev);
        if (!rev) die("out of memory");
    }
    rc = sd_renderer_init(&R, T, C);
    if (rc != SD_OK) {
        fprintf(stderr, "sd_vectors: sd_renderer_init failed (%d)\n", rc);
        return 3;
    }
    if (seek_tick >= 0) sd_renderer_seek(&R, seek_tick, seek_xy[0], seek_xy[1]);
    outs = (sd_outputs_t *)malloc((size_t)n * sizeof(sd_outputs_t));
    audio_cap = (size_t)n * (size_t)(R.audio_cap > 0 ? R.audio_cap : 1);
    audio = (sd_real *)malloc(audio_cap * sizeof(sd_real));
    ev_t = (double *)malloc((size_t)n * SD_EVENT_RING / 2 * sizeof(double) + 8);
    ev_a = (double *)malloc((size_t)n * SD_EVENT_RING / 2 * sizeof(double) + 8);
    if (!outs || !audio || !ev_t || !ev_a) die("out of memory");
    for (i = 0; i < n; i++) {
        long e, nrec, nev;
        if (with_press) {
            sd_renderer_step_press(&R, x[i], y[i], press[i]);
            while (n_rev < 4 * n && sd_react_pop(&R, &rev[n_rev])) n_rev++;
        } else {
            sd_renderer_step(&R, x[i], y[i]);
        }
        outs[i] = R.out;
        memcpy(audio + n_audio_total, R.audio, (size_t)R.n_audio * sizeof(sd_real));
        n_audio_total += R.n_audio;
        nrec = (long)R.run.n_recent;
        nev = (long)R.out.events < nrec ? (long)R.out.events : nrec;     /* the tick's events stored */
        for (e = nrec - nev; e < nrec; e++) {
            ev_t[n_ev] = sd_event_time(&R, e);
            ev_a[n_ev++] = (double)R.ev_a[e];
        }
    }
    for (i = 0; i < n; i++) wr_outputs(&outs[i]);
    wr_i64(n_audio_total);
    wr_reals(audio, n_audio_total);
    wr_i64(R.run.clipped);
    wr_i64(R.run.events_total);
    wr_i64(R.run.events_dropped);
    wr_i64(R.position_faults);
    wr_i64(n_ev);
    for (i = 0; i < n_ev; i++) wr_f64(ev_t[i]);
    for (i = 0; i < n_ev; i++) wr_f64(ev_a[i]);
    if (with_press) {
        wr_i64(n_rev);
        for (i = 0; i < n_rev; i++) {
            wr_i64(rev[i].kind);
            wr_i64(rev[i].widget);
            wr_i64(rev[i].tick);
            wr_f64((double)rev[i].value);
        }
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
    uint64_t *buf;
    double rates[2];
    size_t padded;
    int rc;
    if (size < 0 || size > (int64_t)1 << 30) die("bad image size");
    padded = (size_t)(size + 7) / 8 * 8;
    buf = (uint64_t *)malloc(padded > 0 ? padded : 8);     /* 8-byte aligned, as sd_image_load requires */
    if (!buf) die("out of memory");
    if (padded && fread(buf, 1, padded, in_f) != padded) die("input file truncated");
    rc = sd_image_load(&img, buf, (size_t)size);
    if (rc != SD_OK) {
        fprintf(stderr, "sd_vectors: sd_image_load failed (%d)\n", rc);
        return 4;
    }
    policy = rd_i64();
    model = rd_i64();
    rates[0] = rd_double();
    rates[1] = rd_double();
    if (seek) {
        seek_tick = rd_i64();
        seek_xy[0] = (sd_real)rd_double();
        seek_xy[1] = (sd_real)rd_double();
    }
    sd_image_config(&img, &C);
    C.policy = (int)policy;
    C.model = (int)model;
    C.tick_rate = (sd_real)rates[0];
    C.audio_rate = (sd_real)rates[1];
    return play(&img.table, &C);
}

int main(int argc, char **argv)
{
    int rc = 2;   /* die() exits; the value only keeps clang's flow analysis satisfied */
    if (argc != 4) die("usage: sd_vectors pad|render|image|seek|react IN OUT");
    in_f = fopen(argv[2], "rb");
    if (!in_f) die("cannot open input");
    out_f = fopen(argv[3], "wb");
    if (!out_f) die("cannot open output");
    if (strcmp(argv[1], "pad") == 0) rc = run_pad();
    else if (strcmp(argv[1], "render") == 0) rc = run_render();
    else if (strcmp(argv[1], "image") == 0) rc = run_image(0);
    else if (strcmp(argv[1], "seek") == 0) rc = run_image(1);
    else if (strcmp(argv[1], "react") == 0) {
        with_press = 1;
        rc = run_image(0);
    } else die("mode must be pad, render, image, seek or react");
    fclose(in_f);
    if (fclose(out_f) != 0) die("cannot write output");
    return rc;
}
