/* sd_pad_common.h -- helpers shared by the two pad models (sd_pad.c "jump", sd_exact.c "exact").
 *
 * Private to the runtime: not part of the API in sd_runtime.h. The rules of the arithmetic are
 * sd_pad.c's. static inline: each
 * translation unit gets its own copy and an unused one draws no warning.
 */
#ifndef SD_PAD_COMMON_H
#define SD_PAD_COMMON_H

#include <math.h>
#include "sd_runtime.h"
#include "sd_math.h"


static inline sd_real sd_sgn(sd_real x) { return x > SD_R(0.0) ? SD_R(1.0) : (x < SD_R(0.0) ? -SD_R(1.0) : SD_R(0.0)); }
/* Python's max(a, b) / min(a, b): the first argument unless the second is strictly larger/smaller. */
static inline sd_real py_max(sd_real a, sd_real b) { return b > a ? b : a; }
static inline sd_real py_min(sd_real a, sd_real b) { return b < a ? b : a; }

/* Float modulo with the sign of the divisor (as Python's %). */
static inline sd_real py_mod(sd_real a, sd_real b)
{
    sd_real r = SD_FMOD(a, b);
    if (r != SD_R(0.0)) {
        if ((b < SD_R(0.0)) != (r < SD_R(0.0))) r += b;
    } else {
        r = SD_COPYSIGN(SD_R(0.0), b);
    }
    return r;
}

/* Free under-damped oscillator m y'' + c y' + k y = 0 from (y0, v0), at time t. The pad constants
 * (sig = c/2m, wn2 = k/m, wd) come from sd_pad_prepare, computed there by the expressions the Python
 * kernel evaluates on every call (same values, so the results are the same bits). */
static inline void osc_under(const sd_pad_t *P, sd_real y0, sd_real v0, sd_real t, sd_real *y, sd_real *v)
{
    sd_real sig = P->sig, wn2 = P->wn2;
    sd_real wd = P->wd, e = SD_EXP(-sig * t), cs = SD_COS(wd * t), sn = SD_SIN(wd * t);
    *y = e * (y0 * cs + (v0 + sig * y0) / wd * sn);
    *v = e * (v0 * cs - (wn2 * y0 + sig * v0) / wd * sn);
}

/* m y'' + c y' + k y = 0 from (y0, v0), at time t: under-, critically and over-damped, c = 0 and c < 0.
 * The damping changes from call to call (the linearised friction slope of the tanh and Stribeck slips), so
 * the constants are computed here. */
static inline void osc_any(sd_real m, sd_real c, sd_real k, sd_real y0, sd_real v0, sd_real t, sd_real *y, sd_real *v)
{
    sd_real sig = SD_R(0.5) * c / m;
    sd_real wn2 = k / m;
    sd_real disc = sig * sig - wn2;
    if (disc < -SD_R(1e-10) * wn2) {
        sd_real wd = SD_SQRT(-disc);
        sd_real e = SD_EXP(-sig * t), cs = SD_COS(wd * t), sn = SD_SIN(wd * t);
        *y = e * (y0 * cs + (v0 + sig * y0) / wd * sn);
        *v = e * (v0 * cs - (wn2 * y0 + sig * v0) / wd * sn);
        return;
    }
    if (disc > SD_R(1e-10) * wn2) {
        sd_real sq = SD_SQRT(disc), r1, r2, p, q, e1, e2;
        if (sig >= SD_R(0.0)) {
            r2 = -sig - sq;
            r1 = wn2 / r2;
        } else {
            r1 = -sig + sq;
            r2 = wn2 / r1;
        }
        p = (v0 - r2 * y0) / (r1 - r2);
        q = y0 - p;
        e1 = SD_EXP(r1 * t);
        e2 = SD_EXP(r2 * t);
        *y = p * e1 + q * e2;
        *v = r1 * p * e1 + r2 * q * e2;
        return;
    }
    {
        sd_real w = sig, a = y0, b = v0 + w * y0, e = SD_EXP(-w * t);
        *y = (a + b * t) * e;
        *v = (b - w * a - w * b * t) * e;
    }
}

/* The phase th1 (rad, in (0, pi]) of the under-damped free oscillator's first acceleration zero after
 * t = 0, the zeros being at (th1 + n pi) / wd; -1 if the acceleration is 0. */
static inline sd_real acc_zero_phase_under(const sd_pad_t *P, sd_real y0, sd_real v0)
{
    sd_real sig = P->sig, wn2 = P->wn2;
    sd_real a0 = -SD_R(2.0) * sig * v0 - wn2 * y0;
    sd_real j0 = -SD_R(2.0) * sig * a0 - wn2 * v0;
    sd_real wd = P->wd, bb = (j0 + sig * a0) / wd, phi, th1;
    if (a0 == SD_R(0.0) && bb == SD_R(0.0)) return -SD_R(1.0);
    phi = SD_ATAN2(bb, a0);
    th1 = py_mod(phi + SD_R(0.5) * SD_PI, SD_PI);
    if (th1 < SD_R(SD_TOL_PHASE) || th1 > SD_PI - SD_R(SD_TOL_PHASE)) {
        th1 = th1 > SD_R(1.0) ? SD_PI : th1 + SD_PI;
        if (th1 < SD_PI) th1 = SD_PI;
    }
    return th1;
}

/* First time > after (>= 0) where the under-damped free oscillator's acceleration is zero. */
static inline sd_real next_acc_zero_under(const sd_pad_t *P, sd_real y0, sd_real v0, sd_real after)
{
    sd_real wd = P->wd, th1 = acc_zero_phase_under(P, y0, v0), tz;
    int q;
    if (th1 < SD_R(0.0)) return INFINITY;
    tz = th1 / wd;
    if (tz <= after) {            /* never with after = 0: th1 >= 1e-9 */
        sd_real nper = SD_FLOOR((after - tz) * wd / SD_PI) + SD_R(1.0);
        tz = (th1 + nper * SD_PI) / wd;
        for (q = 0; tz <= after && q < 4; q++) tz += SD_PI / wd;   /* rounding: at most a step or two */
    }
    return tz;
}

/* Phase changes a tick of length h may take (SD_PHASES_BASE in sd_runtime.h); the ceiling also for NaN. */
static inline long phase_cap(const sd_pad_t *P, sd_real h)
{
    sd_real n = SD_R(SD_PHASES_BASE) + h * P->phase_rate;
    return n < SD_R(SD_MAX_EVENTS_PER_TICK) ? (long)n : SD_MAX_EVENTS_PER_TICK;
}

/* Store event (t, a) if there is room; return the event count including it. */
static inline int record(sd_real *ev_t, sd_real *ev_a, int cap, int n_ev, sd_real t, sd_real a)
{
    if (n_ev < cap) {
        ev_t[n_ev] = t;
        ev_a[n_ev] = a;
    }
    return n_ev + 1;
}

/* End-of-tick state shared by the exact and jump ticks, friction force included
 *. The caller stores v (and tsl) itself. */
static inline void finish_tick(sd_pad_state_t *S, sd_real x, sd_real phase, sd_real s, sd_real age, sd_real k,
                               sd_real c, sd_real V, sd_real N, sd_real muk, long n_events)
{
    S->x = x;
    S->phase = phase;
    S->s = s;
    S->age = age;
    S->n_events = n_events;
    if (phase == SD_R(0.0))
        S->f = k * x + c * V;
    else
        S->f = s * muk * N;
}

/* Slip direction and spring stretch at a breakaway with stick force f: a slip
 * forced by the maximum stick period starts from the breakaway stretch of the true N, so the burst,
 * the slip and the re-stick are those of a natural breakaway. */
static inline sd_real breakaway(sd_real *x, sd_real f, sd_real V, int forced, sd_real mus, sd_real N, sd_real k,
                               sd_real c)
{
    sd_real s = sd_sgn(f);
    if (s == SD_R(0.0)) s = V != SD_R(0.0) ? sd_sgn(V) : SD_R(1.0);
    if (forced) *x = (s * mus * N - c * V) / k;
    return s;
}

/* Fast path of both models: stuck for the whole tick (the stick force is linear in time, so
 * both ends inside the static limit means no breakaway in between), as the jump and exact
 * models use it. Returns 1 and advances the state if it applies, 0 otherwise. */
static inline int stuck_whole_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real h, sd_real V, sd_real N,
                                   sd_real mus)
{
    if (S->phase == SD_R(0.0) && P->p.max_stick_period == SD_R(0.0)) {
        sd_real k_ = P->p.stiffness, xe = S->x + V * h;
        sd_real fa = k_ * S->x + P->p.damping * V, fe = k_ * xe + P->p.damping * V, thr_ = mus * N;
        if (SD_FABS(fa) < thr_ && SD_FABS(fe) < thr_) {
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
