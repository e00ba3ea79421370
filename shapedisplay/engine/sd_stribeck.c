/* sd_stribeck.c -- the Imaizumi fingerpad with Stribeck friction on a laterally vibrating contactor
 * (model "stribeck"), one renderer tick at a time.
 *
 * The arithmetic is the runtime's (no fused multiply-add, libm through sd_math.h);
 * tests/test_c_stribeck.py and tests/test_stribeck_kernel.py hold it to independent answers
 * (Radau at tight tolerance, closed forms).
 *
 * Plain curve (stribeck_variant 0), mu = mu_k + (mu_s - mu_k) exp(-a |vr| / W) + b |vr| / W: stick in
 * closed form (the pad moves with the contactor; breakaway where the needed friction reaches mu_s W,
 * polished by safeguarded Newton), slip by steps whose local error stays below stribeck_tol of the
 * pad's scales: Taylor series steps of adaptive order below SD_STRIBECK_EXP_MIN_TOL, exponential
 * Rosenbrock steps from it up. Re-stick where the relative speed reaches zero with the needed friction
 * within mu_s W; otherwise the slip reverses.
 *
 * Pre-maximum variant (1): friction continuous through zero, exponential substeps of at most
 * `substep`; "stick" (state 0) is the pre-maximum region |vr| <= d W, left at |vr| >= 2 d W.
 *
 * Single precision: the slip tolerance is raised to SD_STRIBECK_TOL_FLOOR (the Taylor steps' error
 * control needs a tolerance far below float rounding, so that build always takes exponential steps),
 * and the rounding thresholds below are the float ones. No allocation; every loop is bounded
 * (engine/README.md, "Loops and their worst case per tick").
 */
#include "sd_pad_common.h"

#define R SD_R

/* Tolerances from this one up run the slip by exponential Rosenbrock steps */
#define SD_STRIBECK_EXP_MIN_TOL R(3e-9)
/* Highest order of a Taylor slip step, sign checks per step, step cap per call */
#define ST_MAX_ORDER 14
#define ST_SAMPLES 4
#define ST_MAX_TAYLOR_STEPS 20000L
/* How far a Taylor step's polynomial may miss the equation of motion at its end, in tolerances */
#define ST_TAYLOR_DEFECT_TOLS R(1e3)
/* Weights of the exponential step's error estimate */
#define ST_EXP_ERR_WEIGHT R(10.0)
#define ST_EXP_ERR_WEIGHT_OVERDAMPED R(3.0)
/* Terms of the responses' series in poly_basis at most */
#define ST_SERIES_TERMS 64

#ifdef SD_SINGLE
/* the loosest rounding the float build resolves: its slip tolerance is at least this */
#define SD_STRIBECK_TOL_FLOOR R(1e-5)
#define ST_TINY SD_TINY
#define ST_EXP_LO R(-87.0)          /* e^x below the smallest normal float: 0 */
#define ST_REL R(2.4e-7)            /* the Newton/bisection stopping rules' relative rounding (2 ulp) */
#define ST_ABS_BRACKET R(1e-12)     /* the series root's absolute bracket floor */
#define ST_STICK_GRAZE R(1e-9)      /* stick pieces quartered down to this long (a grazing touch) */
#define ST_LAND_REL R(2.4e-7)       /* a landing's bracket this short (relative to 1 + |t|) is landed */
#define ST_PREMAX_MIN R(2.4e-7)     /* a pre-maximum substep shorter than this (relative to max(1, |t|)): the rest */
#else
#define ST_TINY R(1e-300)
#define ST_EXP_LO R(-708.0)
#define ST_REL R(1e-16)
#define ST_ABS_BRACKET R(1e-17)
#define ST_STICK_GRAZE R(1e-13)
#define ST_LAND_REL R(1e-15)
#define ST_PREMAX_MIN R(1e-12)
#endif

/* e^x, 0 below ST_EXP_LO (no subnormal results) */
static inline sd_real st_exp(sd_real x) { return x < ST_EXP_LO ? R(0.0) : SD_EXP(x); }
static inline int finite_(sd_real x) { return x - x == R(0.0); }

/* The tick's constants. */
typedef struct {
    sd_real m, k, c, a, b, A, om, tol, substep;
} st_par_t;

static inline sd_real free_speed_scale(sd_real V, sd_real A, sd_real om, sd_real mus, sd_real W, sd_real k, sd_real m)
{
    return SD_FABS(V) + A * om + mus * W / SD_SQRT(k * m);
}

/* (W mu, W dmu/d|vr|) of the plain curve at relative speed vr_abs */
static void plain_friction(sd_real vr_abs, sd_real W, sd_real mus, sd_real muk, sd_real a, sd_real b, sd_real *muW,
                           sd_real *dmuW)
{
    sd_real e;
    if (!(W > R(0.0))) {
        *muW = R(0.0);
        *dmuW = R(0.0);
        return;
    }
    e = vr_abs > R(0.0) ? SD_EXP(-a * vr_abs / W) : R(1.0);
    *muW = W * (muk + (mus - muk) * e) + b * vr_abs;
    *dmuW = b - (mus - muk) * a * e;
}

/* ================================================================ stick */
typedef struct {
    sd_real ua, xca, Ca, Sa, ta;
} st_anchor_t;

static void stick_force(const st_par_t *P, sd_real V, const st_anchor_t *an, sd_real t, sd_real *u, sd_real *z,
                        sd_real *F, sd_real *dF)
{
    sd_real xc = R(0.0), dxc = R(0.0), ddxc = R(0.0), dddxc = R(0.0), A = P->A, om = P->om;
    if (A != R(0.0)) {
        sd_real ang = om * (t - an->ta), cd = SD_COS(ang), sd = SD_SIN(ang);
        sd_real cs = an->Ca * cd - an->Sa * sd, sn = an->Sa * cd + an->Ca * sd;
        xc = A * sn;
        dxc = A * om * cs;
        ddxc = -A * om * om * sn;
        dddxc = -A * om * om * om * cs;
    }
    *u = an->ua + (xc - an->xca) - V * (t - an->ta);
    *z = dxc - V;
    *F = P->m * ddxc + P->c * *z + P->k * *u;
    *dF = P->m * dddxc + P->c * ddxc + P->k * *z;
}

/* Stick from ta (stretch ua) to at most te: the first time |F| exceeds thr, or te. Returns broke. */
static int stribeck_stick(const st_par_t *P, sd_real V, sd_real thr, sd_real ua, sd_real ta, sd_real te,
                          int newton_stop, sd_real *t_out, sd_real *u_out, sd_real *z_out, sd_real *F_out)
{
    sd_real m = P->m, k = P->k, c = P->c, A = P->A, om = P->om, fpp, ue, ze, Fe, dFe, dt, u, z, Fa, dFa, tl, Fl, dFl;
    sd_real x, tb;
    st_anchor_t an;
    int broke = 0;
    long it;
    an.ua = ua;
    an.ta = ta;
    an.Ca = R(1.0);
    an.Sa = R(0.0);
    if (A != R(0.0)) {
        an.Ca = SD_COS(om * ta);
        an.Sa = SD_SIN(om * ta);
    }
    an.xca = A * an.Sa;
    if (A != R(0.0)) {
        sd_real q = k - m * om * om;
        fpp = A * om * om * SD_SQRT(q * q + (c * om) * (c * om));
    } else {
        fpp = R(0.0);
    }
    stick_force(P, V, &an, te, &ue, &ze, &Fe, &dFe);
    dt = te - ta;
    if (SD_FABS(Fe) + SD_FABS(dFe) * dt + R(0.5) * fpp * dt * dt <= thr) {
        *t_out = te;
        *u_out = ue;
        *z_out = ze;
        *F_out = Fe;
        return 0;
    }
    stick_force(P, V, &an, ta, &u, &z, &Fa, &dFa);
    if (SD_FABS(Fa) > thr) {
        *t_out = ta;
        *u_out = u;
        *z_out = z;
        *F_out = Fa;
        return 1;
    }
    tl = ta;
    Fl = Fa;
    dFl = R(0.0);
    x = ta;
    tb = te;
    for (it = 0; it < 100000L; it++) {
        sd_real xb, Fb;
        if (x >= te) break;
        if (dt > te - x) dt = te - x;
        xb = x + dt;
        if (xb == te) {
            u = ue;
            z = ze;
            Fl = Fe;
            dFl = dFe;
        } else {
            stick_force(P, V, &an, xb, &u, &z, &Fl, &dFl);
        }
        tl = xb;
        Fb = Fl;
        if (SD_FABS(Fb) > thr) {
            /* crossing in (x, xb]: root of |F| - thr (one crossing: the piece's curvature is small) */
            sd_real lo = x, hi = xb, sg = Fb > R(0.0) ? R(1.0) : -R(1.0), tt = hi;
            int j;
            tb = hi;
            for (j = 0; j < 100; j++) {
                sd_real f, tn;
                if (tt != tl) {
                    stick_force(P, V, &an, tt, &u, &z, &Fl, &dFl);
                    tl = tt;
                }
                f = sg * Fl - thr;
                if (f > R(0.0))
                    hi = tt;
                else
                    lo = tt;
                tn = dFl != R(0.0) ? tt - f / (sg * dFl) : R(0.5) * (lo + hi);
                if (newton_stop && SD_FABS(tn - tt) <= ST_REL * (R(1.0) + SD_FABS(tt))) {
                    tb = tn;
                    break;
                }
                if (!(lo < tn && tn <= hi)) tn = R(0.5) * (lo + hi);
                if (SD_FABS(tn - tt) <= ST_REL * (R(1.0) + SD_FABS(tt)) || hi - lo <= ST_REL * (R(1.0) + SD_FABS(hi))) {
                    tb = tn;
                    break;
                }
                tt = tn;
                tb = hi;
            }
            broke = 1;
            break;
        }
        if (py_max(SD_FABS(Fa), SD_FABS(Fb)) + R(0.125) * fpp * dt * dt <= thr || dt <= ST_STICK_GRAZE) {
            x = xb;
            Fa = Fb;
            dt *= R(2.0);
        } else {
            dt *= R(0.25);
        }
    }
    if (!broke) tb = x < te ? x : te;
    if (tb != tl) stick_force(P, V, &an, tb, &u, &z, &Fl, &dFl);
    *t_out = tb;
    *u_out = u;
    *z_out = z;
    *F_out = Fl;
    return broke;
}

/* ================================================================ linearised fallback step */
static int lin_step(const st_par_t *P, sd_real *u_io, sd_real *z_io, sd_real *sr_io, sd_real V, sd_real W, sd_real mus,
                    sd_real muk, sd_real *t_io, sd_real te)
{
    sd_real m = P->m, k = P->k, c = P->c, A = P->A, om = P->om, u = *u_io, z = *z_io, sr = *sr_io, t = *t_io;
    sd_real vr0, muW, dmuW, ceff, hs, dxcm, ueq, y1, dxc;
    vr0 = (z - (A != R(0.0) ? A * om * SD_COS(om * t) : R(0.0))) + V;
    plain_friction(py_max(sr * vr0, R(0.0)), W, mus, muk, P->a, P->b, &muW, &dmuW);
    ceff = c + dmuW;
    hs = py_min(te - t, P->substep);
    if (ceff < R(0.0)) hs = py_min(hs, R(0.5) * m / (-ceff));
    dxcm = A != R(0.0) ? A * om * SD_COS(om * (t + R(0.5) * hs)) : R(0.0);
    ueq = (-sr * muW - dmuW * (V - dxcm - vr0)) / k;
    osc_any(m, ceff, k, u - ueq, z, hs, &y1, &z);
    u = y1 + ueq;
    t = t + hs < te ? t + hs : te;
    dxc = A != R(0.0) ? A * om * SD_COS(om * t) : R(0.0);
    *t_io = t;
    *u_io = u;
    if (sr * (z + V - dxc) < R(0.0)) {
        sd_real ddxc = A != R(0.0) ? -A * om * om * SD_SIN(om * t) : R(0.0);
        if (SD_FABS(m * ddxc + c * (dxc - V) + k * u) <= mus * W) {
            *z_io = dxc - V;
            return 1;
        }
        sr = -sr;
    }
    *z_io = z;
    *sr_io = sr;
    return 0;
}

/* ================================================================ plain curve: Taylor slip steps */
typedef sd_real st_coef_t[5][ST_MAX_ORDER + 1];

static inline sd_real cos_phase(int j, sd_real C, sd_real S)
{
    int r = j & 3;
    return r == 0 ? C : (r == 1 ? -S : (r == 2 ? -C : S));
}

/* Taylor coefficients of a slip about t into co; returns the order p and the step in *h */
static int taylor_series(const st_par_t *P, sd_real W, sd_real V, sd_real mus, sd_real muk, sd_real sr, sd_real t,
                         sd_real u, sd_real z, sd_real hcap, st_coef_t co, sd_real *h_out)
{
    sd_real m = P->m, k = P->k, c = P->c, a = P->a, b = P->b, A = P->A, om = P->om, dmu = mus - muk;
    sd_real C = R(0.0), S = R(0.0), us, zs, tol = P->tol, cw, sa, e_prev, hc, hp, e1, e2, h1, h2;
    int pmax = ST_MAX_ORDER, p, j, fric, drop, flat = 0;
    if (A != R(0.0)) {
        C = SD_COS(om * t);
        S = SD_SIN(om * t);
    }
    us = R(1.0) / (mus * W / k + SD_FABS(u) + ST_TINY);
    zs = R(1.0) / (free_speed_scale(V, A, om, mus, W, k, m) + SD_FABS(z) + ST_TINY);
    co[0][0] = u;
    co[1][0] = z;
    cw = A * om;
    fric = W > R(0.0);
    sa = fric ? -a * sr / W : R(0.0);
    drop = fric && finite_(sa) &&
           dmu * W > R(1e-17) * (k * SD_FABS(u) + c * SD_FABS(z) + SD_FABS(b * (z + V)) + A * om * k);
    e_prev = R(1.0);
    p = pmax;
    hc = hcap;
    hp = R(1.0);
    for (j = 0; j <= pmax; j++) {
        sd_real vr = co[1][j] - cw * cos_phase(j, C, S), fr, e, hp_prev;
        cw *= om / (sd_real)(j + 1);
        if (j == 0) vr += V;
        co[2][j] = vr;
        if (j == pmax) break;
        if (fric) {
            sd_real E = R(0.0);
            if (drop) {
                sd_real g = sa * vr;
                co[3][j] = g;
                if (j == 0) {
                    E = SD_EXP(g);
                    if (g < R(-700.0)) {
                        /* far down the curve: E stays 0 over a step short enough that the exponent cannot climb by 100 */
                        flat = 1;
                        drop = 0;
                        E = R(0.0);
                    }
                } else {
                    sd_real acc = R(0.0);
                    int i;
                    for (i = 1; i <= j; i++) acc += (sd_real)i * co[3][i] * co[4][j - i];
                    E = acc / (sd_real)j;
                }
            }
            co[4][j] = E;
            fr = -sr * W * ((j == 0 ? muk : R(0.0)) + dmu * E) - b * vr;
        } else {
            fr = R(0.0);
        }
        co[0][j + 1] = co[1][j] / (sd_real)(j + 1);
        co[1][j + 1] = (fr - c * co[1][j] - k * co[0][j]) / (m * (sd_real)(j + 1));
        if (flat && j == 0) {
            sd_real g1 = sa * (co[1][1] + A * om * om * S);
            if (g1 > R(0.0) && R(100.0) / g1 < hc) {
                hc = R(100.0) / g1;
                hp = R(1.0);
            }
        }
        e = py_max(SD_FABS(co[0][j + 1]) * us, SD_FABS(co[1][j + 1]) * zs);
        hp_prev = hp;
        hp *= hc;
        if (j >= 3 && e * hp <= tol && e_prev * hp_prev <= tol && finite_(co[1][j + 1] + co[0][j + 1])) {
            p = j + 1;
            co[2][p] = co[1][p] - cw * cos_phase(p, C, S);
            *h_out = hc;
            return p;
        }
        e_prev = e;
    }
    /* full order: the step from the last two terms; an overflow anywhere reaches them and gives no step */
    e1 = py_max(SD_FABS(co[0][p - 1]) * us, SD_FABS(co[1][p - 1]) * zs);
    e2 = py_max(SD_FABS(co[0][p]) * us, SD_FABS(co[1][p]) * zs);
    if (!(finite_(e1) && finite_(e2) && finite_(co[2][p]))) {
        *h_out = R(0.0);
        return p;
    }
    h1 = e1 > R(0.0) ? SD_POW(tol / e1, R(1.0) / (sd_real)(p - 1)) : (sd_real)INFINITY;
    h2 = e2 > R(0.0) ? SD_POW(tol / e2, R(1.0) / (sd_real)p) : (sd_real)INFINITY;
    *h_out = py_min(py_min(h1, h2), hc);
    return p;
}

static inline sd_real horner(st_coef_t co, int row, int p, sd_real tau)
{
    sd_real acc = co[row][p];
    int j;
    for (j = p - 1; j >= 0; j--) acc = acc * tau + co[row][j];
    return acc;
}

static inline sd_real horner_d(st_coef_t co, int row, int p, sd_real tau, sd_real *d_out)
{
    sd_real acc = co[row][p], d = R(0.0);
    int j;
    for (j = p - 1; j >= 0; j--) {
        d = d * tau + acc;
        acc = acc * tau + co[row][j];
    }
    *d_out = d;
    return acc;
}

/* Root of sr vr (row 2) in (lo, hi] with sr vr(lo) > 0 >= sr vr(hi): safeguarded Newton */
static sd_real series_root(st_coef_t co, int p, sd_real sr, sd_real lo, sd_real hi)
{
    sd_real t = hi;
    int it;
    for (it = 0; it < 100; it++) {
        sd_real d, f = horner_d(co, 2, p, t, &d), tn;
        f *= sr;
        d *= sr;
        if (f > R(0.0))
            lo = t;
        else
            hi = t;
        tn = d != R(0.0) ? t - f / d : R(0.5) * (lo + hi);
        if (!(lo < tn && tn <= hi)) tn = R(0.5) * (lo + hi);
        if (SD_FABS(tn - t) <= ST_REL * (R(1.0) + SD_FABS(t)) || hi - lo <= ST_ABS_BRACKET + ST_REL * hi) return tn;
        t = tn;
    }
    return hi;
}

/* Whether the step's polynomial at tau satisfies the equation of motion */
static int taylor_defect_ok(const st_par_t *P, st_coef_t co, int p, sd_real tau, sd_real sr, sd_real V, sd_real W,
                            sd_real mus, sd_real muk, sd_real t, sd_real z0, sd_real *u1, sd_real *z1)
{
    sd_real m = P->m, k = P->k, c = P->c, A = P->A, om = P->om, zd, vr1, fr = R(0.0), d, zsc;
    *u1 = horner(co, 0, p, tau);
    *z1 = horner_d(co, 1, p, tau, &zd);
    vr1 = *z1 + V - (A != R(0.0) ? A * om * SD_COS(om * (t + tau)) : R(0.0));
    if (W > R(0.0)) {
        sd_real x = -P->a * sr * vr1 / W, E = x > R(-700.0) ? SD_EXP(x) : R(0.0);
        fr = -sr * W * (muk + (mus - muk) * E) - P->b * vr1;
    }
    d = SD_FABS(zd - (fr - c * *z1 - k * *u1) / m) * tau;
    zsc = free_speed_scale(V, A, om, mus, W, k, m) + SD_FABS(z0);
    return d <= ST_TAYLOR_DEFECT_TOLS * P->tol * zsc;
}

/* Slip of the plain curve from t to at most te by Taylor steps; returns stuck */
static int taylor_slip(const st_par_t *P, sd_real *u_io, sd_real *z_io, sd_real *sr_io, sd_real V, sd_real W, sd_real mus,
                       sd_real muk, sd_real *t_io, sd_real te)
{
    sd_real m = P->m, k = P->k, c = P->c, A = P->A, om = P->om, u = *u_io, z = *z_io, sr = *sr_io, t = *t_io;
    sd_real hmin = R(1e-6) * SD_SQRT(m / k), hlim = (sd_real)INFINITY;
    st_coef_t co;
    long it;
    int stuck = 0;
    for (it = 0; it < SD_MAX_EVENTS_PER_TICK; it++) {
        sd_real hs, lo, flo, root, tau, ddxc, dxc, Fst, srn;
        int p, i;
        if (t >= te) break;
        p = taylor_series(P, W, V, mus, muk, sr, t, u, z, py_min(py_min(te - t, P->substep), hlim), co, &hs);
        if (!(hs >= hmin) || it >= ST_MAX_TAYLOR_STEPS) {
            /* the series cannot follow the curve here: a linearised step keeps the state bounded */
            if (lin_step(P, &u, &z, &sr, V, W, mus, muk, &t, te)) {
                stuck = 1;
                break;
            }
            continue;
        }
        /* first sign change of sr vr over the step */
        lo = R(0.0);
        flo = sr * co[2][0];
        root = -R(1.0);
        for (i = 1; i <= ST_SAMPLES; i++) {
            sd_real f;
            tau = hs * (sd_real)i / (sd_real)ST_SAMPLES;
            f = sr * horner(co, 2, p, tau);
            if (f <= R(0.0)) {
                if (flo > R(0.0))
                    root = series_root(co, p, sr, lo, tau);
                else if (i == 1 && flo == R(0.0))
                    root = R(0.0);      /* starting at vr = 0 and moving the other way */
                break;
            }
            lo = tau;
            flo = f;
        }
        if (root != R(0.0)) {
            sd_real u1, z1;
            tau = root < R(0.0) ? hs : root;
            if (!taylor_defect_ok(P, co, p, tau, sr, V, W, mus, muk, t, z, &u1, &z1)) {
                hlim = R(0.5) * tau;
                continue;
            }
            hlim = (sd_real)INFINITY;
            u = u1;
            z = z1;
            if (root < R(0.0)) {
                t = t + hs < te ? t + hs : te;
                continue;
            }
            t += root;
        }
        /* relative speed zero: re-stick if the friction needed to follow the contactor is admissible */
        ddxc = A != R(0.0) ? -A * om * om * SD_SIN(om * t) : R(0.0);
        dxc = A != R(0.0) ? A * om * SD_COS(om * t) : R(0.0);
        Fst = m * ddxc + c * (dxc - V) + k * u;
        if (SD_FABS(Fst) <= mus * W) {
            z = dxc - V;
            stuck = 1;
            break;
        }
        srn = Fst > R(0.0) ? -R(1.0) : R(1.0);
        if (srn == sr && root == R(0.0)) {
            /* a touch of zero at the step's start (a breakaway exactly at the limit): take the step as it is */
            u = horner(co, 0, p, hs);
            z = horner(co, 1, p, hs);
            t = t + hs < te ? t + hs : te;
            continue;
        }
        sr = srn;
    }
    *u_io = u;
    *z_io = z;
    *sr_io = sr;
    *t_io = t;
    return stuck;
}

/* ================================================================ plain curve: exponential slip steps */
/* e^x - 1 - x */
static inline sd_real expm1_minus_x(sd_real x)
{
    if (SD_FABS(x) < R(0.25)) {
        sd_real x2 = x * x, x4 = x2 * x2, x8 = x4 * x4;
        sd_real lo = (R(0.5) + x * R(1.0 / 6)) + x2 * (R(1.0 / 24) + x * R(1.0 / 120));
        sd_real mid = (R(1.0 / 720) + x * R(1.0 / 5040)) + x2 * (R(1.0 / 40320) + x * R(1.0 / 362880));
        sd_real hi = (R(1.0 / 3628800) + x * R(1.0 / 39916800)) + x2 * R(1.0 / 479001600);
        return x2 * ((lo + x4 * mid) + x8 * hi);
    }
    return (st_exp(x) - R(1.0)) - x;
}

/* Propagator of m u'' + ce u' + k u = 0 over h */
static void lin_propagator(sd_real m, sd_real ce, sd_real k, sd_real h, sd_real *p11, sd_real *p12, sd_real *p21,
                           sd_real *p22)
{
    sd_real sig = R(0.5) * ce / m, wn2 = k / m, disc = sig * sig - wn2;
    if (disc >= R(0.0)) {
        sd_real sq = SD_SQRT(disc), r1, r2, e2, x, d;
        if (sig >= R(0.0)) {
            r2 = -sig - sq;
            r1 = wn2 / r2;
        } else {
            r1 = -sig + sq;
            r2 = wn2 / r1;
        }
        e2 = st_exp(r2 * h);
        x = R(2.0) * sq * h;
        if (x > R(0.5)) {
            d = (st_exp(r1 * h) - e2) * (R(0.5) / sq);
        } else if (x < R(0.05)) {
            d = e2 * h * (R(1.0) + x * (R(0.5) + x * (R(1.0 / 6) + x * (R(1.0 / 24) + x * (R(1.0 / 120) + x * (
                    R(1.0 / 720) + x * (R(1.0 / 5040) + x * (R(1.0 / 40320) + x * R(1.0 / 362880)))))))));
        } else {
            d = e2 * h * ((st_exp(x) - R(1.0)) * (R(1.0) / x));
        }
        *p11 = e2 - r2 * d;
        *p12 = d;
        *p21 = -wn2 * d;
        *p22 = e2 + r1 * d;
        return;
    }
    {
        sd_real wd = SD_SQRT(-disc), e = st_exp(-sig * h), cs = SD_COS(wd * h), sn = SD_SIN(wd * h), d = e * sn / wd;
        *p11 = e * cs + sig * d;
        *p12 = d;
        *p21 = -wn2 * d;
        *p22 = e * cs - sig * d;
    }
}

/* (phi_2, phi_3, phi_4)(x) from e^x, |x| >= 1/2 */
static inline void phi234_of_exp(sd_real x, sd_real ex, sd_real *p2, sd_real *p3, sd_real *p4)
{
    sd_real ix = R(1.0) / x;
    *p2 = ((ex - R(1.0)) * ix - R(1.0)) * ix;
    *p3 = (*p2 - R(0.5)) * ix;
    *p4 = (*p3 - R(1.0 / 6)) * ix;
}

/* (phi_2, phi_3, phi_4)(x), phi_k(x) = sum_j x^j / (j + k)! */
static inline void phi234(sd_real x, sd_real *p2, sd_real *p3, sd_real *p4)
{
    if (SD_FABS(x) < R(0.5)) {
        sd_real x2 = x * x, x4 = x2 * x2, x8 = x4 * x4;
        sd_real lo = (R(1.0 / 24.0) + x * R(1.0 / 120.0)) + x2 * (R(1.0 / 720.0) + x * R(1.0 / 5040.0));
        sd_real mid = (R(1.0 / 40320.0) + x * R(1.0 / 362880.0)) + x2 * (R(1.0 / 3628800.0) + x * R(1.0 / 39916800.0));
        sd_real hi = (R(1.0 / 479001600.0) + x * R(1.0 / 6227020800.0)) +
                     x2 * (R(1.0 / 87178291200.0) + x * R(1.0 / 1307674368000.0));
        sd_real q4 = (lo + x4 * mid) + x8 * hi, q3 = x * q4 + R(1.0 / 6);
        *p2 = x * q3 + R(0.5);
        *p3 = q3;
        *p4 = q4;
        return;
    }
    phi234_of_exp(x, st_exp(x), p2, p3, p4);
}

/* poly_basis's responses by divided differences of the phi functions */
static void phi_basis(sd_real m, sd_real h, sd_real x1, sd_real x2, sd_real *o)
{
    sd_real a2, a3, a4, b2, b3, b4, c2, c3, d2, d3, unused, g;
    if (SD_FABS(x1) >= R(1.0)) {
        sd_real e = st_exp(R(0.5) * x1);
        phi234_of_exp(R(0.5) * x1, e, &c2, &c3, &unused);
        phi234_of_exp(x1, e * e, &a2, &a3, &a4);
    } else {
        phi234(x1, &a2, &a3, &a4);
        phi234(R(0.5) * x1, &c2, &c3, &unused);
    }
    phi234(x2, &b2, &b3, &b4);
    phi234(R(0.5) * x2, &d2, &d3, &unused);
    g = h / (m * (x1 - x2));
    o[0] = R(2.0) * h * g * (a3 - b3);
    o[1] = R(2.0) * g * (a2 - b2);
    o[2] = R(0.5) * g * (c2 - d2);
    o[3] = R(6.0) * h * g * (a4 - b4);
    o[4] = R(6.0) * g * (a3 - b3);
    o[5] = R(0.75) * g * (c3 - d3);
}

/* Whether poly_basis takes a step of h in closed form */
static inline int basis_in_closed_form(sd_real m, sd_real ce, sd_real wn, sd_real h, sd_real tol)
{
    sd_real sg = SD_FABS(ce) * h / m, w = wn * h, w2, w4;
    if (sg > R(6.0) || w > R(6.0)) return 1;
    w2 = w * w;
    w4 = w2 * w2;
    return R(1.3e-13) * (w4 + sg * w2 + sg * sg * sg) < tol * (w4 * w4);
}

/* Responses from rest of m u'' + ce u' + k u = s^2 and = s^3 (s = tau / h) at h and h / 2: o[0..5] =
 * (u, u', u'_mid) of the first, then of the second */
static void poly_basis(sd_real m, sd_real ce, sd_real k, sd_real wn, sd_real h, int lng, sd_real r11, sd_real r12,
                       sd_real r21, sd_real r22, sd_real eps, sd_real *o)
{
    sd_real sig, disc, sg, wh, a0, a1, b0, b1, u2, z2, zm2, u3, z3, zm3, w, fn, ih;
    int n;
    if (lng) {
        sd_real p11 = r11 * r11 + r12 * r21, p12 = r11 * r12 + r12 * r22, p21 = r21 * r11 + r22 * r21;
        sd_real p22 = r21 * r12 + r22 * r22, ik = R(1.0) / k, hm = R(0.5) * h;
        sd_real g2, g1, g0, f3, f2, f1, f0;
        ih = R(1.0) / h;
        g2 = ik * ih * ih;
        g1 = -R(2.0) * ce * g2 * ik;
        g0 = -(ce * g1 + R(2.0) * m * g2) * ik;
        o[0] = (g2 * h + g1) * h + g0 - p11 * g0 - p12 * g1;
        o[1] = R(2.0) * g2 * h + g1 - p21 * g0 - p22 * g1;
        o[2] = R(2.0) * g2 * hm + g1 - r21 * g0 - r22 * g1;
        f3 = g2 * ih;
        f2 = -R(3.0) * ce * f3 * ik;
        f1 = -(R(2.0) * ce * f2 + R(6.0) * m * f3) * ik;
        f0 = -(ce * f1 + R(2.0) * m * f2) * ik;
        o[3] = ((f3 * h + f2) * h + f1) * h + f0 - p11 * f0 - p12 * f1;
        o[4] = (R(3.0) * f3 * h + R(2.0) * f2) * h + f1 - p21 * f0 - p22 * f1;
        o[5] = (R(3.0) * f3 * hm + R(2.0) * f2) * hm + f1 - r21 * f0 - r22 * f1;
        return;
    }
    sig = R(0.5) * ce / m;
    disc = sig * sig - wn * wn;
    if (disc > R(0.0)) {
        sd_real sq = SD_SQRT(disc);
        if (R(2.0) * sq * h >= R(0.25)) {
            sd_real rb = sig >= R(0.0) ? -sig - sq : -sig + sq;
            phi_basis(m, h, rb * h, (wn * wn / rb) * h, o);
            return;
        }
    }
    sg = ce * h / m;
    wh = wn * wn * h * h;
    a0 = R(0.0);
    a1 = h * h / (R(12.0) * m);
    b0 = R(0.0);
    b1 = R(0.0);
    u2 = a1;
    z2 = R(4.0) * a1;
    w = R(1.0) / R(8.0);
    zm2 = R(4.0) * a1 * w;
    u3 = R(0.0);
    z3 = R(0.0);
    zm3 = R(0.0);
    fn = R(4.0);
    for (n = 5; n < ST_SERIES_TERMS; n++) {
        sd_real i1 = R(1.0) / (sd_real)n, i2 = R(1.0) / (sd_real)(n * (n - 1)), a2, b2;
        fn += R(1.0);
        a2 = -(sg * i1 * a1 + wh * i2 * a0);
        b2 = -(sg * i1 * b1 + wh * i2 * b0);
        if (n == 5) b2 += h * h / (R(20.0) * m);
        w *= R(0.5);
        u2 += a2;
        z2 += fn * a2;
        zm2 += fn * a2 * w;
        u3 += b2;
        z3 += fn * b2;
        zm3 += fn * b2 * w;
        a0 = a1;
        a1 = a2;
        b0 = b1;
        b1 = b2;
        if (SD_FABS(a2) * fn <= eps * SD_FABS(z2) && SD_FABS(b2) * fn <= eps * SD_FABS(z3)) break;
    }
    ih = R(1.0) / h;
    o[0] = u2;
    o[1] = z2 * ih;
    o[2] = zm2 * ih;
    o[3] = u3;
    o[4] = z3 * ih;
    o[5] = zm3 * ih;
}

/* The landing's constants that landing_refined needs besides the trial  */
typedef struct {
    sd_real sr, W, muk, dmu, E0, b, c, k, m, A, om;
} st_land_t;

/* The next trial step for a landing on sr vr = 0: the regula falsi's hg polished by Newton on the
 * trial's cubic, kept inside (lo, hi) */
static sd_real landing_refined(const st_land_t *L, sd_real hg, sd_real htr, sd_real lo, sd_real hi, sd_real q0,
                               sd_real qd0, sd_real q1, sd_real u1, sd_real z1, sd_real S1, sd_real ex, sd_real vr1)
{
    sd_real sr = L->sr, F1 = -sr * L->W * (L->muk + L->dmu * L->E0 * (R(1.0) + ex)) - L->b * vr1;
    sd_real m0 = htr * qd0, m1 = htr * sr * ((F1 - L->c * z1 - L->k * u1) / L->m + L->A * L->om * L->om * S1);
    sd_real s = hg / htr, h;
    int it;
    for (it = 0; it < 6; it++) {
        sd_real s2 = s * s, s3 = s2 * s, p, dp, ds;
        p = (q0 * (R(2.0) * s3 - R(3.0) * s2 + R(1.0)) + m0 * (s3 - R(2.0) * s2 + s) +
             q1 * (R(3.0) * s2 - R(2.0) * s3) + m1 * (s3 - s2));
        dp = q0 * (R(6.0) * s2 - R(6.0) * s) + m0 * (R(3.0) * s2 - R(4.0) * s + R(1.0)) +
             q1 * (R(6.0) * s - R(6.0) * s2) + m1 * (R(3.0) * s2 - R(2.0) * s);
        if (!(dp != R(0.0))) return hg;
        ds = p / dp;
        s -= ds;
        if (SD_FABS(ds) <= R(1e-12) * SD_FABS(s)) break;
    }
    h = s * htr;
    if (lo < h && h < hi) return h;
    return hg;
}

/* Slip of the plain curve from t to at most te by exponential Rosenbrock steps.
 * (C0, S0) = (cos, sin)(omega t) of the contactor, h0 the first step to try (0: the rest of the tick).
 * Returns stuck; *F_out the friction at the end, *hn_out the next step proposed. */
static int exp_slip(const st_par_t *P, sd_real *u_io, sd_real *z_io, sd_real *sr_io, sd_real V, sd_real W, sd_real mus,
                    sd_real muk, sd_real *t_io, sd_real te, sd_real C0, sd_real S0, sd_real h0, sd_real *F_out,
                    sd_real *hn_out)
{
    sd_real m = P->m, k = P->k, c = P->c, a = P->a, b = P->b, A = P->A, om = P->om, tol = P->tol;
    sd_real u = *u_io, z = *z_io, sr = *sr_io, t = *t_io;
    sd_real tol4 = SD_SQRT(SD_SQRT(tol)), eps_ser = py_max(R(1e-2) * tol, R(1e-17)), dmu = mus - muk;
    sd_real aw, mw2, wn, ik, hmin, usc0, zsc0, ew, vd, tsc, h, h_want, hn = R(0.0), vr0, E0, lo, hi, vlo, vhi, vtol;
    sd_real ttol, h_prev, e4_prev;
    int od, side, touch_checked;
    long it;
    st_land_t L;
    if (!(W > R(0.0))) b = R(0.0);       /* a lifted finger: no friction at all (the viscous term included) */
    aw = W > R(0.0) ? a / W : (sd_real)INFINITY;
    mw2 = k - m * om * om;
    wn = SD_SQRT(k / m);
    ik = R(1.0) / k;
    hmin = R(1e-6) * SD_SQRT(m / k);
    usc0 = mus * W / k;
    od = c + b >= R(2.0) * SD_SQRT(k * m);
    zsc0 = od ? SD_FABS(V) + A * om + mus * W / (c + b) : free_speed_scale(V, A, om, mus, W, k, m);
    ew = od ? ST_EXP_ERR_WEIGHT_OVERDAMPED : ST_EXP_ERR_WEIGHT;
    vd = SD_FABS(V) + A * om;
    tsc = vd > R(0.0) ? usc0 / vd : R(0.0);
    h = py_min(te - t, P->substep);
    h_want = h;
    if (h0 > R(0.0)) {
        h_want = py_min(h0, P->substep);
        h = py_min(h, h_want);
    }
    vr0 = z + V - A * om * C0;
    E0 = W > R(0.0) ? st_exp(-aw * py_max(sr * vr0, R(0.0))) : R(0.0);
    lo = R(0.0);
    hi = -R(1.0);
    side = 0;
    vlo = sr * vr0;
    vhi = R(0.0);
    vtol = R(1e-2) * tol * free_speed_scale(V, A, om, mus, W, k, m);
    ttol = R(0.1) * tol * tsc;
    h_prev = R(0.0);
    e4_prev = R(0.0);
    touch_checked = 0;
    L.W = W;
    L.muk = muk;
    L.dmu = dmu;
    L.b = b;
    L.c = c;
    L.k = k;
    L.m = m;
    L.A = A;
    L.om = om;
    for (it = 0; it < SD_MAX_EVENTS_PER_TICK; it++) {
        sd_real F0, vrd0, G, ce, sig, sig2, wn2, f0, up0, X, Y, ch, sh, q11, q12, q21, q22, r11, r12, r21, r22;
        sd_real ch2, sh2, uh, zh, um, zm, Cm, Sm, vrm, ue, ze, C1, S1, u1, z1, vr1, x, exx, ex, xm, R1, Rm, al3, al2;
        sd_real bs[6], du, dz, dzm, x2, xm2, du1, dz1, duq, dzq, eu, ez, err, ddz, q1, E_start, t_new, e4, grow;
        int cross, landed, lng;
        if (t >= te) break;
        /* linearisation: F(vr) ~ F0 + G (vr - vr0) */
        F0 = -sr * W * (muk + dmu * E0) - b * vr0;
        vrd0 = (F0 - c * z - k * u) / m + A * om * om * S0;
        G = a * dmu * E0 - b;
        ce = c - G;
        sig = R(0.5) * ce / m;
        sig2 = sig * sig;
        wn2 = k / m;
        if (ce < R(0.0)) {
            /* a self-excited step: growth up to e^3 */
            sd_real rgrow = SD_SQRT(sig2 + wn2) - sig;
            if (h * rgrow > R(3.0)) h = R(3.0) / rgrow;
        }
        if (sig2 < wn2) {
            /* an oscillating linear part: at most a quarter of its period per step */
            sd_real wd = SD_SQRT(wn2 - sig2);
            if (h * wd > R(0.5) * SD_PI) h = R(0.5) * SD_PI / wd;
        }
        if (!(h >= hmin) && h < te - t && hi < R(0.0)) {
            /* the curve's drop is steeper than any step resolves (a micronewton load): linearised steps */
            int stuck = lin_step(P, &u, &z, &sr, V, W, mus, muk, &t, te);
            if (A != R(0.0)) {
                C0 = SD_COS(om * t);
                S0 = SD_SIN(om * t);
            }
            if (stuck) {
                *u_io = u;
                *z_io = z;
                *sr_io = sr;
                *t_io = t;
                *F_out = R(0.0);
                *hn_out = R(0.0);
                return 1;
            }
            vr0 = z + V - A * om * C0;
            E0 = W > R(0.0) ? st_exp(-aw * py_max(sr * vr0, R(0.0))) : R(0.0);
            h = py_min(te - t, P->substep);
            h_want = h;
            lo = R(0.0);
            hi = -R(1.0);
            side = 0;
            vlo = sr * vr0;
            touch_checked = 0;
            continue;
        }
        /* m u'' + ce u' + k u = f0 - G A om cos(om s) (+ the remainder below) */
        f0 = F0 - G * (vr0 - V);
        up0 = f0 * ik;
        X = R(0.0);
        Y = R(0.0);
        if (A != R(0.0)) {
            sd_real Fc = -G * A * om / (mw2 * mw2 + ce * ce * om * om);
            X = Fc * mw2;
            Y = Fc * ce * om;
        }
        ch = SD_COS(R(0.25) * om * h);
        sh = SD_SIN(R(0.25) * om * h);
        lin_propagator(m, ce, k, R(0.25) * h, &q11, &q12, &q21, &q22);
        r11 = q11 * q11 + q12 * q21;
        r12 = q11 * q12 + q12 * q22;
        r21 = q21 * q11 + q22 * q21;
        r22 = q21 * q12 + q22 * q22;
        ch2 = ch * ch - sh * sh;
        sh2 = R(2.0) * ch * sh;
        uh = u - up0 - (X * C0 + Y * S0);
        zh = z - om * (Y * C0 - X * S0);
        um = r11 * uh + r12 * zh;
        zm = r21 * uh + r22 * zh;
        Cm = C0 * ch2 - S0 * sh2;
        Sm = S0 * ch2 + C0 * sh2;
        vrm = zm + om * (Y * Cm - X * Sm) + V - A * om * Cm;
        ue = r11 * um + r12 * zm;
        ze = r21 * um + r22 * zm;
        C1 = Cm * ch2 - Sm * sh2;
        S1 = Sm * ch2 + Cm * sh2;
        cross = 0;
        if (hi < R(0.0)) {
            /* the sign of sr vr at the first three quarters */
            sd_real q0 = sr * vr0, Cq = C0 * ch - S0 * sh, Sq = S0 * ch + C0 * sh, qa, qb, qc;
            qa = sr * ((q21 * uh + q22 * zh) + om * (Y * Cq - X * Sq) + V - A * om * Cq);
            qb = sr * vrm;
            Cq = Cm * ch - Sm * sh;
            Sq = Sm * ch + Cm * sh;
            qc = sr * ((q21 * um + q22 * zm) + om * (Y * Cq - X * Sq) + V - A * om * Cq);
            if (qa <= R(0.0)) {
                cross = 1;
                vhi = qa;
                vlo = q0;
            } else if (qb <= R(0.0)) {
                cross = 2;
                vhi = qb;
                vlo = qa;
            } else if (qc <= R(0.0)) {
                cross = 3;
                vhi = qc;
                vlo = qb;
            }
        }
        u1 = ue + up0 + X * C1 + Y * S1;
        z1 = ze + om * (Y * C1 - X * S1);
        vr1 = z1 + V - A * om * C1;
        if (cross > 0) {
            /* through zero inside the step: land on the crossing between the quarters around it */
            lo = R(0.25) * h * (sd_real)(cross - 1);
            hi = R(0.25) * h * (sd_real)cross;
            side = 0;
            h = lo + vlo * (hi - lo) / (vlo - vhi);
            if (!(lo < h && h < hi)) h = R(0.5) * (lo + hi);
            continue;
        }
        /* the curve's remainder at the end and the midpoint as a forcing al2 s^2 + al3 s^3 */
        x = W > R(0.0) ? -aw * sr * (vr1 - vr0) : R(0.0);
        exx = expm1_minus_x(x);
        xm = W > R(0.0) ? -aw * sr * (vrm - vr0) : R(0.0);
        R1 = E0 > R(0.0) ? -sr * W * dmu * E0 * exx : R(0.0);
        Rm = E0 > R(0.0) ? -sr * W * dmu * E0 * expm1_minus_x(xm) : R(0.0);
        al3 = R(2.0) * R1 - R(8.0) * Rm;
        al2 = R1 - al3;
        /* its response from rest, then once more along the corrected path (a Picard pass) */
        lng = basis_in_closed_form(m, ce, wn, h, tol);
        poly_basis(m, ce, k, wn, h, lng, r11, r12, r21, r22, eps_ser, bs);
        du = al2 * bs[0] + al3 * bs[3];
        dz = al2 * bs[1] + al3 * bs[4];
        dzm = al2 * bs[2] + al3 * bs[5];
        x2 = W > R(0.0) ? -aw * sr * (vr1 + dz - vr0) : R(0.0);
        xm2 = W > R(0.0) ? -aw * sr * (vrm + dzm - vr0) : R(0.0);
        exx = expm1_minus_x(x2);
        ex = exx + x2;
        R1 = E0 > R(0.0) ? -sr * W * dmu * E0 * exx : R(0.0);
        Rm = E0 > R(0.0) ? -sr * W * dmu * E0 * expm1_minus_x(xm2) : R(0.0);
        al3 = R(2.0) * R1 - R(8.0) * Rm;
        al2 = R1 - al3;
        du1 = du;
        dz1 = dz;
        du = al2 * bs[0] + al3 * bs[3];
        dz = al2 * bs[1] + al3 * bs[4];
        /* the error estimate: the Picard pass's change plus the cubic fit's change to a quadratic */
        duq = R1 * bs[0];
        dzq = R1 * bs[1];
        eu = (SD_FABS(du - duq) + SD_FABS(du - du1)) / (usc0 + SD_FABS(u));
        ez = (SD_FABS(dz - dzq) + SD_FABS(dz - dz1)) / (zsc0 + SD_FABS(z) + SD_FABS(vr1 - vr0) * (tsc / h));
        err = eu > ez ? eu : ez;
        if (!(eu <= err && ez <= err)) err = (sd_real)INFINITY;
        err *= ew;
        if (!(err <= tol)) {
            /* too long (or overflowed): shorten by the fourth-order rule */
            if (err > R(0.0) && finite_(err))
                h *= py_max(R(0.1), R(0.8) * SD_SQRT(SD_SQRT(tol / err)));
            else
                h *= R(0.1);
            h_want = h;
            hi = -R(1.0);
            lo = R(0.0);
            side = 0;
            vlo = sr * vr0;
            continue;
        }
        /* Aitken's extrapolation of the two passes where they contract */
        ddz = dz - dz1;
        if (SD_FABS(ddz) < R(0.5) * SD_FABS(dz1)) {
            sd_real fk = ddz / (dz1 - ddz);
            du += fk * (du - du1);
            dz += fk * ddz;
        }
        u1 += du;
        z1 += dz;
        vr1 = z1 + V - A * om * C1;
        q1 = sr * vr1;
        landed = 0;
        if (q1 > R(0.0) && hi < R(0.0) && !touch_checked) {
            /* a touch of zero inside the step: the cubic through the ends' values and rates */
            sd_real m0 = h * sr * ((F0 - c * z - k * u) / m + A * om * om * S0);
            if (m0 < R(0.0)) {
                sd_real F1 = -sr * W * (muk + dmu * E0 * (R(1.0) + ex)) - b * vr1;
                sd_real m1 = h * sr * ((F1 - c * z1 - k * u1) / m + A * om * om * S1);
                if (m1 > R(0.0)) {
                    sd_real q0 = sr * vr0, qa = R(6.0) * (q0 - q1) + R(3.0) * (m0 + m1);
                    sd_real qb = R(6.0) * (q1 - q0) - R(4.0) * m0 - R(2.0) * m1;
                    sd_real dq = SD_SQRT(py_max(qb * qb - R(4.0) * qa * m0, R(0.0))), sm;
                    if (qb >= R(0.0))
                        sm = -R(2.0) * m0 / (qb + dq);
                    else if (qa != R(0.0))
                        sm = (dq - qb) / (R(2.0) * qa);
                    else
                        sm = -m0 / qb;
                    if (R(0.0) < sm && sm < R(1.0)) {
                        sd_real s2 = sm * sm, s3 = s2 * sm, pm;
                        pm = (q0 * (R(2.0) * s3 - R(3.0) * s2 + R(1.0)) + m0 * (s3 - R(2.0) * s2 + sm) +
                              q1 * (R(3.0) * s2 - R(2.0) * s3) + m1 * (s3 - s2));
                        if (pm < -vtol) {
                            touch_checked = 1;
                            h *= sm;
                            continue;
                        }
                    }
                }
            }
        }
        L.sr = sr;
        L.E0 = E0;
        if (q1 <= R(0.0)) {
            /* through zero: land on it (Illinois-modified regula falsi on the step length) */
            if (-q1 <= vtol || h - lo <= py_max(ST_LAND_REL * (R(1.0) + SD_FABS(t)), ttol)) {
                landed = 1;
            } else {
                if (side == 1) vlo *= R(0.5);
                side = 1;
                hi = h;
                vhi = q1;
                h = lo + vlo * (hi - lo) / (vlo - vhi);
                if (!(lo < h && h < hi)) h = R(0.5) * (lo + hi);
                h = landing_refined(&L, h, hi, lo, hi, sr * vr0, sr * vrd0, q1, u1, z1, S1, ex, vr1);
                continue;
            }
        } else if (hi > R(0.0)) {
            /* a trial short of the zero found before */
            if (q1 <= vtol || hi - h <= py_max(ST_LAND_REL * (R(1.0) + SD_FABS(t)), ttol)) {
                landed = 1;
            } else {
                sd_real htr;
                if (side == -1) vhi *= R(0.5);
                side = -1;
                htr = h;
                lo = h;
                vlo = q1;
                h = lo + vlo * (hi - lo) / (vlo - vhi);
                if (!(lo < h && h < hi)) h = R(0.5) * (lo + hi);
                h = landing_refined(&L, h, htr, lo, hi, sr * vr0, sr * vrd0, q1, u1, z1, S1, ex, vr1);
                continue;
            }
        }
        /* accept the step */
        E_start = E0;
        t_new = t + h < te ? t + h : te;
        u = u1;
        z = z1;
        C0 = C1;
        S0 = S1;
        t = t_new;
        if (landed) {
            /* on the zero of the relative speed: re-stick if the needed friction is admissible */
            sd_real dxc = A * om * C0, ddxc = -A * om * om * S0, Fst = m * ddxc + c * (dxc - V) + k * u;
            if (SD_FABS(Fst) <= mus * W) {
                *u_io = u;
                *z_io = dxc - V;
                *sr_io = sr;
                *t_io = t;
                *F_out = -Fst;
                *hn_out = R(0.0);
                return 1;
            }
            sr = Fst > R(0.0) ? -R(1.0) : R(1.0);
            vr0 = R(0.0);
            E0 = W > R(0.0) ? R(1.0) : R(0.0);
            z = dxc - V;
        } else {
            /* the curve at the corrected end: E0 e^x e^d, d = -a sr dz / W */
            sd_real d = W > R(0.0) ? -aw * sr * (dz - dz1) : R(0.0);
            vr0 = vr1;
            if (ex < -R(0.5))
                E0 = W > R(0.0) ? st_exp(-aw * sr * vr1) : R(0.0);
            else if (SD_FABS(d) < R(0.05))
                E0 = W > R(0.0) ? E0 * (R(1.0) + ex) *
                                      (R(1.0) + d * (R(1.0) + d * (R(0.5) + d * (R(1.0) / R(6.0) + d * (R(1.0) / R(24.0))))))
                                : R(0.0);
            else
                E0 = E0 * (R(1.0) + ex) * st_exp(d);
        }
        lo = R(0.0);
        hi = -R(1.0);
        side = 0;
        vlo = sr * vr0;
        touch_checked = 0;
        /* next step: the fourth-order rule with Gustafsson's prediction */
        e4 = SD_SQRT(SD_SQRT(err));
        if (err <= tol * R(1.5e-3)) {
            grow = err > R(0.0) ? py_min(R(8.0), R(0.8) * tol4 / e4) : R(8.0);
        } else {
            sd_real gmax = R(2.0);
            grow = R(0.8) * tol4 / e4;
            if (E0 < E_start && !landed) {
                grow *= E0 > R(0.0) ? SD_SQRT(SD_SQRT(E_start / E0)) : R(4.0);
                gmax = R(8.0);
            } else if (E0 > E_start && !landed && e4_prev == R(0.0)) {
                grow *= SD_SQRT(SD_SQRT(E_start / E0));
            }
            if (e4_prev > R(0.0)) {
                sd_real gus = grow * (h / h_prev) * (e4_prev / e4);
                if (gus < grow) grow = gus;
            }
            grow = py_min(gmax, py_max(R(0.2), grow));
        }
        if (t >= te) {
            /* the next tick starts with the step wanted here, or shorter if this one asks for less */
            hn = h_want;
            if (h * grow < hn && (h >= R(0.5) * h_want || grow < R(1.0))) hn = h * grow;
            break;
        }
        h_prev = h;
        e4_prev = e4;
        h_want = py_min(h * grow, P->substep);
        h = py_min(h_want, te - t);
        if (te - t < R(1.25) * h && te - t <= P->substep) h = te - t;
    }
    *u_io = u;
    *z_io = z;
    *sr_io = sr;
    *t_io = t;
    *F_out = -sr * W * (muk + dmu * E0) - b * (z + V - A * om * C0);
    *hn_out = hn;
    return 0;
}

/* ================================================================ the plain curve's tick */
static int plain_tick(sd_pad_state_t *S, const st_par_t *P, sd_real t0, sd_real h, sd_real V, sd_real W, sd_real mus,
                      sd_real muk, sd_real B, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev)
{
    sd_real k = P->k, A = P->A, om = P->om, u = S->x, z = S->v, phase = S->phase, sr, Ct = R(1.0), St = R(0.0);
    sd_real tcs = -(sd_real)INFINITY, t, te, thr, F = R(0.0);
    int expo = P->tol >= SD_STRIBECK_EXP_MIN_TOL;
    long it;
    sr = S->s != R(0.0) ? -S->s : R(1.0);
    if (phase != R(0.0)) {
        sd_real vr;
        if (A != R(0.0)) {
            Ct = SD_COS(om * t0);
            St = SD_SIN(om * t0);
        }
        tcs = t0;
        vr = z + V - A * om * Ct;
        if (vr != R(0.0)) sr = vr > R(0.0) ? R(1.0) : -R(1.0);
    }
    t = t0;
    te = t0 + h;
    thr = mus * W;
    for (it = 0; it < SD_MAX_EVENTS_PER_TICK; it++) {
        int stuck;
        if (phase == R(0.0)) {
            if (!stribeck_stick(P, V, thr, u, t, te, expo, &t, &u, &z, &F)) break;
            n_ev = record(ev_t, ev_a, cap, n_ev, t, B * SD_FABS(k * u));
            sr = F > R(0.0) ? -R(1.0) : R(1.0);
            phase = R(1.0);
            continue;
        }
        if (expo) {
            sd_real hn;
            if (tcs != t && A != R(0.0)) {
                Ct = SD_COS(om * t);
                St = SD_SIN(om * t);
            }
            stuck = exp_slip(P, &u, &z, &sr, V, W, mus, muk, &t, te, Ct, St, t == t0 ? S->slip_step : R(0.0), &F, &hn);
            S->slip_step = hn;
        } else {
            stuck = taylor_slip(P, &u, &z, &sr, V, W, mus, muk, &t, te);
            F = (sd_real)NAN;
        }
        if (stuck) {
            phase = R(0.0);
            continue;
        }
        if (t < te) S->truncated += 1;     /* the slip's step cap ran out before the end of the tick */
        break;
    }
    if (it == SD_MAX_EVENTS_PER_TICK) S->truncated += 1;
    if (phase == R(1.0) && !(F == F)) {
        sd_real dxc = A != R(0.0) ? A * om * SD_COS(om * te) : R(0.0), muW, dmuW;
        plain_friction(SD_FABS(z + V - dxc), W, mus, muk, P->a, P->b, &muW, &dmuW);
        F = -sr * muW;
    }
    S->x = u;
    S->v = z;
    S->phase = phase;
    S->s = -sr;
    S->f = F;
    return n_ev;
}

/* ================================================================ pre-maximum variant */
/* W mu and W dmu/d|vr| of the pre-maximum curve: written without
 * |vr| / W outside the products, so that a vanishing (subnormal) load stays finite */
static void mu_premax(const sd_pad_params_t *p, sd_real vr_abs, sd_real W, sd_real mus, sd_real muk, sd_real *muW,
                      sd_real *dmuW)
{
    sd_real u, e;
    if (W <= R(0.0)) {
        *muW = R(0.0);
        *dmuW = R(0.0);
        return;
    }
    u = vr_abs / W;
    if (u < p->stribeck_d) {
        *muW = p->stribeck_p * vr_abs;
        *dmuW = p->stribeck_p;
        return;
    }
    e = SD_EXP(-p->stribeck_a * (u - p->stribeck_d));
    *muW = W * (muk + (mus - muk) * e) + p->stribeck_b * (vr_abs - p->stribeck_d * W);
    *dmuW = -(mus - muk) * p->stribeck_a * e + p->stribeck_b;
}

static inline sd_real contactor_v(const st_par_t *P, sd_real t)
{
    return P->A == R(0.0) ? R(0.0) : P->A * P->om * SD_COS(P->om * t);
}

/* dur seconds from ta by exponential substeps; returns the step count */
static long premax_slip(const st_par_t *P, const sd_pad_params_t *p, sd_real *u_io, sd_real *du_io, sd_real *s_io,
                        sd_real *F_out, sd_real V, sd_real W, sd_real mus, sd_real muk, sd_real ta, sd_real dur)
{
    sd_real m = P->m, k = P->k, c = P->c, u = *u_io, du = *du_io, s = *s_io, t = ta, tend = ta + dur, F = R(0.0);
    sd_real vr0, muW, dmuW;
    long it;
    vr0 = du + V - contactor_v(P, t);
    mu_premax(p, SD_FABS(vr0), W, mus, muk, &muW, &dmuW);
    for (it = 0; t < tend && it < SD_MAX_EVENTS_PER_TICK; it++) {
        sd_real F0 = -sd_sgn(vr0) * muW, ceff = c + dmuW, hs = py_min(P->substep, tend - t), ueq, y1, v1, vr1;
        if (ceff < R(0.0)) hs = py_min(hs, R(0.5) * m / (-ceff));
        if (hs < ST_PREMAX_MIN * py_max(R(1.0), SD_FABS(t))) hs = tend - t;
        ueq = (F0 - dmuW * (V - contactor_v(P, t + R(0.5) * hs) - vr0)) / k;
        osc_any(m, ceff, k, u - ueq, du, hs, &y1, &v1);
        u = y1 + ueq;
        du = v1;
        t += hs;
        vr1 = du + V - contactor_v(P, t);
        mu_premax(p, SD_FABS(vr1), W, mus, muk, &muW, &dmuW);
        if (vr1 != R(0.0)) {
            F = -sd_sgn(vr1) * muW;
            s = -sd_sgn(vr1);
        } else {
            F = F0;
        }
        vr0 = vr1;
    }
    *u_io = u;
    *du_io = du;
    *s_io = s;
    *F_out = F;
    return it;
}

/* ================================================================ the tick */
int sd_stribeck_tick(sd_pad_state_t *S, const sd_pad_t *Pd, sd_real t0, sd_real h, sd_real V, sd_real N, sd_real mus,
                     sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev)
{
    const sd_pad_params_t *p = &Pd->p;
    sd_real B = p->burst_gain * gain, u, du, phase, s, F, hs, nd;
    int nev0 = n_ev;
    long nsub, i;
    st_par_t P;
    P.m = p->mass;
    P.k = p->stiffness;
    P.c = p->damping;
    P.a = p->stribeck_a;
    P.b = p->stribeck_b;
    P.A = p->contactor_amplitude;
    P.om = p->contactor_omega;
    P.tol = p->stribeck_tol;
#ifdef SD_SINGLE
    if (!(P.tol >= SD_STRIBECK_TOL_FLOOR)) P.tol = SD_STRIBECK_TOL_FLOOR;
#endif
    P.substep = p->substep;
    if (p->stribeck_variant != 1) {
        n_ev = plain_tick(S, &P, t0, h, V, N, mus, muk, B, ev_t, ev_a, cap, n_ev);
        S->n_events = n_ev - nev0;
        return n_ev;
    }
    u = S->x;
    du = S->v;
    phase = S->phase;
    s = S->s;
    F = S->f;
    nd = SD_CEIL(h / P.substep - R(1e-9));
    nsub = nd < R(1.0) ? 1 : (nd < R(SD_MAX_EVENTS_PER_TICK) ? (long)nd : SD_MAX_EVENTS_PER_TICK);
    hs = h / (sd_real)nsub;
    for (i = 0; i < nsub; i++) {
        sd_real ta = t0 + (sd_real)i * hs, avr;
        premax_slip(&P, p, &u, &du, &s, &F, V, N, mus, muk, ta, hs);
        avr = SD_FABS(du + V - contactor_v(&P, ta + hs));
        if (phase == R(0.0) && avr >= R(2.0) * p->stribeck_d * N) {
            n_ev = record(ev_t, ev_a, cap, n_ev, ta + hs, B * SD_FABS(P.k * u));
            phase = R(1.0);
        } else if (phase == R(1.0) && avr <= p->stribeck_d * N) {
            phase = R(0.0);
        }
    }
    S->x = u;
    S->v = du;
    S->phase = phase;
    S->s = s;
    S->f = F;
    S->n_events = n_ev - nev0;
    return n_ev;
}
