/* harness.c -- the shared test vectors and the instruction-count benchmark on a Cortex-M4F.
 *
 * Runs under QEMU (machine mps2-an386) with semihosting; arguments from the command line
 * (`-semihosting-config enable=on,arg=sd_m4,arg=MODE,arg=IN,arg=OUT`):
 *   vectors IN OUT   play a binary table image as `sd_vectors image` does on the host (same input
 *                    and output layout, events included: tests/runtime_vectors.py)
 *   bench   IN OUT   the same input; OUT = u32 SysTick counts of every sd_renderer_step call,
 *                    then u32 the count of an empty measurement (the overhead to subtract).
 *                    With `-icount shift=S`, counts / (2^S * 0.025) = instructions.
 *   react, react-bench   as vectors and bench with f64 press[n] after the stroke
 *                    (sd_renderer_step_press); react's output ends with i64 the reaction events and
 *                    their records (i64 kind, widget, tick, f64 value), as `sd_vectors react`
 * All memory is static; the runtime allocates nothing.
 */
#include <stdint.h>
#include <string.h>
#include "../sd_runtime.h"
#include "m4.h"

#define IN_MAX (1u << 20)
#define TICKS_MAX 100000

static uint64_t in_buf[IN_MAX / 8];
static sd_image_t img;
static sd_renderer_t R;
static double audio[1u << 16];
static sd_real xs[TICKS_MAX], ys[TICKS_MAX];
#define REACT_MAX (1u << 10)
static sd_react_event_t rev_log[REACT_MAX];
#define EVENTS_MAX (1u << 14)
static double ev_log[2][EVENTS_MAX];     /* the stick-to-slip events: absolute time (s), amplitude */

/* The outputs of a tick as float64 records (layouts.OUTPUTS), whatever sd_real is. */
static void write_outputs(int32_t fd, const sd_outputs_t *o)
{
    double rec[64];
    int n = 0;
#define SD_OUT_FIELD(kind, name) rec[n++] = (double)o->name;
    SD_FIELDS_OUTPUTS(SD_OUT_FIELD)
#undef SD_OUT_FIELD
    m4_write(fd, rec, (uint32_t)(8 * n));
}
static uint32_t counts[TICKS_MAX];

static const uint8_t *cur, *end;

static const void *take(uint32_t n)
{
    const uint8_t *p = cur;
    if ((uint32_t)(end - cur) < n) m4_exit(2);
    cur += (n + 7u) & ~7u;
    return p;
}

static int64_t take_i64(void)
{
    int64_t v;
    memcpy(&v, take(8), 8);
    return v;
}

static double take_f64(void)
{
    double v;
    memcpy(&v, take(8), 8);
    return v;
}

int main(void)
{
    static char cmd[512];
    char *argv[4] = {0};
    int argc = 0, bench, press;
    char *p;
    int32_t fd, got;
    int64_t size, n, i, n_audio = 0, n_ev = 0, n_rev = 0;
    const double *x, *y, *f = 0;
    sd_config_t C;
    int rc;
    if (m4_cmdline(cmd, sizeof cmd) != 0) return 2;
    for (p = cmd; *p && argc < 4;) {           /* split on spaces */
        while (*p == ' ') *p++ = 0;
        if (*p) argv[argc++] = p;
        while (*p && *p != ' ') p++;
    }
    if (argc != 4) return 2;
    bench = strcmp(argv[1], "bench") == 0 || strcmp(argv[1], "react-bench") == 0;
    press = strncmp(argv[1], "react", 5) == 0;
    fd = m4_open(argv[2], 0);
    if (fd < 0) return 2;
    got = m4_read(fd, in_buf, sizeof in_buf);
    m4_close(fd);
    cur = (const uint8_t *)in_buf;
    end = cur + got;
    size = take_i64();
    rc = sd_image_load(&img, take((uint32_t)size), (size_t)size);
    if (rc != SD_OK) return 4;
    sd_image_config(&img, &C);
    C.policy = (int)take_i64();
    C.model = (int)take_i64();
    C.tick_rate = (sd_real)take_f64();
    C.audio_rate = (sd_real)take_f64();
    n = take_i64();
    if (n < 1 || n > TICKS_MAX) return 2;
    x = (const double *)take((uint32_t)(8 * n));
    y = (const double *)take((uint32_t)(8 * n));
    if (press) f = (const double *)take((uint32_t)(8 * n));
    for (i = 0; i < n; i++) {        /* the cursor in the runtime's real type, converted outside the count */
        xs[i] = (sd_real)x[i];
        ys[i] = (sd_real)y[i];
    }
    if (sd_renderer_init(&R, &img.table, &C) != SD_OK) return 3;
    fd = m4_open(argv[3], 1);
    if (fd < 0) return 2;
    for (i = 0; i < n; i++) {
        sd_real pi = press ? (sd_real)f[i] : (sd_real)0;   /* converted outside the count */
        if (bench) {
            sd_react_event_t e;
            m4_count_start();
            if (press) sd_renderer_step_press(&R, xs[i], ys[i], pi);
            else sd_renderer_step(&R, xs[i], ys[i]);
            counts[i] = m4_count_read();
            while (sd_react_pop(&R, &e)) {}      /* the host takes the events, outside the count */
        } else {
            long a;
            if (press) {
                sd_renderer_step_press(&R, xs[i], ys[i], pi);
                while (n_rev < (int64_t)REACT_MAX && sd_react_pop(&R, &rev_log[n_rev])) n_rev++;
            } else {
                sd_renderer_step(&R, xs[i], ys[i]);
            }
            write_outputs(fd, &R.out);
            if (n_audio + R.n_audio > (int64_t)(sizeof audio / sizeof audio[0])) return 2;
            for (a = 0; a < R.n_audio; a++) audio[n_audio + a] = (double)R.audio[a];
            n_audio += R.n_audio;
            {
                long nrec = (long)R.run.n_recent, nev = (long)R.out.events, e;
                if (nev > nrec) nev = nrec;              /* the tick's events stored in the ring */
                for (e = nrec - nev; e < nrec; e++) {
                    if (n_ev >= (int64_t)EVENTS_MAX) return 2;
                    ev_log[0][n_ev] = sd_event_time(&R, e);
                    ev_log[1][n_ev++] = (double)R.ev_a[e];
                }
            }
        }
    }
    if (bench) {
        m4_count_start();
        counts[n] = m4_count_read();        /* the measurement's own cost */
        m4_write(fd, counts, (uint32_t)(4 * (n + 1)));
    } else {
        int64_t counters[4];
        m4_write(fd, &n_audio, 8);
        m4_write(fd, audio, (uint32_t)(8 * n_audio));
        counters[0] = R.run.clipped;
        counters[1] = R.run.events_total;
        counters[2] = R.run.events_dropped;
        counters[3] = R.position_faults;
        m4_write(fd, counters, sizeof counters);
        m4_write(fd, &n_ev, 8);
        m4_write(fd, ev_log[0], (uint32_t)(8 * n_ev));
        m4_write(fd, ev_log[1], (uint32_t)(8 * n_ev));
        if (press) {
            m4_write(fd, &n_rev, 8);
            for (i = 0; i < n_rev; i++) {
                int64_t rec[3];
                double v = (double)rev_log[i].value;
                rec[0] = rev_log[i].kind;
                rec[1] = rev_log[i].widget;
                rec[2] = rev_log[i].tick;
                m4_write(fd, rec, sizeof rec);
                m4_write(fd, &v, 8);
            }
        }
    }
    m4_close(fd);
    return 0;
}
