/* sd_exact.c -- the exact event-driven Konyo pad (model "exact"), one renderer tick at a time.
 *
 * IEEE double precision in the reference build (rules in sd_pad.c).
 * Stick phases are linear in time; slip phases are closed-form damped oscillations under
 * kinetic friction; re-stick is bracketed between the closed-form extrema of the pad velocity
 * and polished by safeguarded Newton. No allocation; bounded work per phase change.
 */
#include "sd_pad_common.h"

#define ADMIT (SD_R(1.0) - SD_R(SD_TOL_ADMIT))        /* re-stick admissible if |f| <= ADMIT * mu_s N */
#define ADMIT_TOUCH (SD_R(1.0) - SD_R(SD_TOL_TOUCH))  /* stricter for tangent touches (grazing the limit is no re-stick) */

/* Over-damped pad: the two real rates r1, r2 (the small root taken as wn2 / big root, which
 * keeps its precision) and the amplitudes of y = p e^(r1 t) + q e^(r2 t) from (y0, v0). */
static void over_modes(const sd_pad_t *P, sd_real y0, sd_real v0, sd_real *r1, sd_real *r2, sd_real *p, sd_real *q)
{
    sd_real sig = P->sig, wn2 = P->wn2, sq = P->sq;
    if (sig >= SD_R(0.0)) {
        *r2 = -sig - sq;
        *r1 = wn2 / *r2;
    } else {
        *r1 = -sig + sq;
        *r2 = wn2 / *r1;
    }
    *p = (v0 - *r2 * y0) / (*r1 - *r2);
    *q = y0 - *p;
}

/* Free damped oscillator m y'' + c y' + k y = 0 from (y0, v0) at time t (all damping cases). */
static void osc(const sd_pad_t *P, sd_real y0, sd_real v0, sd_real t, sd_real *y, sd_real *v)
{
    sd_real sig = P->sig, wn2 = P->wn2, disc = P->disc;
    if (disc < -SD_R(1e-10) * wn2) {
        osc_under(P, y0, v0, t, y, v);
        return;
    }
    if (disc > SD_R(1e-10) * wn2) {
        sd_real r1, r2, p, q, e1, e2;
        over_modes(P, y0, v0, &r1, &r2, &p, &q);
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

static sd_real acc(const sd_pad_t *P, sd_real y, sd_real v)
{
    return -(P->p.damping * v + P->p.stiffness * y) / P->p.mass;
}

static sd_real next_acc_zero(const sd_pad_t *P, sd_real y0, sd_real v0, sd_real after)
{
    sd_real sig = P->sig, wn2 = P->wn2, disc = P->disc;
    if (disc < -SD_R(1e-10) * wn2) return next_acc_zero_under(P, y0, v0, after);
    if (disc > SD_R(1e-10) * wn2) {
        sd_real r1, r2, p, q, num, den, tz;
        over_modes(P, y0, v0, &r1, &r2, &p, &q);
        num = -r2 * r2 * q;
        den = r1 * r1 * p;
        if (den == SD_R(0.0) || num / den <= SD_R(0.0)) return INFINITY;
        tz = SD_LOG(num / den) / (r1 - r2);
        return (tz > after && tz > SD_R(1e-15)) ? tz : INFINITY;
    }
    {
        sd_real w = sig, b = v0 + w * y0, tz;
        if (b == SD_R(0.0)) return INFINITY;
        tz = (SD_R(2.0) * b - w * y0) / (w * b);
        return (tz > after && tz > SD_R(1e-15)) ? tz : INFINITY;
    }
}

static sd_real wrel(const sd_pad_t *P, sd_real y0, sd_real v0, sd_real V, sd_real s, sd_real t)
{
    sd_real y, v;
    osc(P, y0, v0, t, &y, &v);
    return -s * (v - V);
}

/* Root of w in [lo, hi] with w(lo) = wlo >= 0 > w(hi) = whi, and the oscillator state there: safeguarded
 * Newton; a Newton step whose own error (|w''/2w'| dt^2 and omega^2 |dt|^3 / 6) is below the tolerance
 * ends it, with the state by Taylor expansion about the last evaluation. */
static sd_real polish(const sd_pad_t *P, sd_real y0, sd_real v0, sd_real V, sd_real s, sd_real lo, sd_real hi,
                      sd_real wlo, sd_real whi, sd_real *y_out, sd_real *v_out)
{
    sd_real m = P->p.mass, c = P->p.damping, k = P->p.stiffness, wn2 = k / m, t;
    int it;
    if (wlo - whi > SD_R(0.0)) t = lo + (hi - lo) * wlo / (wlo - whi);
    else t = SD_R(0.5) * (lo + hi);
    if (!(lo < t && t < hi)) t = SD_R(0.5) * (lo + hi);
    for (it = 0; it < SD_POLISH_MAX; it++) {
        sd_real y, v, wt, a, dw, tn, d, tol;
        int newton;
        osc(P, y0, v0, t, &y, &v);
        wt = -s * (v - V);
        if (wt == SD_R(0.0)) {
            *y_out = y;
            *v_out = v;
            return t;
        }
        if (wt > SD_R(0.0)) lo = t;
        else hi = t;
        a = acc(P, y, v);
        dw = -s * a;
        newton = dw != SD_R(0.0);
        tn = newton ? t - wt / dw : SD_R(0.5) * (lo + hi);
        if (!(lo < tn && tn < hi)) {
            tn = SD_R(0.5) * (lo + hi);
            newton = 0;
        }
        d = tn - t;
        tol = SD_R(SD_POLISH_ABS) + SD_R(SD_POLISH_REL) * t;
        if (newton) {
            sd_real j = -(c * a + k * v) / m, ad = SD_FABS(d);
            if (ad <= tol || hi - lo <= SD_R(SD_POLISH_ABS) + SD_R(SD_POLISH_REL) * hi
                || (SD_FABS(j) * d * d <= SD_R(2.0) * SD_FABS(a) * tol && wn2 * ad * ad * ad <= SD_R(6.0) * tol)) {
                *y_out = y + d * (v + d * (SD_R(0.5) * a + d * j / SD_R(6.0)));
                *v_out = v + d * (a + SD_R(0.5) * d * j);
                return tn;
            }
        } else if (SD_FABS(d) <= tol || hi - lo <= SD_R(SD_POLISH_ABS) + SD_R(SD_POLISH_REL) * hi) {
            osc(P, y0, v0, tn, y_out, v_out);
            return tn;
        }
        t = tn;
    }
    t = SD_R(0.5) * (lo + hi);
    osc(P, y0, v0, t, y_out, v_out);
    return t;
}

/* First re-stick candidate of a slip within rem seconds: kind 0 none (t = rem), 1 crossing,
 * 2 near-tangent touch. Touches before tmin are ignored (stepping past a grazing touch that
 * was not a re-stick). A slip starting with w(0) < -tol crosses at once (kind 1, t = 0). */
static int slip_search(const sd_pad_t *P, sd_real y0, sd_real v0, sd_real V, sd_real s, sd_real rem, sd_real tmin,
                       sd_real *t_out, sd_real *y_out, sd_real *v_out)
{
    /* acceleration zeros are pi / omega_d apart: at most rem omega_d / pi + 1 = rem phase_rate / 4 + 1 in
     * rem, plus grazing touches stepped over; twice that is the bound (no re-stick found: kind 0) */
    sd_real nmax = SD_R(8.0) + rem * P->phase_rate * SD_R(0.5);
    long n_it = 0, n_cap = nmax < SD_R(SD_MAX_EVENTS_PER_TICK) ? (long)nmax : SD_MAX_EVENTS_PER_TICK;
    sd_real tol = SD_R(SD_TOL_GRAZE) * (SD_FABS(V) + SD_FABS(v0)) + SD_R(SD_TINY);
    sd_real sig = P->sig, wn2 = P->wn2, disc = P->disc, ta = SD_R(0.0), wa = SD_R(0.0);
    int under = disc < -SD_R(1e-10) * wn2;
    /* the relative velocity already past zero by more than rounding (the surface velocity changed at a
     * tick boundary): a crossing at once */
    if (-s * (v0 - V) < -tol) {
        *t_out = SD_R(0.0);
        *y_out = y0;
        *v_out = v0;
        return 1;
    }
    if (sig >= SD_R(0.0) && under) {
        sd_real wd = P->wd, bv = (wn2 * y0 + sig * v0) / wd, amp = SD_SQRT(v0 * v0 + bv * bv);
        if (s * V - amp > SD_R(2.0) * tol) {
            *t_out = rem;
            osc(P, y0, v0, rem, y_out, v_out);
            return 0;
        }
    }
    for (;;) {
        sd_real tz, tb, wb, yb, vb;
        int interior, graze;
        if (++n_it > n_cap) {
            *t_out = rem;
            osc(P, y0, v0, rem, y_out, v_out);
            return 0;
        }
        tz = next_acc_zero(P, y0, v0, ta);
        interior = tz < rem;
        tb = interior ? tz : rem;
        osc(P, y0, v0, tb, &yb, &vb);
        wb = -s * (vb - V);
        graze = interior && wb >= -tol && wb <= tol;
        if (graze && tb < tmin) {
            ta = tb;
            wa = wb;
            continue;
        }
        if (wb < SD_R(0.0)) {
            /* w at the bracket's start: the last bracket's end, or w(0) -- under-damped, osc at t = 0
             * returns (y0, v0) exactly (exp, cos give 1, sin 0), so without the call */
            if (ta == SD_R(0.0)) wa = under ? -s * (v0 - V) : wrel(P, y0, v0, V, s, ta);
            *t_out = polish(P, y0, v0, V, s, ta, tb, wa, wb, y_out, v_out);
            if (interior && wb >= -tol) return 2;
            return 1;
        }
        *y_out = yb;
        *v_out = vb;
        if (wb == SD_R(0.0)) {
            *t_out = tb;
            return interior ? 2 : 1;
        }
        if (graze) {
            *t_out = tb;
            return 2;
        }
        if (!interior) {
            *t_out = rem;
            return 0;
        }
        ta = tb;
        wa = wb;
    }
}

/* End a re-stick root search at the state (y, v), acceleration a, at t, where the Newton step towards
 * v = V is d, if the rest of the root and the state there follow from the Taylor expansion about t to
 * rounding: the series reversion of v(t + x) = V to fourth order (its first omitted term below
 * SD_TOL_ROOT of the root time) and the Taylor polynomial of order 5 of the state (omega_n |d| <= 1e-3).
 * Returns 1 with the root and the state there, 0 if the step is too long. */
static int restick_end(const sd_pad_t *P, sd_real t, sd_real y, sd_real v, sd_real a, sd_real d,
                       sd_real *t_out, sd_real *y_out, sd_real *v_out)
{
    sd_real wn2 = P->wn2, c_m, d3, d4, d5, d6, ia, A, B, C, E, A2, d2, nxt, x, x2, x3, x4, x5;
    if (!(wn2 * d * d <= SD_R(1e-6))) return 0;
    c_m = P->p.damping / P->p.mass;
    d3 = -(c_m * a + wn2 * v);
    d4 = -(c_m * d3 + wn2 * a);
    d5 = -(c_m * d4 + wn2 * d3);
    d6 = -(c_m * d5 + wn2 * d4);
    ia = SD_R(1.0) / a;
    A = SD_R(0.5) * d3 * ia;
    B = (SD_R(1.0) / SD_R(6.0)) * d4 * ia;
    C = (SD_R(1.0) / SD_R(24.0)) * d5 * ia;
    E = (SD_R(1.0) / SD_R(120.0)) * d6 * ia;
    A2 = A * A;
    d2 = d * d;
    nxt = (SD_R(14.0) * A2 * A2 + SD_R(21.0) * A2 * SD_FABS(B) + SD_R(6.0) * SD_FABS(A * C) + SD_R(3.0) * B * B
           + SD_FABS(E)) * (d2 * d2 * SD_FABS(d));
    if (!(nxt <= SD_TOL_ROOT * SD_FABS(t + d))) return 0;
    x = d * (SD_R(1.0) + d * (-A + d * ((SD_R(2.0) * A2 - B) + d * (SD_R(5.0) * A * B - SD_R(5.0) * A2 * A - C))));
    x2 = SD_R(0.5) * x;
    x3 = (SD_R(1.0) / SD_R(3.0)) * x;
    x4 = SD_R(0.25) * x;
    x5 = SD_R(0.2) * x;
    *y_out = y + x * (v + x2 * (a + x3 * (d3 + x4 * (d4 + x5 * d5))));
    *v_out = v + x * (a + x2 * (d3 + x3 * (d4 + x4 * d5)));
    *t_out = t + x;
    return 1;
}

/* The root of w = -s (v - V) in (lo, hi), where w falls monotonically through 0, by Newton's method from
 * t with the state (y, v) there until restick_end ends it; with the outcome against the span rem: kind 1
 * (crossing before rem), 0 (none within rem: the state at rem) or -1 (no settled root, or the evaluation
 * at rem within rounding of it: the caller walks the brackets). */
static int restick_newton(const sd_pad_t *P, sd_real y0, sd_real v0, sd_real V, sd_real s, sd_real lo, sd_real hi,
                          sd_real t, sd_real y, sd_real v, sd_real rem, sd_real *t_out, sd_real *y_out, sd_real *v_out)
{
    sd_real c = P->p.damping, k = P->p.stiffness;
    int it;
    for (it = 0; it < 8; it++) {
        sd_real a = acc(P, y, v), d, tn, tr, yr, vr;
        if (!(s * a > SD_R(0.0))) break;
        d = (V - v) / a;
        tn = t + d;
        if (!(lo < tn && tn < hi)) break;
        if (restick_end(P, t, y, v, a, d, &tr, &yr, &vr)) {
            /* the root inside (lo, hi) with w' < 0 there, as on the way to it */
            if (!(lo < tr && tr < hi && s * (c * vr + k * yr) < SD_R(0.0))) break;
            if (tr < rem) {
                *t_out = tr;
                *y_out = yr;
                *v_out = vr;
                return 1;
            }
            osc(P, y0, v0, rem, &y, &v);
            if (s * (v - V) < SD_R(0.0)) {
                *t_out = rem;
                *y_out = y;
                *v_out = v;
                return 0;
            }
            break;
        }
        t = tn;
        osc(P, y0, v0, t, &y, &v);
    }
    return -1;
}

/* slip_search of a fresh slip (v0 = V, no touch to skip), from half a damped period on, where the state
 * is -e_tp times the start: a certain crossing in (tp, 2 tp) found by Newton's method from tp; anything
 * else goes to slip_search. */
static int fresh_slip_search(const sd_pad_t *P, sd_real y0, sd_real V, sd_real s, sd_real rem, sd_real *t_out,
                             sd_real *y_out, sd_real *v_out)
{
    sd_real sig = P->sig, wn2 = P->wn2, wd, a0, j0, bb, B, R2, tp, e, e4, lo2, sv2, y, v;
    sd_real tol = SD_R(SD_TOL_GRAZE) * (SD_FABS(V) + SD_FABS(V)) + SD_R(SD_TINY), sv = s * V;
    int kind;
    if (!(P->under && sig >= SD_R(0.0) && sv > SD_R(2.0) * tol)) return slip_search(P, y0, V, V, s, rem, SD_R(0.0), t_out, y_out, v_out);
    wd = P->wd;
    a0 = -SD_R(2.0) * sig * V - wn2 * y0;
    j0 = -SD_R(2.0) * sig * a0 - wn2 * V;
    bb = (j0 + sig * a0) / wd;
    B = (wn2 * y0 + sig * V) / wd;
    R2 = V * V + B * B;
    tp = P->tp;
    e = P->e_tp;
    e4 = (e * e) * (e * e);
    lo2 = R2 * (wd * wd / wn2) * e4 * (SD_R(1.0) - SD_R(1e-9));
    sv2 = sv + SD_R(2.0) * tol;
    if (!(s * a0 < SD_R(0.0) && a0 * a0 > SD_R(1e-6) * (a0 * a0 + bb * bb) && lo2 > sv2 * sv2 * (SD_R(1.0) + SD_R(1e-6))))
        return slip_search(P, y0, V, V, s, rem, SD_R(0.0), t_out, y_out, v_out);
    if (rem <= tp) {
        /* w > 0 on (0, rem]: no crossing in this span (as the evaluation at rem confirms) */
        osc(P, y0, V, rem, &y, &v);
        if (s * (v - V) < SD_R(0.0)) {
            *t_out = rem;
            *y_out = y;
            *v_out = v;
            return 0;
        }
        return slip_search(P, y0, V, V, s, rem, SD_R(0.0), t_out, y_out, v_out);
    }
    kind = restick_newton(P, y0, V, V, s, tp, tp + tp, tp, -e * y0, -e * V, rem, t_out, y_out, v_out);
    if (kind < 0) return slip_search(P, y0, V, V, s, rem, SD_R(0.0), t_out, y_out, v_out);
    return kind;
}

/* slip_search of a slip under way (w(0) above the tolerance, no touch to skip): the first trough of w from
 * the closed-form |v| at the acceleration zeros, a first guess from the half cosine through the peak and
 * the trough refined on the damped shape, Newton's method; anything else goes to slip_search
 *. */
static int continued_slip_search(const sd_pad_t *P, sd_real y0, sd_real v0, sd_real V, sd_real s, sd_real rem,
                                 sd_real *t_out, sd_real *y_out, sd_real *v_out)
{
    sd_real sig = P->sig, wn2 = P->wn2, wd, a0, j0, bb, tz1, tp, e, B, D, v1, lo, t_pk, w_pk, t_tr, w_tr, t, y, v;
    sd_real tol = SD_R(SD_TOL_GRAZE) * (SD_FABS(V) + SD_FABS(v0)) + SD_R(SD_TINY);
    int kind;
    if (!(P->under && sig >= SD_R(0.0) && -s * (v0 - V) > tol))
        return slip_search(P, y0, v0, V, s, rem, SD_R(0.0), t_out, y_out, v_out);
    wd = P->wd;
    a0 = -SD_R(2.0) * sig * v0 - wn2 * y0;
    j0 = -SD_R(2.0) * sig * a0 - wn2 * v0;
    bb = (j0 + sig * a0) / wd;
    if (!(a0 * a0 > SD_R(1e-6) * (a0 * a0 + bb * bb))) return slip_search(P, y0, v0, V, s, rem, SD_R(0.0), t_out, y_out, v_out);
    tz1 = acc_zero_phase_under(P, y0, v0) / wd;
    tp = P->tp;
    e = P->e_tp;
    B = (wn2 * y0 + sig * v0) / wd;
    D = SD_SQRT((v0 * v0 + B * B) * (wd * wd / wn2));
    v1 = D * SD_EXP(-sig * tz1);
    if (a0 < SD_R(0.0)) v1 = -v1;
    if (s * a0 > SD_R(0.0)) {
        /* w falls from the start to its trough at tz1 (its peak was tp before) */
        lo = SD_R(0.0);
        t_pk = tz1 - tp;
        w_pk = -s * (-v1 / e - V);
        t_tr = tz1;
        w_tr = -s * (v1 - V);
    } else {
        /* w rises to its peak at tz1, then falls to the trough half a period later */
        lo = tz1;
        t_pk = tz1;
        w_pk = -s * (v1 - V);
        t_tr = tz1 + tp;
        w_tr = -s * (-e * v1 - V);
        if (rem <= tz1) {
            osc(P, y0, v0, rem, &y, &v);
            if (s * (v - V) < SD_R(0.0)) {
                *t_out = rem;
                *y_out = y;
                *v_out = v;
                return 0;
            }
            return slip_search(P, y0, v0, V, s, rem, SD_R(0.0), t_out, y_out, v_out);
        }
    }
    if (!(w_tr < -SD_R(2.0) * tol - SD_R(1e-9) * D && w_pk > SD_R(0.0)))
        return slip_search(P, y0, v0, V, s, rem, SD_R(0.0), t_out, y_out, v_out);
    /* the half cosine's root, then two Newton steps on the damped shape between the peak and the trough
     * */
    {
        sd_real r = w_pk / (w_pk - w_tr), cu = SD_R(1.0) - SD_R(2.0) * r, su = SD_R(2.0) * SD_SQRT(r * (SD_R(1.0) - r));
        sd_real u = SD_ACOS(cu) / wd, v_pk = V - s * w_pk, q = sig / wd, g = wn2 / wd, eu = SD_EXP(-sig * u);
        sd_real fp = v_pk * eu * g * su;
        if (fp != SD_R(0.0)) {
            sd_real du = (v_pk * eu * (cu + q * su) - V) / fp, x = wd * du;
            if (SD_FABS(x) < SD_R(0.3)) {
                sd_real x2 = x * x;
                sd_real cx = SD_R(1.0) - x2 * (SD_R(0.5) - x2 * (SD_R(1.0) / SD_R(24.0) - x2 * (SD_R(1.0) / SD_R(720.0))));
                sd_real sx = x * (SD_R(1.0) - x2 * (SD_R(1.0) / SD_R(6.0) - x2 * (SD_R(1.0) / SD_R(120.0) - x2 * (SD_R(1.0) / SD_R(5040.0)))));
                sd_real c1 = cu * cx - su * sx, s1 = su * cx + cu * sx;
                sd_real e1 = eu * (SD_R(1.0) - sig * du * (SD_R(1.0) - SD_R(0.5) * sig * du));
                sd_real fp1 = v_pk * e1 * g * s1;
                if (fp1 != SD_R(0.0)) du += (v_pk * e1 * (c1 + q * s1) - V) / fp1;
            }
            u += du;
        }
        t = t_pk + u;
    }
    if (!(lo < t && t < t_tr)) t = SD_R(0.5) * (lo + t_tr);
    osc(P, y0, v0, t, &y, &v);
    kind = restick_newton(P, y0, v0, V, s, lo, t_tr, t, y, v, rem, t_out, y_out, v_out);
    if (kind < 0) return slip_search(P, y0, v0, V, s, rem, SD_R(0.0), t_out, y_out, v_out);
    return kind;
}

int sd_exact_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                  sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev)
{
    sd_real m, k, c, B, tmax, x, v, phase, s, age, t, tmin;
    int nev0;
    long it, it_cap;
    if (stuck_whole_tick(S, P, h, V, N, mus)) return n_ev;
    it_cap = phase_cap(P, h);
    m = P->p.mass;
    k = P->p.stiffness;
    c = P->p.damping;
    B = P->p.burst_gain * gain;
    tmax = P->p.max_stick_period;
    x = S->x;
    v = S->v;
    phase = S->phase;
    s = S->s;
    age = S->age;
    t = SD_R(0.0);
    nev0 = n_ev;
    it = 0;
    tmin = SD_R(0.0);
    while (t < h) {
        sd_real rem, F, xeq, y0, tr, y1, v1, fst, lim, afs;
        int kind;
        it += 1;
        if (it > it_cap) {
            S->truncated += 1;
            break;
        }
        rem = h - t;
        if (phase == SD_R(0.0)) {
            sd_real thr = mus * N, f = k * x + c * V;
            int brk = 0, forced = 0, loaded = 0;
            v = V;
            if (SD_FABS(f) > thr * (SD_R(1.0) + SD_R(SD_TOL_BREAK)) || (SD_FABS(f) >= thr && f * V > SD_R(0.0) && thr > SD_R(0.0))
                || (thr == SD_R(0.0) && f != SD_R(0.0))) {
                brk = 1;
            } else {
                sd_real tb = INFINITY, tf = INFINITY, tn;
                if (V != SD_R(0.0)) {
                    tb = (sd_sgn(V) * thr - f) / (k * V);
                    if (tb < SD_R(0.0)) tb = SD_R(0.0);
                }
                if (tmax > SD_R(0.0) && V != SD_R(0.0)) tf = py_max(tmax - age, SD_R(0.0));
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
                brk = 1;
                forced = tf < tb;
                loaded = tn > SD_R(0.0) && !forced;
            }
            if (brk) {
                s = breakaway(&x, f, V, forced, mus, N, k, c);
                /* loaded to the limit within this span: the breakaway stretch in closed form */
                if (loaded) x = (s * mus * N - c * V) / k;
                n_ev = record(ev_t, ev_a, cap, n_ev, t0 + t, B * SD_FABS(k * x));
                phase = SD_R(1.0);
                age = SD_R(0.0);
                continue;
            }
        }
        /* slip */
        F = s * muk * N;
        xeq = F / k;
        y0 = x - xeq;
        if (mus * N > SD_R(0.0)) {
            if (tmin == SD_R(0.0) && v == V)
                kind = fresh_slip_search(P, y0, V, s, rem, &tr, &y1, &v1);
            else if (tmin == SD_R(0.0))
                kind = continued_slip_search(P, y0, v, V, s, rem, &tr, &y1, &v1);
            else
                kind = slip_search(P, y0, v, V, s, rem, tmin, &tr, &y1, &v1);
        } else {
            kind = 0;            /* no static friction: nothing to stick to */
            tr = rem;
            osc(P, y0, v, tr, &y1, &v1);
        }
        tmin = SD_R(0.0);
        x = y1 + xeq;
        v = v1;
        t += tr;
        if (kind == 0) {
            t = h;
            break;
        }
        fst = k * x + c * V;
        lim = mus * N;
        afs = SD_FABS(fst);
        /* re-stick if static friction holds the pad: well inside the limit, or at the limit and moving
         * inwards (at the limit and moving outwards the stick would end at once). No static friction at
         * all (N = 0 or mu_s = 0): the pad never sticks again */
        if (lim > SD_R(0.0) && (afs <= (kind == 1 ? ADMIT : ADMIT_TOUCH) * lim
                                || (fst * V <= SD_R(0.0) && afs <= lim * (SD_R(1.0) + SD_R(SD_TOL_BREAK))))) {
            phase = SD_R(0.0);
            v = V;
            age = SD_R(0.0);
        } else if (kind == 1) {
            /* the pad passes the surface speed: the friction turns; after a located crossing the slip
             * goes on from w = 0 (the root's residual would read as a crossing back at once) */
            s = -s;
            if (tr > SD_R(0.0)) v = V;
        } else {
            /* grazing touch that is not a re-stick: keep slipping past it; the next touch or
             * crossing is at least one extremum (pi / omega_d) away */
            tmin = SD_R(0.5) * SD_PI * SD_SQRT(m / k);
        }
    }
    S->v = v;
    finish_tick(S, x, phase, s, age, k, c, V, N, muk, n_ev - nev0);
    return n_ev;
}
