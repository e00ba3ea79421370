/* sd_render.c -- table lookup, per-tick inputs, bursts and the online renderer step.
 *
 * Ports of shapedisplay/runtime/lookup.py (sample_all), renderer.py (_axis_speed, _derive,
 * online_step) and bursts.py (envelope, burst_value, synth), operation for operation in
 * IEEE double precision (see sd_pad.c for the rules that keep it bit-identical).
 */
#include <math.h>
#include <string.h>
#include "sd_runtime.h"

#define SD_PI 3.141592653589793

static double py_max(double a, double b) { return b > a ? b : a; }
static double py_min(double a, double b) { return b < a ? b : a; }
static long imax(long a, long b) { return b > a ? b : a; }
static long imin(long a, long b) { return b < a ? b : a; }

/* ------------------------------------------------------------------ table lookup */
double sd_channel_value(const sd_channel_t *ch, long idx)
{
    double code;
    if (idx < 0) return ch->background;
    switch (ch->dtype) {
    case SD_U8: code = (double)((const uint8_t *)ch->codes)[idx]; break;
    case SD_U16: code = (double)((const uint16_t *)ch->codes)[idx]; break;
    case SD_F32: return (double)((const float *)ch->codes)[idx];
    default: return ((const double *)ch->codes)[idx];
    }
    return ch->offset + ch->scale * code;   /* as Quantization.decode */
}

/* Index of canvas sample (r, c) in the code arrays, or -1 outside every block. With a tile index
 * the work is at most max_tile_blocks block tests (the image header states it); without one, a
 * scan of all blocks. */
long sd_cell_index(const sd_table_t *T, long r, long c)
{
    int32_t b;
    if (T->tile_start) {
        long tile = (r / T->tile_rows) * (long)T->tiles_x + c / T->tile_cols;
        uint32_t e, e1 = T->tile_start[tile + 1];
        for (e = T->tile_start[tile]; e < e1; e++) {
            const int32_t *k = T->blocks[T->tile_list[e]];
            long r0 = k[0], c0 = k[1], nr = k[2], nc = k[3];
            if (r0 <= r && r < r0 + nr && c0 <= c && c < c0 + nc) return (long)k[4] + (r - r0) * nc + (c - c0);
        }
        return -1;
    }
    for (b = 0; b < T->n_blocks; b++) {
        long r0 = T->blocks[b][0], c0 = T->blocks[b][1], nr = T->blocks[b][2], nc = T->blocks[b][3];
        if (r0 <= r && r < r0 + nr && c0 <= c && c < c0 + nc)
            return (long)T->blocks[b][4] + (r - r0) * nc + (c - c0);
    }
    return -1;
}

/* Cell of a position along one axis: the two sample indices around it and the weight of
 * the second, with the edge value held outside (lookup._axis_cell). */
static void axis_cell(double pos, double origin, double step, long n, long *i0, long *i1, double *t)
{
    double f = (pos - origin) / step;
    if (!(f >= 0.0)) f = 0.0;          /* also NaN: never converted to an integer */
    if (f > (double)(n - 1)) f = (double)n - 1.0;
    *i0 = (long)floor(f);
    if (*i0 > imax(n - 2, 0)) *i0 = imax(n - 2, 0);
    *t = f - (double)*i0;
    *i1 = imin(*i0 + 1, n - 1);
}

/* Bilinear value of every slot at (x, y) metres into out[SD_NSLOT] (0 for absent slots). */
void sd_sample_slots(const sd_table_t *T, double x, double y, double *out)
{
    long rows = T->grid.rows, cols = T->grid.cols, c0, c1, r0, r1;
    double tx, ty;
    int s;
    axis_cell(x, T->grid.x0, T->grid.dx, cols, &c0, &c1, &tx);
    if (rows == 1) {
        long i0 = sd_cell_index(T, 0, c0), i1 = sd_cell_index(T, 0, c1);
        for (s = 0; s < SD_NSLOT; s++) {
            const sd_channel_t *ch = T->slot[s];
            out[s] = ch ? sd_channel_value(ch, i0) * (1 - tx) + sd_channel_value(ch, i1) * tx : 0.0;
        }
        return;
    }
    axis_cell(y, T->grid.y0, T->grid.dy, rows, &r0, &r1, &ty);
    {
        long i00 = sd_cell_index(T, r0, c0), i01 = sd_cell_index(T, r0, c1);
        long i10 = sd_cell_index(T, r1, c0), i11 = sd_cell_index(T, r1, c1);
        for (s = 0; s < SD_NSLOT; s++) {
            const sd_channel_t *ch = T->slot[s];
            double top, bot;
            if (!ch) {
                out[s] = 0.0;
                continue;
            }
            top = sd_channel_value(ch, i00) * (1 - tx) + sd_channel_value(ch, i01) * tx;
            bot = sd_channel_value(ch, i10) * (1 - tx) + sd_channel_value(ch, i11) * tx;
            out[s] = top * (1 - ty) + bot * ty;
        }
    }
}

/* ------------------------------------------------------------------ bursts */
double sd_envelope(double tau, double rise, double decay)
{
    double u, r;
    if (tau < 0.0) return 0.0;
    if (tau < rise) return tau / rise;
    u = tau - rise;
    if (u < decay) {
        r = 1.0 - u / decay;
        return r * r;
    }
    return 0.0;
}

/* The burst envelope on one phase-continuous carrier (bursts.py): the state carries the playing
 * segment (retrigger, max) or the running sums of the rises and decays (add), and indices into the
 * event ring. Every transition is applied in time order, whatever the evaluation times. */
static double segment(const sd_burst_state_t *B, double t, double rise, double decay)
{
    double tau = t - B->te, u, r;
    if (tau < rise) return B->e0 + (B->a - B->e0) * (tau / rise);
    u = tau - rise;
    if (u < decay) {
        r = 1.0 - u / decay;
        return B->a * r * r;
    }
    return 0.0;
}

static double sums(const sd_burst_state_t *B, double t, double rise, double decay)
{
    double dt = t - B->tref, e = (B->ra * dt - B->rat) / rise, x = dt / decay;
    e += B->q0 - 2.0 * B->q1 * x + B->q2 * x * x;
    return e > 0.0 ? e : 0.0;
}

static void shift_ref(sd_burst_state_t *B, double tnew, double decay)
{
    double dlt = tnew - B->tref, d;
    if (dlt == 0.0) return;
    d = dlt / decay;
    B->rat -= dlt * B->ra;
    B->q0 += d * (d * B->q2 - 2.0 * B->q1);
    B->q1 -= d * B->q2;
    B->tref = tnew;
}

static void add_decay(sd_burst_state_t *B, double te, double a, double rise, double decay, double sign)
{
    double u = 1.0 + (te + rise - B->tref) / decay;
    if (sign > 0.0) {
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
static double envelope_at(sd_burst_state_t *B, const double *ev_t, const double *ev_a, long n_ev, double t,
                          double rise, double decay, int policy)
{
    long i_in = B->i_in, i_mid, i_out;
    double dur = rise + decay;
    if (policy != SD_ADD) {
        while (i_in < n_ev && ev_t[i_in] < t) {
            double te = ev_t[i_in], a = ev_a[i_in], e_now = segment(B, te, rise, decay);
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
        double t_in = i_in < n_ev ? ev_t[i_in] : INFINITY;
        double t_mid = i_mid < i_in ? ev_t[i_mid] + rise : INFINITY;
        double t_out = i_out < i_mid ? ev_t[i_out] + dur : INFINITY;
        if (t_out <= t_mid && t_out <= t_in) {
            if (!(t_out < t)) break;
            add_decay(B, ev_t[i_out], ev_a[i_out], rise, decay, -1.0);
            i_out += 1;
            if (i_out == i_mid) B->q0 = B->q1 = B->q2 = 0.0;     /* no decaying burst left */
        } else if (t_mid <= t_in) {
            double a;
            if (!(t_mid < t)) break;
            a = ev_a[i_mid];
            B->ra -= a;
            B->rat -= a * (ev_t[i_mid] - B->tref);
            add_decay(B, ev_t[i_mid], a, rise, decay, 1.0);
            i_mid += 1;
            if (i_mid == i_in) B->ra = B->rat = 0.0;             /* no rising burst left */
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
    if (i_out == i_in) return 0.0;
    return sums(B, t, rise, decay);
}

/* The first k events leave the ring (bursts.forget_events). */
static void forget_events(sd_burst_state_t *B, const double *ev_t, const double *ev_a, long k, double rise,
                          double decay, int policy)
{
    long i;
    if (policy == SD_ADD) {
        for (i = B->i_out; i < (k < B->i_in ? k : B->i_in); i++) {
            if (i < B->i_mid) {
                add_decay(B, ev_t[i], ev_a[i], rise, decay, -1.0);
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

/* Audio samples j0..j1-1 (time t_origin + j / rate) into out[0 .. j1-j0-1]; returns samples clipped.
 * The carrier is a rotation per sample carried from call to call, re-anchored with sin/cos every
 * SD_CARRIER_BLOCK samples of the stream (anchors depend only on j: the stream does not depend on how
 * it is cut into calls). */
static long synth(sd_burst_state_t *B, const double *ev_t, const double *ev_a, long n_ev, double t_origin,
                  double rate, int64_t j0, int64_t j1, double carrier, double rise, double decay, int policy,
                  double *out)
{
    double w = 2.0 * SD_PI * carrier, cd = B->rc, sd = B->rs, cr = B->cc, sr = B->cs;
    long clipped = 0;
    int64_t j, q;
    for (j = j0; j < j1; j++) {
        double t, val;
        if (j % SD_CARRIER_BLOCK == 0) {
            double th = w * ((double)j / rate);
            cr = cos(th);
            sr = sin(th);
        } else if (j == j0 && B->cj != j) {
            /* not the continuation of the last call: rotate from the anchor of this block */
            int64_t ja = j - j % SD_CARRIER_BLOCK;
            double th = w * ((double)ja / rate);
            cr = cos(th);
            sr = sin(th);
            for (q = 0; q < j - ja; q++) {
                double cn = cr * cd - sr * sd, sn = sr * cd + cr * sd;
                cr = cn;
                sr = sn;
            }
        } else {
            double cn = cr * cd - sr * sd, sn = sr * cd + cr * sd;
            cr = cn;
            sr = sn;
        }
        t = t_origin + (double)j / rate;
        val = envelope_at(B, ev_t, ev_a, n_ev, t, rise, decay, policy) * sr;
        if (val > 1.0) {
            val = 1.0;
            clipped += 1;
        } else if (val < -1.0) {
            val = -1.0;
            clipped += 1;
        }
        out[j - j0] = val;
    }
    if (j1 > j0) {
        B->cc = cr;
        B->cs = sr;
        B->cj = j1;
    }
    return clipped;
}

/* ------------------------------------------------------------------ per-tick inputs */
static void axis_speed(double vx, double vy, double *ax, double *ay, double *V)
{
    double sp = sqrt(vx * vx + vy * vy), dx, dy;
    if (sp == 0.0) {
        *V = 0.0;
        return;
    }
    dx = vx / sp;
    dy = vy / sp;
    if (dx * *ax + dy * *ay >= 0.0) {
        *V = sp;
        *ax = dx;
        *ay = dy;
        return;
    }
    *V = -sp;
    *ax = -dx;
    *ay = -dy;
}

static void derive(const sd_renderer_t *R, const double *vals, double vx, double vy, double speed, double *N_out,
                   double *mus_out, double *muk_out, double *gain_out)
{
    const sd_table_t *T = R->table;
    const sd_config_t *C = &R->cfg;
    double N = T->slot[SD_SLOT_NORMAL_FORCE] ? vals[SD_SLOT_NORMAL_FORCE] : C->normal_force_constant, fs, mus, muk, gain;
    if (N < 0.0) N = 0.0;
    fs = T->slot[SD_SLOT_FRICTION_SCALE] ? vals[SD_SLOT_FRICTION_SCALE] : 1.0;
    if (fs < 0.0) fs = 0.0;
    mus = C->mu_s * fs;
    muk = C->mu_k * fs;
    if (T->slot[SD_SLOT_BREAKAWAY_FORCE] && N > 0.0) mus = py_max(vals[SD_SLOT_BREAKAWAY_FORCE], 0.0) / N;
    if (T->slot[SD_SLOT_KINETIC_FORCE] && N > 0.0) muk = py_max(vals[SD_SLOT_KINETIC_FORCE], 0.0) / N;
    if (C->k_mu != 0.0 && speed > 0.0 && T->slot[SD_SLOT_GRAD_X]) {
        double gy = T->slot[SD_SLOT_GRAD_Y] ? vals[SD_SLOT_GRAD_Y] : 0.0;
        double slope = (vals[SD_SLOT_GRAD_X] * vx + gy * vy) / speed;
        if (slope > 0.0) {
            mus += C->k_mu * slope;
            muk += C->k_mu * slope;
        }
    }
    if (muk > mus) muk = mus;
    gain = T->slot[SD_SLOT_BURST_GAIN] ? vals[SD_SLOT_BURST_GAIN] : 1.0;
    if (gain < 0.0) gain = 0.0;
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
};

sd_tick_fn sd_model_tick(int model)
{
    return model >= 0 && model < SD_NMODEL ? TICKS[model] : NULL;
}

size_t sd_renderer_size(void) { return sizeof(sd_renderer_t); }

int sd_renderer_init(sd_renderer_t *R, const sd_table_t *table, const sd_config_t *cfg)
{
    const sd_pad_params_t *p = &cfg->pad;
    if (!R || !table || !cfg) return SD_ERR_ARG;
    if (table->grid.rows < 1 || table->grid.cols < 1 || !(table->grid.dx > 0.0) || !(table->grid.dy > 0.0) || table->n_blocks < 0)
        return SD_ERR_TABLE;
    /* the pad models need N: the table's channel, or the constant N of a table without it */
    if (!table->slot[SD_SLOT_NORMAL_FORCE]
        && !(cfg->normal_force_constant >= 0.0 && cfg->normal_force_constant < INFINITY))
        return SD_ERR_PARAM;
    if (cfg->k_mu > 0.0 && !table->slot[SD_SLOT_GRAD_X]) return SD_ERR_TABLE;  /* slope friction needs grad */
    if (!(p->mass > 0.0) || !(p->stiffness > 0.0) || !(p->damping >= 0.0) || !(p->burst_gain >= 0.0)
        || !(p->max_stick_period >= 0.0) || !(cfg->mu_s > 0.0) || !(cfg->mu_k >= 0.0) || cfg->mu_k > cfg->mu_s
        || !(cfg->k_mu >= 0.0))
        return SD_ERR_PARAM;
    if (!(cfg->tick_rate >= 100.0 && cfg->tick_rate <= 192000.0)) return SD_ERR_PARAM;
    if (!(cfg->audio_rate == 0.0 || (cfg->audio_rate >= 1000.0 && cfg->audio_rate <= 384000.0)))
        return SD_ERR_PARAM;
    if (!(cfg->carrier_hz > 0.0) || !(cfg->rise_s > 0.0) || !(cfg->decay_s > 0.0)) return SD_ERR_PARAM;
    if (cfg->policy < SD_RETRIGGER || cfg->policy > SD_MAX) return SD_ERR_PARAM;
    if (!sd_model_tick(cfg->model)) return SD_ERR_PARAM;
    R->table = table;
    R->cfg = *cfg;
    sd_pad_prepare(&R->pad_model, &cfg->pad);
    R->tick_fn = sd_model_tick(cfg->model);
    R->audio_cap = cfg->audio_rate > 0.0 ? (long)ceil(cfg->audio_rate / cfg->tick_rate) + 2 : 0;
    if (R->audio_cap > SD_AUDIO_BLOCK_MAX) return SD_ERR_PARAM;
    if (cfg->audio_rate > 0.0) {     /* constants of the carrier rotation: once here, not per tick */
        double w = 2.0 * SD_PI * cfg->carrier_hz;
        R->rot_cos = cos(w / cfg->audio_rate);
        R->rot_sin = sin(w / cfg->audio_rate);
    }
    sd_renderer_reset(R, 0.0);
    return SD_OK;
}

/* Index of the last audio sample at or before elapsed time e (s), plus one, as renderer.online_step
 * computes it; saturated below 2^63 so that it never overflows (audio stops after 2^63 - 2048
 * samples: 6 million years at 48 kHz). */
static int64_t sample_end(double e, double rate)
{
    double v = floor(e * rate + 1e-9);
    if (!(v < 9223372036854773760.0)) v = v > 0.0 ? 9223372036854773760.0 : 0.0;   /* 2^63 - 2048; NaN: 0 */
    return (int64_t)v + 1;
}

void sd_renderer_reset(sd_renderer_t *R, double t0)
{
    sd_pad_reset(&R->pad);
    memset(&R->run, 0, sizeof R->run);
    R->position_faults = 0;
    R->run.ax = 1.0;
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
}

void sd_renderer_seek(sd_renderer_t *R, int64_t tick, double x, double y)
{
    double t0 = R->run.t0;
    sd_renderer_reset(R, t0);
    if (tick <= 0) return;
    R->run.tick = (double)tick;
    R->run.xp = x;
    R->run.yp = y;
    if (R->audio_cap > 0)
        R->run.next_sample = sample_end((t0 + ((double)tick - 1.0) / R->cfg.tick_rate) - t0, R->cfg.audio_rate);
}

double sd_renderer_step(sd_renderer_t *R, double x, double y)
{
    double vals[SD_NSLOT];
    double k = R->run.tick, rate = R->cfg.tick_rate, t = R->run.t0 + k / rate;
    double h, vx, vy, xm, ym, V, N, mus, muk, gain, dur, drive, f, target;
    long nrec = R->run.n_recent, drop = 0, nev = 0, i, done;
    int64_t j0, j1;
    const long cap = SD_EVENT_RING;
    /* a non-finite or absurd position is a fault: hold the last valid one */
    if (!(fabs(x) <= SD_POSITION_LIMIT_M) || !(fabs(y) <= SD_POSITION_LIMIT_M)) {
        R->position_faults += 1;
        if (k != 0.0) {
            x = R->run.xp;
            y = R->run.yp;
        } else {
            x = R->table->grid.x0;
            y = R->table->grid.y0;
        }
    }
    if (k == 0.0) {
        h = 0.0;
        vx = 0.0;
        vy = 0.0;
        xm = x;
        ym = y;
    } else {
        h = t - (R->run.t0 + (k - 1.0) / rate);
        if (!(h > 0.0)) h = 1.0 / rate;     /* beyond 2^53 ticks the double times stop resolving a tick */
        vx = (x - R->run.xp) / h;
        vy = (y - R->run.yp) / h;
        xm = 0.5 * (x + R->run.xp);
        ym = 0.5 * (y + R->run.yp);
    }
    axis_speed(vx, vy, &R->run.ax, &R->run.ay, &V);
    sd_sample_slots(R->table, xm, ym, vals);
    derive(R, vals, vx, vy, fabs(V), &N, &mus, &muk, &gain);
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
    if (h > 0.0) {
        long n1 = R->tick_fn(&R->pad, &R->pad_model, t - h, h, V, N, mus, muk, gain, R->ev_t, R->ev_a, (int)cap,
                             (int)nrec);
        nev = n1 - nrec;
        if (n1 > cap) {
            R->run.events_dropped += n1 - cap;
            n1 = cap;
        }
        nrec = n1;
    }
    R->run.n_recent = nrec;
    R->run.events_total += nev;
    /* audio samples with times in (t - h, t] */
    R->n_audio = 0;
    if (R->audio_cap > 0) {
        j0 = R->run.next_sample;
        j1 = sample_end(t - R->run.t0, R->cfg.audio_rate);
        if (j1 - j0 > R->audio_cap) j0 = j1 - R->audio_cap;
        if (j1 > j0)
            R->run.clipped += synth(&R->bursts, R->ev_t, R->ev_a, nrec, R->run.t0, R->cfg.audio_rate, j0, j1,
                                    R->cfg.carrier_hz, R->cfg.rise_s, R->cfg.decay_s, R->cfg.policy, R->audio);
        R->run.next_sample = j1;
        R->n_audio = j1 - j0 > 0 ? j1 - j0 : 0;
    }
    drive = envelope_at(&R->bursts, R->ev_t, R->ev_a, nrec, t, R->cfg.rise_s, R->cfg.decay_s, R->cfg.policy)
            * sin(2.0 * SD_PI * R->cfg.carrier_hz * (t - R->run.t0));
    drive = py_min(py_max(drive, -1.0), 1.0);
    f = R->pad.f;
    R->out.t = t;
    R->out.x = x;
    R->out.y = y;
    R->out.vx = vx;
    R->out.vy = vy;
    R->out.pad_speed = V;
    R->out.normal_force = N;
    R->out.friction_force = f;
    R->out.state = R->pad.phase;
    R->out.lateral_x = vals[SD_SLOT_LATERAL_X];
    R->out.lateral_y = vals[SD_SLOT_LATERAL_Y];
    target = R->table->slot[SD_SLOT_SKIN_STRETCH] ? vals[SD_SLOT_SKIN_STRETCH] : R->cfg.skin_target;
    R->out.skin_stretch = mus * N > 0.0 ? target * f / (mus * N) : 0.0;
    R->out.events = (double)nev;
    R->out.drive = drive;
    R->out.audio_samples = (double)R->n_audio;
    R->run.xp = x;
    R->run.yp = y;
    R->run.tick = k + 1.0;
    return drive;
}
