/* sd_baselines.c -- the comparison integrators of the accuracy and stability reports, one renderer tick at
 * a time: the Konyo pad with tanh-regularised Coulomb friction and one
 * fixed explicit step per tick, forward Euler or classical RK4. They are deliberately naive: the explicit ones blow up on the stiff Konyo pad (forward Euler
 * unless h < 2 zeta / omega_n, about 5 us; RK4 unless h < 2.8 / omega_n, about 63 us) and the tanh model
 * creeps below breakaway; the reports show exactly that.
 *
 * Double precision with the libm functions exp, sin, cos, sqrt, tanh (rules in sd_pad.c; compile with
 * -ffp-contract=off). Divergence detection: a non-finite state or |x| beyond the physical bound sets S->diverged (and S->diverged_at), freezes the
 * state at zero and every later tick outputs f = 0.
 *
 * Work per tick: euler and rk4 O(1), no loop. tanh: one substep per min(substep, time left) (h / substep
 * of them on a steady stroke), each with at most 60 closed-form oscillator evaluations (a substep that
 * would carry the slip speed through zero is cut at the crossing); at most SD_MAX_EVENTS_PER_TICK
 * substeps (a tick cut there counts in S->truncated).
 */
#include "sd_pad_common.h"

#ifndef SD_TANH
#ifdef SD_SINGLE
#define SD_TANH tanhf
#else
#define SD_TANH tanh
#endif
#endif

/* sqrt(2) and sqrt(2 e), the nearest doubles */
#define SD_SQRT2 SD_R(1.4142135623730951)
#define SD_SQRT2E SD_R(2.331643981597124)

/* ------------------------------------------------------------------ tanh-regularised Coulomb */
/* Friction on the pad at slip speed w = V - v and its slope df/dw:
 * f = N [(mu_s - mu_k) sqrt(2e) u exp(-u^2) + mu_k tanh(w / v_C)], u = w / v_St, v_St = sqrt(2) eps,
 * v_C = eps / 10. */
static void tanh_friction(sd_real w, sd_real N, sd_real mus, sd_real muk, sd_real eps, sd_real *f, sd_real *df)
{
    sd_real vst = SD_SQRT2 * eps;
    sd_real vc = SD_R(0.1) * eps;
    sd_real u = w / vst;
    sd_real e = SD_EXP(-u * u);
    sd_real th = SD_TANH(w / vc);
    sd_real dmu = mus - muk;
    *f = N * (dmu * SD_SQRT2E * u * e + muk * th);
    *df = N * (dmu * SD_SQRT2E * (SD_R(1.0) - SD_R(2.0) * u * u) * e / vst + muk * (SD_R(1.0) - th * th) / vc);
}

/* Konyo pad with tanh-regularised friction: linearly implicit exponential substeps (the
 * friction linearised about the current slip speed, the linear oscillator solved in closed form in
 * increment form); phase 1 while |w| >= 2 eps (entered: the burst event, interpolated in the substep),
 * 0 again once |w| <= eps. */
int sd_tanh_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                 sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev)
{
    sd_real m = P->p.mass, k = P->p.stiffness, c = P->p.damping;
    sd_real B = P->p.burst_gain * gain;
    sd_real eps = P->p.tanh_eps, hmax = P->p.substep;
    sd_real x = S->x, v = S->v, phase = S->phase;
    sd_real vc = SD_R(0.1) * eps, t = SD_R(0.0), f, df_end;
    int nev0 = n_ev;
    long it = 0;
    if (phase == SD_R(0.0) && SD_FABS(V - v) > SD_R(2.0) * eps)
        v = V;            /* a new surface speed while stuck: the pad takes it at once, as in `exact` */
    while (t < h) {
        sd_real w0, f0, df, ceff, hs, a0, x1, yh = SD_R(0.0), vh = SD_R(0.0), dx = SD_R(0.0), v1 = v, w1;
        int q;
        it += 1;
        if (it > SD_MAX_EVENTS_PER_TICK) {
            S->truncated += 1;
            break;
        }
        w0 = V - v;
        w1 = w0;
        tanh_friction(w0, N, mus, muk, eps, &f0, &df);
        ceff = c + df;
        hs = py_min(hmax, h - t);
        if (ceff < SD_R(0.0)) hs = py_min(hs, SD_R(0.5) * m / (-ceff));
        /* exponential Euler in increment form, Y1 = Y0 + A^-1 (e^{hA} - I) Y0' with Y = (x, v):
         * (e^{hA} - I) Y0' is the free oscillator started at (v0, a0), and A^-1 = [[-ceff/k, -m/k], [1, 0]] */
        a0 = (f0 - c * v - k * x) / m;
        for (q = 0; q < 60; q++) {
            osc_any(m, ceff, k, v, a0, hs, &yh, &vh);
            dx = yh - v;
            v1 = v + dx;
            w1 = V - v1;
            if (!(w0 * w1 < SD_R(0.0) && SD_FABS(w1) > vc && SD_FABS(w0) > vc) || hs <= SD_R(1e-15)) break;
            hs *= py_max(py_min(w0 / (w0 - w1), SD_R(0.5)), SD_R(1e-3));
        }
        x1 = x - (ceff * dx + m * (vh - a0)) / k;
        if (phase == SD_R(0.0) && SD_FABS(w1) >= SD_R(2.0) * eps) {
            sd_real fr;
            a0 = SD_FABS(w0);
            fr = SD_FABS(w1) > a0 ? (SD_R(2.0) * eps - a0) / (SD_FABS(w1) - a0) : SD_R(1.0);
            fr = py_min(py_max(fr, SD_R(0.0)), SD_R(1.0));
            n_ev = record(ev_t, ev_a, cap, n_ev, t0 + t + fr * hs, B * SD_FABS(k * (x + fr * (x1 - x))));
            phase = SD_R(1.0);
        } else if (phase == SD_R(1.0) && SD_FABS(w1) <= eps) {
            phase = SD_R(0.0);
        }
        x = x1;
        v = v1;
        t = t + hs < h ? t + hs : h;
    }
    tanh_friction(V - v, N, mus, muk, eps, &f, &df_end);
    S->x = x;
    S->v = v;
    S->phase = phase;
    S->f = f;
    S->work_friction = SD_R(0.0);
    S->work_damping = SD_R(0.0);
    S->n_events = n_ev - nev0;
    return n_ev;
}

/* ------------------------------------------------------------------ explicit one-step baselines */
/* One fixed explicit step per tick, forward Euler or RK4, with stick/slip switching.
 * Blow-up (|x| beyond a physical bound, or a non-finite state) sets S->diverged and S->diverged_at and
 * freezes the state at zero; every later tick outputs f = 0 and no event. */
static int explicit_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                         sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev,
                         int rk4)
{
    sd_real m = P->p.mass, k = P->p.stiffness, c = P->p.damping;
    sd_real B = P->p.burst_gain * gain;
    sd_real x = S->x, v = S->v, phase = S->phase, s = S->s;
    sd_real thr = mus * N, limit;
    int nev0 = n_ev;
    if (S->diverged != 0) {
        S->f = SD_R(0.0);
        S->n_events = 0;
        return n_ev;
    }
    if (phase == SD_R(0.0)) {
        sd_real f;
        x += V * h;
        v = V;
        f = k * x + c * V;
        if (SD_FABS(f) > thr || (thr == SD_R(0.0) && f != SD_R(0.0))) {
            s = sd_sgn(f);
            n_ev = record(ev_t, ev_a, cap, n_ev, t0 + h, B * SD_FABS(k * x));
            phase = SD_R(1.0);
        }
    } else {
        sd_real F = s * muk * N;
        if (rk4) {
            sd_real a1 = (F - c * v - k * x) / m;
            sd_real x2 = x + SD_R(0.5) * h * v;
            sd_real v2 = v + SD_R(0.5) * h * a1;
            sd_real a2 = (F - c * v2 - k * x2) / m;
            sd_real x3 = x + SD_R(0.5) * h * v2;
            sd_real v3 = v + SD_R(0.5) * h * a2;
            sd_real a3 = (F - c * v3 - k * x3) / m;
            sd_real x4 = x + h * v3;
            sd_real v4 = v + h * a3;
            sd_real a4 = (F - c * v4 - k * x4) / m;
            x = x + h / SD_R(6.0) * (v + SD_R(2.0) * v2 + SD_R(2.0) * v3 + v4);
            v = v + h / SD_R(6.0) * (a1 + SD_R(2.0) * a2 + SD_R(2.0) * a3 + a4);
        } else {
            sd_real a1 = (F - c * v - k * x) / m;
            sd_real xn = x + h * v;
            v = v + h * a1;
            x = xn;
        }
        if (-s * (v - V) <= SD_R(0.0)) {
            if (SD_FABS(k * x + c * V) <= thr) {
                phase = SD_R(0.0);
                v = V;
            } else {
                s = -s;
            }
        }
    }
    limit = SD_R(10.0) * (py_max(mus, muk) * N / k + SD_FABS(V) * (h + SD_SQRT(m / k))) + SD_R(1e-6);
    if (!(isfinite(x) && isfinite(v)) || SD_FABS(x) > limit) {
        S->diverged = 1;
        S->diverged_at = t0 + h;
        x = SD_R(0.0);
        v = SD_R(0.0);
        phase = SD_R(0.0);
    }
    S->x = x;
    S->v = v;
    S->phase = phase;
    S->s = s;
    S->f = phase == SD_R(0.0) ? k * x + c * V : s * muk * N;
    if (S->diverged != 0) S->f = SD_R(0.0);
    S->n_events = n_ev - nev0;
    return n_ev;
}

/* Forward Euler, one step per tick. */
int sd_euler_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                  sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev)
{
    return explicit_tick(S, P, t0, h, V, N, mus, muk, gain, ev_t, ev_a, cap, n_ev, 0);
}

/* Classical RK4, one step per tick. */
int sd_rk4_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev)
{
    return explicit_tick(S, P, t0, h, V, N, mus, muk, gain, ev_t, ev_a, cap, n_ev, 1);
}
