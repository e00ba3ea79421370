/* sd_pad.c -- the quasi-static "jump" stick-slip pad model, one renderer tick at a time.
 *
 * Every floating-point operation is written in a fixed order, in IEEE double precision in the
 * reference build, with the libm functions exp, sin, cos, atan2, sqrt, fmod, so on hosts with
 * the same libm the results are bit-identical; see runtime-c/README.md for the tolerance on other
 * targets. Compile as C99 without -ffast-math and without FMA contraction
 * (-ffp-contract=off), which would change the rounding of a*b+c.
 *
 * No allocation, no recursion; work per tick is O(1) plus O(1) per stick-slip event.
 */
#include <string.h>
#include "sd_pad_common.h"

void sd_pad_prepare(sd_pad_t *P, const sd_pad_params_t *params)
{
    sd_real m = params->mass, c = params->damping, k = params->stiffness;
    P->p = *params;
    P->sig = SD_R(0.5) * c / m;
    P->wn2 = k / m;
    P->disc = P->sig * P->sig - P->wn2;
    P->under = P->disc < -SD_R(1e-10) * P->wn2;
    P->wd = P->under ? SD_SQRT(-P->disc) : SD_R(0.0);
    P->tp = P->under ? SD_PI / P->wd : SD_R(0.0);
    P->e_tp = P->under ? SD_EXP(-P->sig * P->tp) : SD_R(0.0);
    P->sq = P->disc > SD_R(0.0) ? SD_SQRT(P->disc) : SD_R(0.0);
    P->phase_rate = SD_R(4.0) * (P->under ? P->wd : SD_SQRT(P->wn2)) / SD_PI;
}

/* 1 (the velocity peak after the first minimum reaches V) or -1 (it does
 * not) where a closed-form bound on |v| at the acceleration zeros decides with a wide margin, 0 where
 * the peak must be located (same operations, same constants). */
static int restick_peak_reaches(const sd_pad_t *P, sd_real e, sd_real s, sd_real y0, sd_real V)
{
    sd_real sig = P->sig, wn2 = P->wn2, wd = P->wd;
    sd_real a0 = -SD_R(2.0) * sig * V - wn2 * y0;
    sd_real j0 = -SD_R(2.0) * sig * a0 - wn2 * V;
    sd_real bb = (j0 + sig * a0) / wd, B, R2, e4, lo2;
    if (!(a0 * a0 > SD_R(1e-6) * (a0 * a0 + bb * bb))) return 0;
    B = (wn2 * y0 + sig * V) / wd;
    R2 = V * V + B * B;
    e4 = (e * e) * (e * e);
    lo2 = R2 * (wd * wd / wn2) * e4 * (SD_R(1.0) - SD_R(1e-9));
    if (!(lo2 > SD_R(1e-6) * R2 && lo2 * (SD_R(1.0) - SD_R(1e-6)) > V * V)) return 0;
    return s * a0 < SD_R(0.0) ? 1 : -1;
}

/* The closed-form re-stick of the jump model, with the pad constants (sig, wn2, disc, wd, pi/wd,
 * SD_EXP(-sig pi/wd)) computed once by sd_pad_prepare from the same expressions. */
static void restick(const sd_pad_t *P, sd_real s, sd_real xb, sd_real V, sd_real muk, sd_real N,
                    sd_real *slip_time, sd_real *x_restick)
{
    sd_real k = P->p.stiffness;
    sd_real sig = P->sig, wn2 = P->wn2, wd, xeq, y0, tp, e, yp, vp, ap, tz1, ypk, vpk, dt;
    int ok;
    *slip_time = INFINITY;
    *x_restick = xb;
    if (!P->under) return;
    wd = P->wd;
    xeq = s * muk * N / k;
    y0 = xb - xeq;
    tp = P->tp;
    e = P->e_tp;
    yp = -e * y0;
    vp = -e * V;
    ap = -SD_R(2.0) * sig * vp - wn2 * yp;
    if (s * ap <= SD_R(0.0)) return;
    ok = restick_peak_reaches(P, e, s, y0, V);
    if (ok < 0) return;
    if (ok == 0) {
        tz1 = next_acc_zero_under(P, y0, V, SD_R(0.0));
        if (tz1 == INFINITY) return;
        osc_under(P, y0, V, tz1 + SD_PI / wd, &ypk, &vpk);
        if (s * (vpk - V) < SD_R(0.0)) return;
    }
    dt = (V - vp) / ap;
    if (SD_FABS(dt) * wd > SD_R(0.5) * SD_PI) return;
    *x_restick = xeq + yp + vp * dt + SD_R(0.5) * ap * dt * dt;
    *slip_time = tp + dt;
}

void sd_jump_restick(sd_real m, sd_real c, sd_real k, sd_real s, sd_real xb, sd_real V, sd_real muk, sd_real N,
                     sd_real *slip_time, sd_real *x_restick)
{
    sd_pad_params_t params;
    sd_pad_t P;
    memset(&params, 0, sizeof params);
    params.mass = m;
    params.damping = c;
    params.stiffness = k;
    sd_pad_prepare(&P, &params);
    restick(&P, s, xb, V, muk, N, slip_time, x_restick);
}

void sd_pad_reset(sd_pad_state_t *S)
{
    memset(S, 0, sizeof *S);
    S->s = SD_R(1.0);
}

int sd_jump_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                 sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev)
{
    sd_real x, phase, s, age, tsl, t, k, c, B, tmax;
    int nev0;
    long it, it_cap;
    if (stuck_whole_tick(S, P, h, V, N, mus)) return n_ev;
    it_cap = phase_cap(P, h);
    k = P->p.stiffness;
    c = P->p.damping;
    B = P->p.burst_gain * gain;
    tmax = P->p.max_stick_period;
    x = S->x;
    phase = S->phase;
    s = S->s;
    age = S->age;
    tsl = S->slip_left;
    t = SD_R(0.0);
    nev0 = n_ev;
    it = 0;
    while (t < h) {
        sd_real rem;
        it += 1;
        if (it > it_cap) {
            S->truncated += 1;
            break;
        }
        rem = h - t;
        if (phase == SD_R(0.0)) {
            sd_real thr = mus * N;
            sd_real f = k * x + c * V;
            int forced;
            sd_real xr;
            if (SD_FABS(f) > thr * (SD_R(1.0) + SD_R(SD_TOL_BREAK)) || (SD_FABS(f) >= thr && f * V > SD_R(0.0) && thr > SD_R(0.0))
                || (thr == SD_R(0.0) && f != SD_R(0.0))) {
                forced = 0;
            } else {
                sd_real tb = INFINITY, tf, tn;
                if (V != SD_R(0.0)) tb = py_max((sd_sgn(V) * thr - f) / (k * V), SD_R(0.0));
                tf = tmax > SD_R(0.0) && V != SD_R(0.0) ? py_max(tmax - age, SD_R(0.0)) : INFINITY;
                tn = py_min(tb, tf);
                if (tn >= rem) {
                    x += V * rem;
                    if (V != SD_R(0.0)) age += rem;
                    t = h;
                    break;
                }
                x += V * tn;
                if (V != SD_R(0.0)) age += tn;
                t += tn;
                f = k * x + c * V;
                forced = tf < tb;
            }
            s = breakaway(&x, f, V, forced, mus, N, k, c);
            n_ev = record(ev_t, ev_a, cap, n_ev, t0 + t, B * SD_FABS(k * x));
            /* restick is a pure function: steady strokes repeat its inputs exactly, so the last
             * result is reused when they do (same bits in, same bits out). */
            if (S->memo_valid && S->memo_s == s && S->memo_x == x && S->memo_v == V && S->memo_muk == muk
                && S->memo_n == N) {
                tsl = S->memo_slip_time;
                xr = S->memo_x_restick;
            } else {
                restick(P, s, x, V, muk, N, &tsl, &xr);
                S->memo_valid = 1;
                S->memo_s = s;
                S->memo_x = x;
                S->memo_v = V;
                S->memo_muk = muk;
                S->memo_n = N;
                S->memo_slip_time = tsl;
                S->memo_x_restick = xr;
            }
            /* a re-stick force beyond the static limit (or no static friction) is no re-stick */
            if (thr <= SD_R(0.0) || SD_FABS(k * xr + c * V) > thr) tsl = INFINITY;
            S->x_restick = xr;
            phase = SD_R(1.0);
            age = SD_R(0.0);
            continue;
        }
        /* slip: count down the closed-form slip time, or slide steadily */
        if (tsl == INFINITY) {
            x = s * muk * N / k;
            if (s * V <= SD_R(0.0)) {
                phase = SD_R(0.0);
                age = SD_R(0.0);
                continue;
            }
            t = h;
            break;
        }
        if (tsl > rem) {
            tsl -= rem;
            t = h;
            break;
        }
        t += tsl;
        tsl = SD_R(0.0);
        x = S->x_restick;
        phase = SD_R(0.0);
        age = SD_R(0.0);
    }
    S->v = V;
    S->slip_left = tsl;
    finish_tick(S, x, phase, s, age, k, c, V, N, muk, n_ev - nev0);
    return n_ev;
}
