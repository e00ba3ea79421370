/* sd_vectors.c -- host program that runs the C runtime on test vectors written by Python.
 *
 *   sd_vectors pad    IN OUT   run the jump pad model over per-tick inputs (as pads.run_ticks)
 *   sd_vectors render IN OUT   render a cursor stroke through a table (as Renderer, model jump)
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
    double prm[5];
    sd_pad_params_t P;
    sd_pad_state_t S;
    int64_t n, i;
    double *t, *V, *N, *mus, *muk, *gain, *of, *ox, *ophase, *ev_t, *ev_a;
    int cap, n_ev = 0;
    rd(prm, sizeof(double), 5);
    P.mass = prm[0];
    P.stiffness = prm[1];
    P.damping = prm[2];
    P.burst_gain = prm[3];
    P.max_stick_period = prm[4];
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
            if (h > 0.0)
                n_ev = sd_jump_tick(&S, &P, t0, h, V[i], N[i], mus[i], muk[i], gain[i], ev_t, ev_a, cap, n_ev);
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

int main(int argc, char **argv)
{
    int rc;
    if (argc != 4) die("usage: sd_vectors pad|render IN OUT");
    in_f = fopen(argv[2], "rb");
    if (!in_f) die("cannot open input");
    out_f = fopen(argv[3], "wb");
    if (!out_f) die("cannot open output");
    if (strcmp(argv[1], "pad") == 0) rc = run_pad();
    else die("mode must be pad or render");
    fclose(in_f);
    if (fclose(out_f) != 0) die("cannot write output");
    return rc;
}
