/* sd_runtime.h -- portable C99 runtime of the shapedisplay stick-slip renderer.
 *
 * Plays a friction-envelope table on a microcontroller: bilinear table lookup, the
 * quasi-static "jump" pad model, and the vibrotactile burst at every stick-to-slip event.
 * It reproduces the Python renderer (shapedisplay.runtime, model "jump") sample for
 * sample on shared test vectors (tests/test_c_runtime.py).
 *
 * Real-time rules: all memory is provided by the caller (tables are const arrays, e.g. from
 * `shapedisplay export --format c`, or a buffer received over the device link); nothing is
 * allocated after sd_renderer_init; sd_renderer_tick does bounded work per stick-slip
 * event and never blocks. Units are SI (m, s, N, kg, Hz).
 */
#ifndef SD_RUNTIME_H
#define SD_RUNTIME_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* Safety cap on phase changes inside one tick (never reached by physical inputs). */
#define SD_MAX_EVENTS_PER_TICK 200000L

/* ------------------------------------------------------------------ pad model */
typedef struct {
    double mass;              /* kg */
    double stiffness;         /* N/m */
    double damping;           /* N*s/m */
    double burst_gain;        /* B, output amplitude per newton of breakaway force */
    double max_stick_period;  /* s; 0 = off */
} sd_pad_params_t;

typedef struct {
    double x;        /* spring stretch, m */
    double v;        /* pad velocity, m/s */
    double phase;    /* 0 stick, 1 slip */
    double s;        /* sign of the friction force */
    double age;      /* time in the current stick phase, s */
    double ncap;     /* normal-force cap set by a forced breakaway, N (inf = none) */
    double tsl;      /* remaining slip time, s (inf = steady sliding) */
    double xr;       /* stretch at the coming re-stick, m */
    double f;        /* friction force at the end of the last tick, N */
    long truncated;  /* ticks cut at SD_MAX_EVENTS_PER_TICK */
    long n_events;   /* events in the last tick */
} sd_pad_state_t;

void sd_pad_reset(sd_pad_state_t *S);

/* Advance the jump model by one tick [t0, t0 + h] at surface velocity V (m/s), normal force N,
 * coefficients mus/muk and burst-gain multiplier gain. Stick-to-slip events (time s, burst
 * amplitude) are written to ev_t/ev_a[n_ev..cap-1]; returns the new event count (it may exceed
 * cap: the extra events are counted, not stored). */
int sd_jump_tick(sd_pad_state_t *S, const sd_pad_params_t *P, double t0, double h, double V, double N,
                 double mus, double muk, double gain, double *ev_t, double *ev_a, int cap, int n_ev);

/* Closed-form slip outcome (see pads.jump_restick): slip time (inf = steady sliding) and the
 * spring stretch at re-stick. */
void sd_jump_restick(double m, double c, double k, double s, double xb, double V, double muk, double N,
                     double *slip_time, double *x_restick);

#ifdef __cplusplus
}
#endif

#endif /* SD_RUNTIME_H */
