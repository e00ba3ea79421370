/* sd_pad_common.h -- helpers shared by the two pad models (sd_pad.c "jump", sd_exact.c "exact").
 *
 * Private to the runtime: not part of the API in sd_runtime.h. Every function repeats the
 * floating-point operations of shapedisplay/runtime/pads.py in the same order (rules in
 * sd_pad.c), so both models stay bit-exact against the Python kernels. static inline: each
 * translation unit gets its own copy and an unused one draws no warning.
 */
#ifndef SD_PAD_COMMON_H
#define SD_PAD_COMMON_H

#include <math.h>
#include "sd_runtime.h"

#define SD_PI 3.141592653589793

static inline double sd_sgn(double x) { return x > 0.0 ? 1.0 : (x < 0.0 ? -1.0 : 0.0); }
/* Python's max(a, b) / min(a, b): the first argument unless the second is strictly larger/smaller. */
static inline double py_max(double a, double b) { return b > a ? b : a; }
static inline double py_min(double a, double b) { return b < a ? b : a; }

/* Python float modulo (sign of the divisor), as CPython's float_rem and numba. */
static inline double py_mod(double a, double b)
{
    double r = fmod(a, b);
    if (r != 0.0) {
        if ((b < 0.0) != (r < 0.0)) r += b;
    } else {
        r = copysign(0.0, b);
    }
    return r;
}

/* Free under-damped oscillator m y'' + c y' + k y = 0 from (y0, v0), at time t. */
static inline void osc_under(double m, double c, double k, double y0, double v0, double t, double *y, double *v)
{
    double sig = 0.5 * c / m, wn2 = k / m, disc = sig * sig - wn2;
    double wd = sqrt(-disc), e = exp(-sig * t), cs = cos(wd * t), sn = sin(wd * t);
    *y = e * (y0 * cs + (v0 + sig * y0) / wd * sn);
    *v = e * (v0 * cs - (wn2 * y0 + sig * v0) / wd * sn);
}

/* First time > after (>= 0) where the under-damped free oscillator's acceleration is zero. */
static inline double next_acc_zero_under(double m, double c, double k, double y0, double v0, double after)
{
    double sig = 0.5 * c / m, wn2 = k / m, disc = sig * sig - wn2;
    double a0 = -2.0 * sig * v0 - wn2 * y0;
    double j0 = -2.0 * sig * a0 - wn2 * v0;
    double wd = sqrt(-disc), bb = (j0 + sig * a0) / wd, phi, th1, tz;
    if (a0 == 0.0 && bb == 0.0) return INFINITY;
    phi = atan2(bb, a0);
    th1 = py_mod(phi + 0.5 * SD_PI, SD_PI);
    if (th1 < 1e-9 || th1 > SD_PI - 1e-9) {
        th1 = th1 > 1.0 ? SD_PI : th1 + SD_PI;
        if (th1 < SD_PI) th1 = SD_PI;
    }
    tz = th1 / wd;
    if (tz <= after) {            /* never with after = 0: th1 >= 1e-9 */
        double nper = floor((after - tz) * wd / SD_PI) + 1.0;
        tz = (th1 + nper * SD_PI) / wd;
        while (tz <= after) tz += SD_PI / wd;
    }
    return tz;
}

/* Store event (t, a) if there is room; return the event count including it. */
static inline int record(double *ev_t, double *ev_a, int cap, int n_ev, double t, double a)
{
    if (n_ev < cap) {
        ev_t[n_ev] = t;
        ev_a[n_ev] = a;
    }
    return n_ev + 1;
}

/* End-of-tick state shared by the exact and jump ticks, friction force included
 * (pads._finish_tick). The caller stores v (and tsl) itself. */
static inline void finish_tick(sd_pad_state_t *S, double x, double phase, double s, double age, double k,
                               double c, double V, double N, double muk, long n_events)
{
    S->x = x;
    S->phase = phase;
    S->s = s;
    S->age = age;
    S->n_events = n_events;
    if (phase == 0.0)
        S->f = k * x + c * V;
    else
        S->f = s * muk * N;
}

/* Slip direction and spring stretch at a breakaway with stick force f (pads._breakaway): a slip
 * forced by the maximum stick period starts from the breakaway stretch of the true N, so the burst,
 * the slip and the re-stick are those of a natural breakaway. */
static inline double breakaway(double *x, double f, double V, int forced, double mus, double N, double k,
                               double c)
{
    double s = sd_sgn(f);
    if (s == 0.0) s = V != 0.0 ? sd_sgn(V) : 1.0;
    if (forced) *x = (s * mus * N - c * V) / k;
    return s;
}

/* Fast path of both models: stuck for the whole tick (the stick force is linear in time, so
 * both ends inside the static limit means no breakaway in between) -- as pads.jump_tick and
 * pads.exact_tick. Returns 1 and advances the state if it applies, 0 otherwise. */
static inline int stuck_whole_tick(sd_pad_state_t *S, const sd_pad_t *P, double h, double V, double N,
                                   double mus)
{
    if (S->phase == 0.0 && P->p.max_stick_period == 0.0) {
        double k_ = P->p.stiffness, xe = S->x + V * h;
        double fa = k_ * S->x + P->p.damping * V, fe = k_ * xe + P->p.damping * V, thr_ = mus * N;
        if (fabs(fa) < thr_ && fabs(fe) < thr_) {
            S->x = xe;
            S->v = V;
            S->f = fe;
            S->n_events = 0;
            return 1;
        }
    }
    return 0;
}

#endif
