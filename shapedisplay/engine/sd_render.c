/* sd_render.c -- table lookup, per-tick inputs, bursts and the online renderer step.
 *
 * IEEE double precision in the reference build (see sd_pad.c for the rules of the arithmetic).
 */
#include <math.h>
#include <string.h>
#include "sd_runtime.h"
#include "sd_math.h"


static sd_real py_max(sd_real a, sd_real b) { return b > a ? b : a; }
static long imax(long a, long b) { return b > a ? b : a; }
static long imin(long a, long b) { return b < a ? b : a; }

/* ------------------------------------------------------------------ table lookup */
#ifdef SD_SINGLE
/* The float nearest a stored float64 code (little-endian bytes), by integer operations: the tick
 * path of the single-precision build uses no double arithmetic. sd_image_load checked the value
 * finite and within float range; magnitudes below FLT_MIN flush to zero. */
static sd_real f64_code(const uint8_t *p)
{
    uint32_t lo = (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
    uint32_t hi = (uint32_t)p[4] | (uint32_t)p[5] << 8 | (uint32_t)p[6] << 16 | (uint32_t)p[7] << 24;
    int32_t e = (int32_t)((hi >> 20) & 0x7ffu) - 1023 + 127;
    uint32_t m = (hi & 0xfffffu) << 3 | lo >> 29, rest = lo << 3, bits;
    float f;
    if (e <= 0) return SD_R(0.0);
    if (e >= 255) {
        e = 254;
        m = 0x7fffffu;
        rest = 0;
    }
    bits = (hi & 0x80000000u) | (uint32_t)e << 23 | m;
    if (rest > 0x80000000u || (rest == 0x80000000u && (m & 1u))) bits += 1u;   /* to nearest, ties to even */
    memcpy(&f, &bits, sizeof f);
    return f;
}
#endif

sd_real sd_channel_value(const sd_channel_t *ch, long idx)
{
    sd_real code;
    if (idx < 0) return ch->background;
    switch (ch->dtype) {
    case SD_U8: code = (sd_real)((const uint8_t *)ch->codes)[idx]; break;
    case SD_U16: code = (sd_real)((const uint16_t *)ch->codes)[idx]; break;
    case SD_F32: return (sd_real)((const float *)ch->codes)[idx];
#ifdef SD_SINGLE
    default: return f64_code((const uint8_t *)ch->codes + 8 * idx);
#else
    default: return ((const double *)ch->codes)[idx];
#endif
    }
    return ch->offset + ch->scale * code;   /* as Quantization.decode */
}

/* Index of canvas sample (r, c) in the code arrays, or -1 outside every block. With a tile index
 * the work is at most max_tile_blocks block tests (the image header states it); without one, a
 * scan of all blocks. */
/* The code offset of block b: its own, or the one an override gives it (a toggle in its other state). */
static long block_offset(const sd_table_t *T, long b, const int32_t *ov_block, const int32_t *ov_off, int n_ov)
{
    int i;
    for (i = 0; i < n_ov; i++)
        if (ov_block[i] == b) return ov_off[i];
    return T->blocks[b][4];
}

static long cell_index(const sd_table_t *T, long r, long c, const int32_t *ov_block, const int32_t *ov_off, int n_ov)
{
    int32_t b;
    if (T->tile_start) {
        long tile = (r / T->tile_rows) * (long)T->tiles_x + c / T->tile_cols;
        uint32_t e, e1 = T->tile_start[tile + 1];
        for (e = T->tile_start[tile]; e < e1; e++) {
            const int32_t *k = T->blocks[T->tile_list[e]];
            long r0 = k[0], c0 = k[1], nr = k[2], nc = k[3];
            if (r0 <= r && r < r0 + nr && c0 <= c && c < c0 + nc)
                return (n_ov ? block_offset(T, (long)T->tile_list[e], ov_block, ov_off, n_ov) : (long)k[4])
                       + (r - r0) * nc + (c - c0);
        }
        return -1;
    }
    for (b = 0; b < T->n_blocks; b++) {
        long r0 = T->blocks[b][0], c0 = T->blocks[b][1], nr = T->blocks[b][2], nc = T->blocks[b][3];
        if (r0 <= r && r < r0 + nr && c0 <= c && c < c0 + nc)
            return (n_ov ? block_offset(T, b, ov_block, ov_off, n_ov) : (long)T->blocks[b][4]) + (r - r0) * nc + (c - c0);
    }
    return -1;
}

long sd_cell_index(const sd_table_t *T, long r, long c) { return cell_index(T, r, c, NULL, NULL, 0); }

/* Cell of a position along one axis: the two sample indices around it and the weight of
 * the second, with the edge value held outside. */
static void axis_cell(sd_real pos, sd_real origin, sd_real step, long n, long *i0, long *i1, sd_real *t)
{
    sd_real f = (pos - origin) / step;
    if (!(f >= SD_R(0.0))) f = SD_R(0.0);          /* also NaN: never converted to an integer */
    if (f > (sd_real)(n - 1)) f = (sd_real)n - SD_R(1.0);
    *i0 = (long)SD_FLOOR(f);
    if (*i0 > imax(n - 2, 0)) *i0 = imax(n - 2, 0);
    *t = f - (sd_real)*i0;
    *i1 = imin(*i0 + 1, n - 1);
}

/* Bilinear value of every slot at (x, y) metres into out[SD_NSLOT] (0 for absent slots). */
void sd_sample_slots(const sd_table_t *T, sd_real x, sd_real y, sd_real *out)
{
    sd_sample_slots_ov(T, x, y, out, NULL, NULL, 0);
}

void sd_sample_slots_ov(const sd_table_t *T, sd_real x, sd_real y, sd_real *out, const int32_t *ovb,
                        const int32_t *ovo, int n_ov)
{
    long rows = T->grid.rows, cols = T->grid.cols, c0, c1, r0, r1;
    sd_real tx, ty;
    int s;
    axis_cell(x, T->grid.x0, T->grid.dx, cols, &c0, &c1, &tx);
    if (rows == 1) {
        long i0 = cell_index(T, 0, c0, ovb, ovo, n_ov), i1 = cell_index(T, 0, c1, ovb, ovo, n_ov);
        for (s = 0; s < SD_NSLOT; s++) {
            const sd_channel_t *ch = T->slot[s];
            out[s] = ch ? sd_channel_value(ch, i0) * (1 - tx) + sd_channel_value(ch, i1) * tx : SD_R(0.0);
        }
        return;
    }
    axis_cell(y, T->grid.y0, T->grid.dy, rows, &r0, &r1, &ty);
    {
        long i00 = cell_index(T, r0, c0, ovb, ovo, n_ov), i01 = cell_index(T, r0, c1, ovb, ovo, n_ov);
        long i10 = cell_index(T, r1, c0, ovb, ovo, n_ov), i11 = cell_index(T, r1, c1, ovb, ovo, n_ov);
        for (s = 0; s < SD_NSLOT; s++) {
            const sd_channel_t *ch = T->slot[s];
            sd_real top, bot;
            if (!ch) {
                out[s] = SD_R(0.0);
                continue;
            }
            top = sd_channel_value(ch, i00) * (1 - tx) + sd_channel_value(ch, i01) * tx;
            bot = sd_channel_value(ch, i10) * (1 - tx) + sd_channel_value(ch, i11) * tx;
            out[s] = top * (1 - ty) + bot * ty;
        }
    }
}

/* ------------------------------------------------------------------ bursts */
sd_real sd_envelope(sd_real tau, sd_real rise, sd_real decay)
{
    sd_real u, r;
    if (tau < SD_R(0.0)) return SD_R(0.0);
    if (tau < rise) return tau / rise;
    u = tau - rise;
    if (u < decay) {
        r = SD_R(1.0) - u / decay;
        return r * r;
    }
    return SD_R(0.0);
}

/* The burst envelope on one phase-continuous carrier (bursts.py): the state carries the playing
 * segment (retrigger, max) or the running sums of the rises and decays (add), and indices into the
 * event ring. Every transition is applied in time order, whatever the evaluation times. */
static sd_real segment(const sd_burst_state_t *B, sd_real t, sd_real rise, sd_real decay)
{
    sd_real tau = t - B->te, u, r;
    if (tau < rise) return B->e0 + (B->a - B->e0) * (tau / rise);
    u = tau - rise;
    if (u < decay) {
        r = SD_R(1.0) - u / decay;
        return B->a * r * r;
    }
    return SD_R(0.0);
}

static sd_real sums(const sd_burst_state_t *B, sd_real t, sd_real rise, sd_real decay)
{
    sd_real dt = t - B->tref, e = (B->ra * dt - B->rat) / rise, x = dt / decay;
    e += B->q0 - SD_R(2.0) * B->q1 * x + B->q2 * x * x;
    return e > SD_R(0.0) ? e : SD_R(0.0);
}

static void shift_ref(sd_burst_state_t *B, sd_real tnew, sd_real decay)
{
    sd_real dlt = tnew - B->tref, d;
    if (dlt == SD_R(0.0)) return;
    d = dlt / decay;
    B->rat -= dlt * B->ra;
    B->q0 += d * (d * B->q2 - SD_R(2.0) * B->q1);
    B->q1 -= d * B->q2;
    B->tref = tnew;
}

static void add_decay(sd_burst_state_t *B, sd_real te, sd_real a, sd_real rise, sd_real decay, sd_real sign)
{
    sd_real u = SD_R(1.0) + (te + rise - B->tref) / decay;
    if (sign > SD_R(0.0)) {
        B->q0 += a * u * u;
        B->q1 += a * u;
        B->q2 += a;
    } else {
        B->q0 -= a * u * u;
        B->q1 -= a * u;
        B->q2 -= a;
    }
}

/* Advance the burst state over every transition before t and return the envelope at t. */
static sd_real envelope_at(sd_burst_state_t *B, const sd_real *ev_t, const sd_real *ev_a, long n_ev, sd_real t,
                          sd_real rise, sd_real decay, int policy)
{
    long i_in = B->i_in, i_mid, i_out;
    sd_real dur = rise + decay;
    if (policy != SD_ADD) {
        while (i_in < n_ev && ev_t[i_in] < t) {
            sd_real te = ev_t[i_in], a = ev_a[i_in], e_now = segment(B, te, rise, decay);
            if (policy == SD_RETRIGGER || a > e_now) {
                B->te = te;
                B->e0 = e_now;
                B->a = a;
            }
            i_in += 1;
        }
        B->i_in = i_in;
        return segment(B, t, rise, decay);
    }
    i_mid = B->i_mid;
    i_out = B->i_out;
    for (;;) {
        sd_real t_in = i_in < n_ev ? ev_t[i_in] : INFINITY;
        sd_real t_mid = i_mid < i_in ? ev_t[i_mid] + rise : INFINITY;
        sd_real t_out = i_out < i_mid ? ev_t[i_out] + dur : INFINITY;
        if (t_out <= t_mid && t_out <= t_in) {
            if (!(t_out < t)) break;
            add_decay(B, ev_t[i_out], ev_a[i_out], rise, decay, -SD_R(1.0));
            i_out += 1;
            if (i_out == i_mid) B->q0 = B->q1 = B->q2 = SD_R(0.0);     /* no decaying burst left */
        } else if (t_mid <= t_in) {
            sd_real a;
            if (!(t_mid < t)) break;
            a = ev_a[i_mid];
            B->ra -= a;
            B->rat -= a * (ev_t[i_mid] - B->tref);
            add_decay(B, ev_t[i_mid], a, rise, decay, SD_R(1.0));
            i_mid += 1;
            if (i_mid == i_in) B->ra = B->rat = SD_R(0.0);             /* no rising burst left */
        } else {
            if (!(t_in < t)) break;
            shift_ref(B, ev_t[i_in], decay);
            B->ra += ev_a[i_in];
            i_in += 1;
        }
    }
    B->i_in = i_in;
    B->i_mid = i_mid;
    B->i_out = i_out;
    if (i_out == i_in) return SD_R(0.0);
    return sums(B, t, rise, decay);
}

/* The first k events leave the ring (bursts.forget_events). */
static void forget_events(sd_burst_state_t *B, const sd_real *ev_t, const sd_real *ev_a, long k, sd_real rise,
                          sd_real decay, int policy)
{
    long i;
    if (policy == SD_ADD) {
        for (i = B->i_out; i < (k < B->i_in ? k : B->i_in); i++) {
            if (i < B->i_mid) {
                add_decay(B, ev_t[i], ev_a[i], rise, decay, -SD_R(1.0));
            } else {
                B->ra -= ev_a[i];
                B->rat -= ev_a[i] * (ev_t[i] - B->tref);
            }
        }
    }
    B->i_in = B->i_in > k ? B->i_in - k : 0;
    B->i_mid = B->i_mid > k ? B->i_mid - k : 0;
    B->i_out = B->i_out > k ? B->i_out - k : 0;
}

/* v clipped to [-1, 1]; counts a clipped sample in *clipped. NaN gives 0, counted as clipped: no
 * NaN reaches the DAC (the drive's clamp in sd_renderer_step counts its NaN in run.value_faults). */
static sd_real clip_unit(sd_real v, long *clipped)
{
    if (v > SD_R(1.0)) {
        *clipped += 1;
        return SD_R(1.0);
    }
    if (v < -SD_R(1.0)) {
        *clipped += 1;
        return -SD_R(1.0);
    }
    if (v != v) {
        *clipped += 1;
        return SD_R(0.0);
    }
    return v;
}

/* The carrier after samples j0..j1-1, for the next call to continue from. */
static void keep_carrier(sd_burst_state_t *B, sd_real cr, sd_real sr, int64_t j0, int64_t j1)
{
    if (j1 > j0) {
        B->cc = cr;
        B->cs = sr;
        B->cj = j1;
    }
}

#ifdef SD_SINGLE
/* Carrier cos/sin at the phase ph (2^-64 cycles): the top 32 bits as a signed angle in [-pi, pi). */
static void carrier_at(uint64_t ph, sd_real *c, sd_real *s)
{
    sd_real th = (sd_real)(int32_t)(uint32_t)(ph >> 32) * SD_R(1.4629180792671596e-09);   /* 2 pi / 2^32 */
    *c = SD_COS(th);
    *s = SD_SIN(th);
}

/* The single-precision synth: audio samples j0..j1-1 at epoch times (j - epoch_sample) / rate. The
 * carrier is a rotation per sample carried from call to call, re-anchored from the exact fixed-point
 * phase of sample j every SD_CARRIER_BLOCK samples and wherever a call does not continue the last
 * one, so the rotation's rounding never accumulates over more than SD_CARRIER_BLOCK samples. */
static long synth(sd_burst_state_t *B, const sd_clock_t *K, const sd_real *ev_t, const sd_real *ev_a, long n_ev,
                  int64_t j0, int64_t j1, sd_real rise, sd_real decay, int policy, const sd_react_t *ck, sd_real *out)
{
    sd_real cd = B->rc, sd = B->rs, cr = B->cc, sr = B->cs;
    long clipped = 0;
    int64_t j;
    for (j = j0; j < j1; j++) {
        sd_real t;
        if (j % SD_CARRIER_BLOCK == 0 || (j == j0 && B->cj != j)) {
            carrier_at((uint64_t)j * K->dphase_sample, &cr, &sr);
        } else {
            sd_real cn = cr * cd - sr * sd, sn = sr * cd + cr * sd;
            cr = cn;
            sr = sn;
        }
        t = (sd_real)(int32_t)(j - K->epoch_sample) * K->inv_audio;
        sd_real v = envelope_at(B, ev_t, ev_a, n_ev, t, rise, decay, policy) * sr;
        if (ck) v += sd_react_click(ck, t);     /* (only then: adding 0.0 would turn a -0.0 sample into +0.0) */
        out[j - j0] = clip_unit(v, &clipped);
    }
    keep_carrier(B, cr, sr, j0, j1);
    return clipped;
}
#else
/* Audio samples j0..j1-1 (time t_origin + j / rate) into out[0 .. j1-j0-1]; returns samples clipped.
 * The carrier is a rotation per sample carried from call to call, re-anchored with sin/cos every
 * SD_CARRIER_BLOCK samples of the stream (anchors depend only on j: the stream does not depend on how
 * it is cut into calls). */
static long synth(sd_burst_state_t *B, const sd_real *ev_t, const sd_real *ev_a, long n_ev, sd_real t_origin,
                  sd_real rate, int64_t j0, int64_t j1, sd_real carrier, sd_real rise, sd_real decay, int policy,
                  const sd_react_t *ck, sd_real *out)
{
    sd_real w = SD_R(2.0) * SD_PI * carrier, cd = B->rc, sd = B->rs, cr = B->cc, sr = B->cs;
    long clipped = 0;
    int64_t j, q;
    for (j = j0; j < j1; j++) {
        sd_real t;
        if (j % SD_CARRIER_BLOCK == 0) {
            sd_real th = w * ((sd_real)j / rate);
            cr = SD_COS(th);
            sr = SD_SIN(th);
        } else if (j == j0 && B->cj != j) {
            /* not the continuation of the last call: rotate from the anchor of this block */
            int64_t ja = j - j % SD_CARRIER_BLOCK;
            sd_real th = w * ((sd_real)ja / rate);
            cr = SD_COS(th);
            sr = SD_SIN(th);
            for (q = 0; q < j - ja; q++) {
                sd_real cn = cr * cd - sr * sd, sn = sr * cd + cr * sd;
                cr = cn;
                sr = sn;
            }
        } else {
            sd_real cn = cr * cd - sr * sd, sn = sr * cd + cr * sd;
            cr = cn;
            sr = sn;
        }
        t = t_origin + (sd_real)j / rate;
        sd_real v = envelope_at(B, ev_t, ev_a, n_ev, t, rise, decay, policy) * sr;
        if (ck) v += sd_react_click(ck, t);     /* (only then: adding 0.0 would turn a -0.0 sample into +0.0) */
        out[j - j0] = clip_unit(v, &clipped);
    }
    keep_carrier(B, cr, sr, j0, j1);
    return clipped;
}


/* Offline burst audio of a sorted event list (the renderer's burst state and carrier, without a table):
 * n samples at times t_start + j / rate into out (the envelope alone when envelope_only); returns the
 * samples limited to [-1, 1]. */
long sd_render_events(const sd_real *ev_t, const sd_real *ev_a, long n_ev, sd_real t_start, sd_real rate,
                      int64_t n, sd_real carrier, sd_real rise, sd_real decay, int policy, int envelope_only,
                      sd_real *out)
{
    sd_burst_state_t B;
    int64_t j;
    memset(&B, 0, sizeof B);
    B.cj = -1;
    B.rc = SD_COS(SD_R(2.0) * SD_PI * carrier / rate);     /* as sd_renderer_init: w / rate */
    B.rs = SD_SIN(SD_R(2.0) * SD_PI * carrier / rate);
    if (!envelope_only) return synth(&B, ev_t, ev_a, n_ev, t_start, rate, 0, n, carrier, rise, decay, policy, NULL, out);
    for (j = 0; j < n; j++) out[j] = envelope_at(&B, ev_t, ev_a, n_ev, t_start + (sd_real)j / rate, rise, decay, policy);
    return 0;
}
#endif

/* ------------------------------------------------------------------ per-tick inputs */
static void axis_speed(sd_real vx, sd_real vy, sd_real *ax, sd_real *ay, sd_real *V)
{
    sd_real sp = SD_SQRT(vx * vx + vy * vy), dx, dy;
    if (sp == SD_R(0.0)) {
        *V = SD_R(0.0);
        return;
    }
    dx = vx / sp;
    dy = vy / sp;
    if (dx * *ax + dy * *ay >= SD_R(0.0)) {
        *V = sp;
        *ax = dx;
        *ay = dy;
        return;
    }
    *V = -sp;
    *ax = -dx;
    *ay = -dy;
}

void sd_derive(const sd_table_t *T, const sd_config_t *C, const sd_real *vals, sd_real vx, sd_real vy, sd_real speed,
               sd_real *N_out, sd_real *mus_out, sd_real *muk_out, sd_real *gain_out)
{
    sd_real N = T->slot[SD_SLOT_NORMAL_FORCE] ? vals[SD_SLOT_NORMAL_FORCE] : C->normal_force_constant, fs, mus, muk, gain;
    if (N < SD_R(0.0)) N = SD_R(0.0);
    fs = T->slot[SD_SLOT_FRICTION_SCALE] ? vals[SD_SLOT_FRICTION_SCALE] : SD_R(1.0);
    if (fs < SD_R(0.0)) fs = SD_R(0.0);
    mus = C->mu_s * fs;
    muk = C->mu_k * fs;
    if (T->slot[SD_SLOT_BREAKAWAY_FORCE] && N > SD_R(0.0)) mus = py_max(vals[SD_SLOT_BREAKAWAY_FORCE], SD_R(0.0)) / N;
    if (T->slot[SD_SLOT_KINETIC_FORCE] && N > SD_R(0.0)) muk = py_max(vals[SD_SLOT_KINETIC_FORCE], SD_R(0.0)) / N;
    if (C->k_mu != SD_R(0.0) && speed > SD_R(0.0) && T->slot[SD_SLOT_GRAD_X]) {
        sd_real gy = T->slot[SD_SLOT_GRAD_Y] ? vals[SD_SLOT_GRAD_Y] : SD_R(0.0);
        sd_real slope = (vals[SD_SLOT_GRAD_X] * vx + gy * vy) / speed;
        if (slope > SD_R(0.0)) {
            mus += C->k_mu * slope;
            muk += C->k_mu * slope;
        }
    }
    if (muk > mus) muk = mus;
    gain = T->slot[SD_SLOT_BURST_GAIN] ? vals[SD_SLOT_BURST_GAIN] : SD_R(1.0);
    if (gain < SD_R(0.0)) gain = SD_R(0.0);
    *N_out = N;
    *mus_out = mus;
    *muk_out = muk;
    *gain_out = gain;
}

/* ------------------------------------------------------------------ renderer */
/* The pad models with a C tick, by model id (the registry of the Python runtime numbers them). */
static const sd_tick_fn TICKS[SD_NMODEL] = {
    [SD_MODEL_EXACT] = sd_exact_tick,
    [SD_MODEL_JUMP] = sd_jump_tick,
    [SD_MODEL_KARNOPP] = sd_karnopp_tick,
    [SD_MODEL_EULER] = sd_euler_tick,
    [SD_MODEL_RK4] = sd_rk4_tick,
    [SD_MODEL_TANH] = sd_tanh_tick,
    [SD_MODEL_STRIBECK] = sd_stribeck_tick,
};

sd_tick_fn sd_model_tick(int model)
{
    return model >= 0 && model < SD_NMODEL ? TICKS[model] : NULL;
}

size_t sd_renderer_size(void) { return sizeof(sd_renderer_t); }

#ifdef SD_SINGLE
static uint32_t gcd_u32(uint32_t a, uint32_t b)
{
    while (b) {                 /* Euclid: at most ~27 steps for 20-bit operands */
        uint32_t r = a % b;
        a = b;
        b = r;
    }
    return a;
}

/* Fraction of a cycle as a 64-bit fixed-point phase step (0 <= cycles < 1). */
static uint64_t phase_step(double cycles)
{
    cycles -= floor(cycles);
    return (uint64_t)(cycles * 18446744073709551616.0 * 0.5) * 2u;   /* 2^64; halved: stays below 2^63 */
}

/* The constants of the single-precision time base, computed in double once here (not per tick).
 * The rates must be whole numbers of hertz (integer tick and sample counts). */
static int clock_init(sd_clock_t *K, const sd_config_t *cfg)
{
    double tr = (double)cfg->tick_rate, ar = (double)cfg->audio_rate, f = (double)cfg->carrier_hz;
    uint32_t l0, target;
    if (tr != floor(tr) || ar != floor(ar)) return SD_ERR_PARAM;
    memset(K, 0, sizeof *K);
    K->tick_hz = (uint32_t)tr;
    K->audio_hz = (uint32_t)ar;
    /* an epoch is a whole number of samples long: a multiple of l0 ticks, near 1/16 s */
    l0 = K->audio_hz ? K->tick_hz / gcd_u32(K->tick_hz, K->audio_hz) : 1u;
    target = K->tick_hz / 16u;
    K->epoch_ticks = (int64_t)l0 * (target > l0 ? target / l0 : 1u);
    K->epoch_samples = K->epoch_ticks * (int64_t)K->audio_hz / (int64_t)K->tick_hz;
    K->h = (sd_real)(1.0 / tr);
    K->inv_audio = ar > 0.0 ? (sd_real)(1.0 / ar) : SD_R(0.0);
    K->epoch_s = (sd_real)((double)K->epoch_ticks / tr);
    K->dphase_sample = ar > 0.0 ? phase_step(f / ar) : 0u;
    K->dphase_tick = phase_step(f / tr);
    K->tick_rc = (sd_real)cos(2.0 * 3.141592653589793 * (f / tr - floor(f / tr)));
    K->tick_rs = (sd_real)sin(2.0 * 3.141592653589793 * (f / tr - floor(f / tr)));
    return SD_OK;
}

/* The clock at tick `tick` (reset: 0), the epoch at the last whole epoch at or before tick - 1. */
static void clock_seek(sd_clock_t *K, int64_t tick)
{
    int64_t q, r, e;
    K->tick = tick;
    q = tick / (int64_t)K->tick_hz;
    r = tick % (int64_t)K->tick_hz;
    /* floor(tick * audio / tick_rate) without overflow below 2^63 / audio_rate seconds */
    K->sample_floor = q * (int64_t)K->audio_hz + r * (int64_t)K->audio_hz / (int64_t)K->tick_hz;
    K->sample_rem = (uint32_t)(r * (int64_t)K->audio_hz % (int64_t)K->tick_hz);
    e = tick > 0 ? (tick - 1) / K->epoch_ticks : 0;
    K->epoch = e * K->epoch_ticks;
    K->epoch_sample = e * K->epoch_samples;
    K->drive_k = -1;
}
#endif

int sd_renderer_init(sd_renderer_t *R, const sd_table_t *table, const sd_config_t *cfg)
{
    const sd_pad_params_t *p = &cfg->pad;
    if (!R || !table || !cfg) return SD_ERR_ARG;
    if (table->grid.rows < 1 || table->grid.cols < 1 || !(table->grid.dx > SD_R(0.0)) || !(table->grid.dy > SD_R(0.0)) || table->n_blocks < 0)
        return SD_ERR_TABLE;
    /* the pad models need N: the table's channel, or the constant N of a table without it */
    if (!table->slot[SD_SLOT_NORMAL_FORCE]
        && !(cfg->normal_force_constant >= SD_R(0.0) && cfg->normal_force_constant < INFINITY))
        return SD_ERR_PARAM;
    if (cfg->k_mu > SD_R(0.0) && !table->slot[SD_SLOT_GRAD_X]) return SD_ERR_TABLE;  /* slope friction needs grad */
    if (!(p->mass > SD_R(0.0)) || !(p->stiffness > SD_R(0.0)) || !(p->damping >= SD_R(0.0)) || !(p->burst_gain >= SD_R(0.0))
        || !(p->max_stick_period >= SD_R(0.0)) || !(cfg->mu_s > SD_R(0.0)) || !(cfg->mu_k >= SD_R(0.0)) || cfg->mu_k > cfg->mu_s
        || !(cfg->k_mu >= SD_R(0.0)))
        return SD_ERR_PARAM;
    if (!(cfg->tick_rate >= 100.0f && cfg->tick_rate <= 192000.0f)) return SD_ERR_PARAM;   /* devices.TICK_RATE_RANGE */
    /* the pad's natural frequency within what a tick resolves: h * omega_n <= SD_H_OMEGA_MAX (devices.H_OMEGA_MAX);
       beyond it the pad rings through thousands of stick-slip transitions in one tick */
    if (!((double)p->stiffness <= (double)p->mass * (SD_H_OMEGA_MAX * SD_H_OMEGA_MAX)
                                   * (double)cfg->tick_rate * (double)cfg->tick_rate))
        return SD_ERR_PARAM;
    if (!(cfg->audio_rate == SD_R(0.0) || (cfg->audio_rate >= SD_R(1000.0) && cfg->audio_rate <= SD_R(384000.0))))
        return SD_ERR_PARAM;
    if (!(cfg->carrier_hz > SD_R(0.0)) || !(cfg->rise_s > SD_R(0.0)) || !(cfg->decay_s > SD_R(0.0))) return SD_ERR_PARAM;
    if (cfg->policy < SD_RETRIGGER || cfg->policy > SD_MAX) return SD_ERR_PARAM;
    if (!sd_model_tick(cfg->model)) return SD_ERR_PARAM;
    R->table = table;
    R->cfg = *cfg;
    sd_pad_prepare(&R->pad_model, &cfg->pad);
    R->tick_fn = sd_model_tick(cfg->model);
    R->audio_cap = cfg->audio_rate > SD_R(0.0) ? (long)SD_CEIL(cfg->audio_rate / cfg->tick_rate) + 2 : 0;
    if (R->audio_cap > SD_AUDIO_BLOCK_MAX) return SD_ERR_PARAM;
#ifdef SD_SINGLE
    if (clock_init(&R->clock, cfg) != SD_OK) return SD_ERR_PARAM;
    R->rot_cos = (sd_real)cos(2.0 * 3.141592653589793 * (double)cfg->carrier_hz / (double)cfg->audio_rate);
    R->rot_sin = (sd_real)sin(2.0 * 3.141592653589793 * (double)cfg->carrier_hz / (double)cfg->audio_rate);
#else
    if (cfg->audio_rate > SD_R(0.0)) {     /* constants of the carrier rotation: once here, not per tick */
        sd_real w = SD_R(2.0) * SD_PI * cfg->carrier_hz;
        R->rot_cos = SD_COS(w / cfg->audio_rate);
        R->rot_sin = SD_SIN(w / cfg->audio_rate);
    }
#endif
    sd_renderer_reset(R, SD_R(0.0));
    return SD_OK;
}

/* Index of the last audio sample at or before elapsed time e (s), plus one, as every tick
 * computes it; saturated below 2^63 so that it never overflows (audio stops after 2^63 - 2048
 * samples: 6 million years at 48 kHz). */
#ifndef SD_SINGLE
static int64_t sample_end(sd_real e, sd_real rate)
{
    sd_real v = SD_FLOOR(e * rate + SD_R(1e-9));
    if (!(v < SD_R(9223372036854773760.0))) v = v > SD_R(0.0) ? SD_R(9223372036854773760.0) : SD_R(0.0);   /* 2^63 - 2048; NaN: 0 */
    return (int64_t)v + 1;
}
#endif

void sd_renderer_reset(sd_renderer_t *R, sd_real t0)
{
    sd_pad_reset(&R->pad);
    memset(&R->run, 0, sizeof R->run);
    R->position_faults = 0;
    R->run.ax = SD_R(1.0);
    R->run.t0 = t0;
    R->n_audio = 0;
    memset(R->ev_t, 0, sizeof R->ev_t);
    memset(R->ev_a, 0, sizeof R->ev_a);
    memset(R->audio, 0, sizeof R->audio);
    memset(&R->out, 0, sizeof R->out);
    memset(&R->bursts, 0, sizeof R->bursts);
    R->bursts.cj = -1;
    R->bursts.rc = R->rot_cos;      /* the carrier rotation per sample, from sd_renderer_init */
    R->bursts.rs = R->rot_sin;
#ifdef SD_SINGLE
    clock_seek(&R->clock, 0);
#endif
    sd_react_reset(R);
}

void sd_renderer_seek(sd_renderer_t *R, int64_t tick, sd_real x, sd_real y)
{
    sd_real t0 = R->run.t0;
    sd_renderer_reset(R, t0);
    if (tick <= 0) return;
    R->run.tick = (sd_real)tick;
    R->run.xp = x;
    R->run.yp = y;
#ifdef SD_SINGLE
    clock_seek(&R->clock, tick);
    /* next_sample: one past the last sample of the last tick played (tick - 1) */
    if (R->audio_cap > 0) {
        int64_t k1 = tick - 1;
        R->run.next_sample = k1 / (int64_t)R->clock.tick_hz * (int64_t)R->clock.audio_hz
                             + k1 % (int64_t)R->clock.tick_hz * (int64_t)R->clock.audio_hz / (int64_t)R->clock.tick_hz + 1;
    }
#else
    if (R->audio_cap > 0)
        R->run.next_sample = sample_end((t0 + ((sd_real)tick - SD_R(1.0)) / R->cfg.tick_rate) - t0, R->cfg.audio_rate);
#endif
}

#ifdef SD_SINGLE
/* Move the epoch on by one epoch: the live event times and the burst state's times shift by its
 * length (n_recent <= SD_EVENT_RING / 2 subtractions, once every epoch_ticks ticks). */
static void rebase(sd_renderer_t *R)
{
    sd_clock_t *K = &R->clock;
    sd_real d = K->epoch_s;
    long i, n = (long)R->run.n_recent;
    for (i = 0; i < n; i++) R->ev_t[i] -= d;
    R->bursts.te -= d;
    R->bursts.tref -= d;
    R->react.click_t -= d;          /* the click in progress, on the same time base */
    K->epoch += K->epoch_ticks;
    K->epoch_sample += K->epoch_samples;
}

/* The carrier at tick k (time k / tick_rate from t0): a rotation per tick from the last one,
 * re-anchored from the exact fixed-point phase every SD_CARRIER_BLOCK ticks. */
static sd_real tick_carrier(sd_clock_t *K, int64_t k)
{
    if (K->drive_k == k - 1 && k % SD_CARRIER_BLOCK != 0) {
        sd_real cn = K->dc * K->tick_rc - K->ds * K->tick_rs, sn = K->ds * K->tick_rc + K->dc * K->tick_rs;
        K->dc = cn;
        K->ds = sn;
    } else {
        carrier_at((uint64_t)k * K->dphase_tick, &K->dc, &K->ds);
    }
    K->drive_k = k;
    return K->ds;
}
#endif

double sd_event_time(const sd_renderer_t *R, long i)
{
#ifdef SD_SINGLE
    return (double)R->run.t0 + (double)R->clock.epoch / (double)R->clock.tick_hz + (double)R->ev_t[i];
#else
    return R->ev_t[i];
#endif
}

sd_real sd_renderer_step(sd_renderer_t *R, sd_real x, sd_real y)
{
    return sd_renderer_step_press(R, x, y, SD_R(0.0));
}

sd_real sd_renderer_step_press(sd_renderer_t *R, sd_real x, sd_real y, sd_real press)
{
    sd_real vals[SD_NSLOT], svx = SD_R(0.0), svy = SD_R(0.0);
    const int react = R->react.n > 0;
#ifdef SD_SINGLE
    /* times from the epoch (sd_clock_t); the tick count in an integer */
    sd_clock_t *K = &R->clock;
    const int64_t kk = K->tick;
    const int first = kk == 0;
    sd_real t;
#else
    sd_real k = R->run.tick, rate = R->cfg.tick_rate, t = R->run.t0 + k / rate;
    const int first = k == SD_R(0.0);
#endif
    sd_real h, vx, vy, xm, ym, V, N, mus, muk, gain, dur, drive, f, target;
    long nrec = R->run.n_recent, drop = 0, nev = 0, i, done;
    int64_t j0, j1;
    const long cap = SD_EVENT_RING;
#ifdef SD_SINGLE
    if (kk - K->epoch > K->epoch_ticks) rebase(R);
    t = (sd_real)(int32_t)(kk - K->epoch) * K->h;
#endif
    if (!(press >= SD_R(0.0))) press = SD_R(0.0);      /* NaN, negative: not pressing */
    else if (press > SD_R(1e6)) press = SD_R(1e6);
    /* a non-finite or absurd position is a fault: hold the last valid one */
    if (!(SD_FABS(x) <= SD_R(SD_POSITION_LIMIT_M)) || !(SD_FABS(y) <= SD_R(SD_POSITION_LIMIT_M))) {
        R->position_faults += 1;
        if (!first) {
            x = R->run.xp;
            y = R->run.yp;
        } else {
            x = R->table->grid.x0;
            y = R->table->grid.y0;
        }
    }
    if (first) {
        h = SD_R(0.0);
        vx = SD_R(0.0);
        vy = SD_R(0.0);
        xm = x;
        ym = y;
    } else {
#ifdef SD_SINGLE
        h = K->h;
#else
        h = t - (R->run.t0 + (k - 1.0) / rate);
        if (!(h > 0.0)) h = 1.0 / rate;     /* beyond 2^53 ticks the double times stop resolving a tick */
#endif
        vx = (x - R->run.xp) / h;
        vy = (y - R->run.yp) / h;
        xm = SD_R(0.5) * (x + R->run.xp);
        ym = SD_R(0.5) * (y + R->run.yp);
    }
    if (react) {
        /* toggles, moving parts and the part the finger holds; the pad is driven by the finger's velocity
         * relative to the surface under it (docs/reactive.md) */
        sd_react_lookup(R, xm, ym, h, vals, &svx, &svy);
        vx -= svx;
        vy -= svy;
    } else {
        sd_sample_slots(R->table, xm, ym, vals);
    }
    axis_speed(vx, vy, &R->run.ax, &R->run.ay, &V);
    sd_derive(R->table, &R->cfg, vals, vx, vy, SD_FABS(V), &N, &mus, &muk, &gain);
    if (react && R->react.click_on) {       /* the click's friction transient: N drops, then recovers */
        sd_real tau = t - R->react.click_t;
        if (tau > SD_R(0.0) && tau < R->react.drop_s) N *= SD_R(1.0) - R->react.drop * (SD_R(1.0) - tau / R->react.drop_s);
    }
    /* Table values are finite (sd_image_load), but their products may not be (a normal force of 1e300
     * times a slope of 1e10): such a tick is a value fault, played without contact (N = 0). */
    if (!(isfinite(mus * N) && isfinite(muk * N) && isfinite(mus) && isfinite(gain))) {
        R->run.value_faults += 1;
        N = SD_R(0.0);
        mus = R->cfg.mu_s;
        muk = R->cfg.mu_k;
        gain = SD_R(0.0);
    }
    /* forget bursts that have finished (and that the burst state no longer needs) */
    dur = R->cfg.rise_s + R->cfg.decay_s;
    done = R->cfg.policy == SD_ADD ? (long)R->bursts.i_out : (long)R->bursts.i_in;
    while (drop < nrec && drop < done && R->ev_t[drop] + dur <= t - h) drop += 1;
    if (nrec > cap / 2 && drop == 0) {
        drop = nrec - cap / 4;
        R->run.events_dropped += drop;
    }
    if (drop > 0) {
        forget_events(&R->bursts, R->ev_t, R->ev_a, drop, R->cfg.rise_s, R->cfg.decay_s, R->cfg.policy);
        for (i = drop; i < nrec; i++) {
            R->ev_t[i - drop] = R->ev_t[i];
            R->ev_a[i - drop] = R->ev_a[i];
        }
        nrec -= drop;
    }
    if (h > SD_R(0.0)) {
        long n1 = R->tick_fn(&R->pad, &R->pad_model, t - h, h, V, N, mus, muk, gain, R->ev_t, R->ev_a, (int)cap,
                             (int)nrec);
        if (!(isfinite(R->pad.f) && isfinite(R->pad.x) && isfinite(R->pad.v))) {
            /* overflow inside the pad model (forces near the largest sd_real): a value fault, the pad
             * starts again at rest; the tick's events stand (their amplitudes are clipped or counted) */
            R->run.value_faults += 1;
            sd_pad_reset(&R->pad);
        }
        nev = n1 - nrec;
        if (n1 > cap) {
            R->run.events_dropped += n1 - cap;
            n1 = cap;
        }
        nrec = n1;
    }
    R->run.n_recent = nrec;
    R->run.events_total += nev;
    if (react) {
#ifdef SD_SINGLE
        sd_react_update(R, x, y, press, t, h, kk);
#else
        sd_react_update(R, x, y, press, t, h, (int64_t)k);
#endif
    } else {
        R->react.press = press;
    }
    /* audio samples with times in (t - h, t] */
    R->n_audio = 0;
    if (R->audio_cap > 0) {
        j0 = R->run.next_sample;
#ifdef SD_SINGLE
        j1 = K->sample_floor + 1;
        if (j1 - j0 > R->audio_cap) j0 = j1 - R->audio_cap;
        if (j1 > j0)
            R->run.clipped += synth(&R->bursts, K, R->ev_t, R->ev_a, nrec, j0, j1, R->cfg.rise_s, R->cfg.decay_s,
                                    R->cfg.policy, R->react.click_on ? &R->react : NULL, R->audio);
#else
        j1 = sample_end(t - R->run.t0, R->cfg.audio_rate);
        if (j1 - j0 > R->audio_cap) j0 = j1 - R->audio_cap;
        if (j1 > j0)
            R->run.clipped += synth(&R->bursts, R->ev_t, R->ev_a, nrec, R->run.t0, R->cfg.audio_rate, j0, j1,
                                    R->cfg.carrier_hz, R->cfg.rise_s, R->cfg.decay_s, R->cfg.policy,
                                    R->react.click_on ? &R->react : NULL, R->audio);
#endif
        R->run.next_sample = j1;
        R->n_audio = j1 - j0 > 0 ? j1 - j0 : 0;
    }
    drive = envelope_at(&R->bursts, R->ev_t, R->ev_a, nrec, t, R->cfg.rise_s, R->cfg.decay_s, R->cfg.policy)
#ifdef SD_SINGLE
            * tick_carrier(K, kk);
#else
            * sin(2.0 * SD_PI * R->cfg.carrier_hz * (t - R->run.t0));
#endif
    if (R->react.click_on) drive += sd_react_click(&R->react, t);
    if (drive > SD_R(1.0)) drive = SD_R(1.0);          /* as min(max(drive, -1), 1) for numbers */
    else if (drive < -SD_R(1.0)) drive = -SD_R(1.0);
    else if (drive != drive) {                          /* NaN (an inf amplitude times a carrier zero): never into the drive */
        drive = SD_R(0.0);
        R->run.value_faults += 1;
    }
    f = R->pad.f;
#ifdef SD_SINGLE
    R->out.t = R->run.t0 + (sd_real)kk * K->h;
#else
    R->out.t = t;
#endif
    R->out.x = x;
    R->out.y = y;
    R->out.vx = vx;
    R->out.vy = vy;
    R->out.pad_speed = V;
    R->out.mu_s = mus;
    R->out.mu_k = muk;
    R->out.burst_gain = gain;
    R->out.normal_force = N;
    R->out.friction_force = f;
    R->out.state = R->pad.phase;
    R->out.lateral_x = vals[SD_SLOT_LATERAL_X];
    R->out.lateral_y = vals[SD_SLOT_LATERAL_Y];
    target = R->table->slot[SD_SLOT_SKIN_STRETCH] ? vals[SD_SLOT_SKIN_STRETCH] : R->cfg.skin_target;
    R->out.skin_stretch = mus * N > SD_R(0.0) ? target * f / (mus * N) : SD_R(0.0);
    if (!isfinite(R->out.skin_stretch)) {              /* a huge target times a huge force */
        R->out.skin_stretch = SD_R(0.0);
        R->run.value_faults += 1;
    }
    R->out.events = (sd_real)nev;
    R->out.drive = drive;
    R->out.audio_samples = (sd_real)R->n_audio;
    R->out.press = R->react.press;
    R->out.reactions = (sd_real)R->react.tick_events;
    R->run.xp = x;
    R->run.yp = y;
#ifdef SD_SINGLE
    {   /* the next tick; floor((k + 1) audio / tick_rate) by one exact integer step */
        uint32_t q;
        K->tick = kk + 1;
        K->sample_rem += K->audio_hz;
        q = K->sample_rem / K->tick_hz;
        K->sample_floor += q;
        K->sample_rem -= q * K->tick_hz;
        R->run.tick = (sd_real)K->tick;
    }
#else
    R->run.tick = k + 1.0;
#endif
    return drive;
}
