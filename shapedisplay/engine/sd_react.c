/* sd_react.c -- reactive widgets and moving surfaces: press handling, the widget state machine, moving
 * parts and the event queue (docs/reactive.md).
 *
 * A table may carry reactive widgets (sd_table_t.react: REACT_DEF records, sd_layout.h). Each tick the
 * renderer asks sd_react_lookup for the slot values at the finger -- the static table with every toggle's
 * block read at the patch of the state it is in, plus every moving part (a slider's thumb, a movable
 * object, a scrolling or keyframed surface) added where it has moved to -- and for the velocity of the
 * surface under the finger, which the pad model sees subtracted from the finger's. After the pad model,
 * sd_react_update handles the tick's press force: a press crossing a widget's threshold under the
 * finger presses it (a button clicks, a toggle flips and clicks, a slider's thumb or an object is
 * grabbed), a press falling below the release level releases it (and drops what it held); a held thumb
 * follows the finger along its track, clamped to it, ticking at each detent it passes; moving parts move
 * on. Every change plays from the next tick. Events go to a ring (sd_react_pop).
 *
 * Work per tick: a pass over the moving parts (each a bilinear look-up of its patch when the finger is
 * on it) and, on a tick whose press changes, one over the widgets; at most SD_DETENTS_PER_TICK detent
 * ticks; keyframe search over the part's keyframes (at most SD_MAX_KEYS). Nothing is allocated. All
 * arithmetic is in sd_real: no double on the tick path of the single-precision build.
 */
#include <math.h>
#include <string.h>
#include "sd_runtime.h"
#include "sd_math.h"

/* ------------------------------------------------------------------ the event queue */
static void push(sd_react_t *K, int64_t kind, int64_t widget, int64_t tick, sd_real value)
{
    sd_react_event_t *e;
    if (K->count == SD_REACT_QUEUE) {          /* full: the oldest goes */
        K->head = (K->head + 1) % SD_REACT_QUEUE;
        K->count -= 1;
        K->dropped += 1;
    }
    e = &K->queue[(K->head + K->count) % SD_REACT_QUEUE];
    e->kind = kind;
    e->widget = widget;
    e->tick = tick;
    e->value = value;
    K->count += 1;
    K->total += 1;
    K->tick_events += 1;
}

int sd_react_pop(sd_renderer_t *R, sd_react_event_t *ev)
{
    sd_react_t *K = &R->react;
    if (K->count == 0) return 0;
    *ev = K->queue[K->head];
    K->head = (K->head + 1) % SD_REACT_QUEUE;
    K->count -= 1;
    return 1;
}

double sd_react_event_time(const sd_renderer_t *R, const sd_react_event_t *ev)
{
    return (double)R->run.t0 + (double)ev->tick / (double)R->cfg.tick_rate;
}

/* ------------------------------------------------------------------ helpers */
static sd_real clampr(sd_real v, sd_real lo, sd_real hi) { return v < lo ? lo : (v > hi ? hi : v); }

/* v modulo w in [0, w) (w > 0) */
static sd_real pmod(sd_real v, sd_real w)
{
    sd_real m = SD_FMOD(v, w);
    if (m < SD_R(0.0)) m += w;
    if (m >= w) m = SD_R(0.0);
    return m;
}

/* Detents at or below thumb centre c: detent k (0 .. n-1) sits at detent0 + k step. */
static sd_real detent_region(const sd_react_def_t *d, sd_real c)
{
    sd_real r;
    if (d->n_detents <= 0) return SD_R(0.0);
    r = SD_FLOOR((c - d->detent0) / d->detent_step) + SD_R(1.0);
    return clampr(r, SD_R(0.0), (sd_real)d->n_detents);
}

/* Displacement (dx, dy) and velocity (vx, vy) of a keyframed part at time c along its keyframes: piecewise
 * linear between keyframes, held before the first and after the last. */
static void keyframe(const sd_table_t *T, const sd_react_def_t *d, sd_real c, sd_real *dx, sd_real *dy, sd_real *vx,
                     sd_real *vy)
{
    const sd_react_key_t *k = T->react_keys + d->key0;
    int64_t i, n = d->n_keys;
    *vx = *vy = SD_R(0.0);
    if (c <= k[0].t) {
        *dx = k[0].dx;
        *dy = k[0].dy;
        return;
    }
    for (i = 0; i + 1 < n; i++) {
        if (c < k[i + 1].t) {
            sd_real span = k[i + 1].t - k[i].t, u = (c - k[i].t) / span;
            *vx = (k[i + 1].dx - k[i].dx) / span;
            *vy = (k[i + 1].dy - k[i].dy) / span;
            *dx = k[i].dx + (k[i + 1].dx - k[i].dx) * u;
            *dy = k[i].dy + (k[i + 1].dy - k[i].dy) * u;
            return;
        }
    }
    *dx = k[n - 1].dx;
    *dy = k[n - 1].dy;
}

/* A keyframe clock moved on by h: wrapped at the loop period, or held just past the last keyframe. */
static sd_real clock_after(const sd_table_t *T, const sd_react_def_t *d, sd_real c, sd_real h)
{
    sd_real last = T->react_keys[d->key0 + d->n_keys - 1].t;
    c += h;
    if (d->loop_s > SD_R(0.0)) return c >= d->loop_s ? pmod(c, d->loop_s) : c;
    return c > last ? last + SD_R(1.0) : c;
}

/* Toggles in the state their block does not store: their block read at the other state's patch. */
static void rebuild_overrides(const sd_table_t *T, sd_react_t *K)
{
    int i;
    K->n_ov = 0;
    for (i = 0; i < K->n; i++) {
        const sd_react_def_t *d = &T->react[i];
        /* (compared as a flag: a float to int64 conversion calls a double helper on a 32-bit core) */
        if (d->kind != SD_REACT_TOGGLE || (K->state[i].state != SD_R(0.0)) == (d->state0 != 0)) continue;
        K->ov_block[K->n_ov] = (int32_t)d->block;
        K->ov_off[K->n_ov] = (int32_t)(K->state[i].state != SD_R(0.0) ? d->offset_b : d->offset_a);
        K->n_ov += 1;
    }
}

void sd_react_reset(sd_renderer_t *R)
{
    sd_react_t *K = &R->react;
    const sd_table_t *T = R->table;
    int i;
    memset(K, 0, sizeof *K);
    K->held = -1;
    K->on_part = -1;
    if (!T || T->n_react <= 0 || !T->react) return;
    K->n = T->n_react < SD_MAX_REACTIVE ? T->n_react : SD_MAX_REACTIVE;
    K->skipped = T->n_react - K->n;
    for (i = 0; i < K->n; i++) {
        const sd_react_def_t *d = &T->react[i];
        sd_react_state_t *st = &K->state[i];
        st->state = (sd_real)d->state0;
        if (d->part_rows > 0) K->part[K->n_parts++] = i;
        if (d->kind == SD_REACT_SLIDER) {
            st->thumb = d->thumb_c;
            st->value = (d->thumb_c - d->track0) / d->track_len;
            st->reported = st->value;
            st->region = detent_region(d, d->thumb_c);
        }
        if (d->n_keys > 0) {
            sd_real vx, vy;
            keyframe(T, d, SD_R(0.0), &st->dx, &st->dy, &vx, &vy);
        }
    }
    rebuild_overrides(T, K);
}

void sd_react_restart(sd_renderer_t *R, sd_real t0)
{
    sd_react_state_t keep[SD_MAX_REACTIVE];
    int i, n = R->react.n;
    memcpy(keep, R->react.state, (size_t)n * sizeof keep[0]);
    sd_renderer_reset(R, t0);
    for (i = 0; i < n && i < R->react.n; i++) {
        R->react.state[i] = keep[i];
        R->react.state[i].pressed = SD_R(0.0);      /* a new run starts with the finger lifted */
        R->react.state[i].grabbed = SD_R(0.0);
    }
    rebuild_overrides(R->table, &R->react);
}

/* ------------------------------------------------------------------ looking up */
/* Add moving part d at canvas position (u, v) to vals: its patch read bilinearly (the background outside
 * it), minus the background -- what the part adds to the surface beneath. */
static void add_part(const sd_table_t *T, const sd_react_def_t *d, sd_real u, sd_real v, sd_real *vals)
{
    long nr = (long)d->part_rows, nc = (long)d->part_cols, off = (long)d->part_offset, c0, r0, i[4];
    sd_real fc = (u - T->grid.x0) / T->grid.dx - (sd_real)d->part_col0, fr, tx, ty;
    int s, k;
    if (!(fc > SD_R(-1.0) && fc < (sd_real)nc)) return;          /* also NaN */
    c0 = (long)SD_FLOOR(fc);
    tx = fc - (sd_real)c0;
    if (T->grid.rows == 1) {
        r0 = 0;
        ty = SD_R(0.0);
    } else {
        fr = (v - T->grid.y0) / T->grid.dy - (sd_real)d->part_row0;
        if (!(fr > SD_R(-1.0) && fr < (sd_real)nr)) return;
        r0 = (long)SD_FLOOR(fr);
        ty = fr - (sd_real)r0;
    }
    for (k = 0; k < 4; k++) {
        long r = r0 + (k >> 1), c = c0 + (k & 1);
        i[k] = (r >= 0 && r < nr && c >= 0 && c < nc) ? off + r * nc + c : -1;
    }
    for (s = 0; s < SD_NSLOT; s++) {
        const sd_channel_t *ch = T->slot[s];
        sd_real top, bot;
        if (!ch) continue;
        top = sd_channel_value(ch, i[0]) * (1 - tx) + sd_channel_value(ch, i[1]) * tx;
        bot = sd_channel_value(ch, i[2]) * (1 - tx) + sd_channel_value(ch, i[3]) * tx;
        vals[s] += top * (1 - ty) + bot * ty - ch->background;
    }
}

void sd_react_lookup(sd_renderer_t *R, sd_real xm, sd_real ym, sd_real h, sd_real *vals, sd_real *svx, sd_real *svy)
{
    const sd_table_t *T = R->table;
    sd_react_t *K = &R->react;
    int j;
    if (K->n_ov) sd_sample_slots_ov(T, xm, ym, vals, K->ov_block, K->ov_off, K->n_ov);
    else sd_sample_slots(T, xm, ym, vals);
    *svx = *svy = SD_R(0.0);
    K->on_part = -1;
    for (j = 0; j < K->n_parts; j++) {
        int i = K->part[j];
        const sd_react_def_t *d = &T->react[i];
        const sd_react_state_t *st = &K->state[i];
        sd_real dx, dy, vx = SD_R(0.0), vy = SD_R(0.0), u, v;
        int on;
        if (i == K->held) continue;            /* held: the finger feels what lies beneath it */
        if (d->wrap) {                         /* content scrolling through its box at (vx, vy) */
            sd_real W = d->x1 - d->x0, H = d->y1 - d->y0;
            vx = d->vx;
            vy = d->vy;
            dx = st->dx + SD_R(0.5) * h * vx;
            dy = st->dy + SD_R(0.5) * h * vy;
            on = xm >= d->x0 && xm <= d->x1 && (T->grid.rows == 1 || (ym >= d->y0 && ym <= d->y1));
            if (!on) continue;                 /* nothing of it shows outside its box */
            u = d->x0 + pmod(xm - d->x0 - dx, W);
            v = H > SD_R(0.0) ? d->y0 + pmod(ym - d->y0 - dy, H) : ym - dy;
        } else {
            if (d->n_keys > 0) keyframe(T, d, clock_after(T, d, st->clock, SD_R(0.5) * h), &dx, &dy, &vx, &vy);
            else {
                dx = st->dx;
                dy = st->dy;
            }
            u = xm - dx;
            v = ym - dy;
            on = u >= d->x0 && u <= d->x1 && (T->grid.rows == 1 || (v >= d->y0 && v <= d->y1));
        }
        if (on) {                              /* the topmost part under the finger moves the surface */
            K->on_part = i;
            *svx = vx;
            *svy = vy;
        }
        add_part(T, d, u, v, vals);
    }
}

/* ------------------------------------------------------------------ pressing */
sd_real sd_react_click(const sd_react_t *K, sd_real t)
{
    sd_real tau = t - K->click_t;
    if (!(tau >= SD_R(0.0) && tau < K->click_s)) return SD_R(0.0);
    return K->click_a * SD_SIN(K->click_w * tau) * (SD_R(1.0) - tau / K->click_s);
}

/* A click of widget d at time t: the event, and its drive and friction transient (replacing any in progress). */
static void click(sd_react_t *K, const sd_react_def_t *d, int64_t tick, sd_real t, sd_real value)
{
    if (!(d->click_gain > SD_R(0.0) || d->drop > SD_R(0.0))) return;
    push(K, SD_EV_CLICK, d->widget, tick, value);
    K->click_on = 1;
    K->click_t = t;
    K->click_a = d->click_gain;
    K->click_w = SD_R(2.0) * SD_PI * d->click_hz;
    K->click_s = d->click_s;
    K->drop = d->drop;
    K->drop_s = d->drop_s;
}

/* The finger at (x, y) on widget d's box (a moving object's or keyframed part's box where it has moved to). */
static int in_box(const sd_table_t *T, const sd_react_def_t *d, const sd_react_state_t *st, sd_real x, sd_real y)
{
    if (d->part_rows > 0 && !d->wrap && d->kind != SD_REACT_SLIDER) {
        x -= st->dx;
        y -= st->dy;
    }
    return x >= d->x0 && x <= d->x1 && (T->grid.rows == 1 || (y >= d->y0 && y <= d->y1));
}

static void press_widget(sd_react_t *K, const sd_table_t *T, int i, sd_real x, sd_real y, int64_t tick, sd_real t)
{
    const sd_react_def_t *d = &T->react[i];
    sd_react_state_t *st = &K->state[i];
    st->pressed = SD_R(1.0);
    push(K, SD_EV_PRESS, d->widget, tick, SD_R(0.0));
    switch ((int)d->kind) {
    case SD_REACT_BUTTON:
        click(K, d, tick, t, SD_R(0.0));
        break;
    case SD_REACT_TOGGLE:
        st->state = st->state != SD_R(0.0) ? SD_R(0.0) : SD_R(1.0);
        push(K, SD_EV_TOGGLE, d->widget, tick, st->state);
        click(K, d, tick, t, SD_R(0.0));
        rebuild_overrides(T, K);
        break;
    case SD_REACT_SLIDER: {
        sd_real along = d->axis ? y : x, cross = d->axis ? x : y;
        if (K->held >= 0 || !(SD_FABS(along - st->thumb) <= d->thumb_r)
            || !(T->grid.rows == 1 || SD_FABS(cross - d->cross_c) <= d->thumb_r))
            break;                             /* a press on the track beside the thumb: only pressed */
        K->held = i;
        st->grabbed = SD_R(1.0);
        st->grab_x = along - st->thumb;
        push(K, SD_EV_GRAB, d->widget, tick, st->value);
        break;
    }
    case SD_REACT_OBJECT:
        if (K->held >= 0) break;
        K->held = i;
        st->grabbed = SD_R(1.0);
        st->grab_x = x - st->dx;
        st->grab_y = y - st->dy;
        push(K, SD_EV_GRAB, d->widget, tick, SD_R(0.0));
        break;
    default:
        break;
    }
}

static void drop(sd_react_t *K, const sd_table_t *T, int64_t tick)
{
    int i = K->held;
    const sd_react_def_t *d = &T->react[i];
    sd_react_state_t *st = &K->state[i];
    if (d->kind == SD_REACT_SLIDER) {
        push(K, SD_EV_VALUE, d->widget, tick, st->value);
        st->reported = st->value;
    }
    push(K, SD_EV_DROP, d->widget, tick, d->kind == SD_REACT_SLIDER ? st->value : SD_R(0.0));
    st->grabbed = SD_R(0.0);
    K->held = -1;
}

/* The held thumb follows the finger along its track, clamped to it: detent ticks, value events. */
static void follow_thumb(sd_react_t *K, const sd_table_t *T, int i, sd_real x, sd_real y, int64_t tick, sd_real t)
{
    const sd_react_def_t *d = &T->react[i];
    sd_react_state_t *st = &K->state[i];
    sd_real along = d->axis ? y : x, c, region, disp;
    int fired = 0;
    c = clampr(along - st->grab_x, d->track0, d->track0 + d->track_len);
    st->thumb = c;
    disp = c - d->thumb_c;
    st->dx = d->axis ? SD_R(0.0) : disp;
    st->dy = d->axis ? disp : SD_R(0.0);
    st->value = (c - d->track0) / d->track_len;
    region = detent_region(d, c);
    /* one tick per detent passed, in the order passed (at most SD_DETENTS_PER_TICK in one tick) */
    while (region != st->region && fired < SD_DETENTS_PER_TICK) {
        sd_real k = region > st->region ? st->region + SD_R(1.0) : st->region;   /* the detent number passed */
        click(K, d, tick, t, k);
        st->region += region > st->region ? SD_R(1.0) : -SD_R(1.0);
        fired += 1;
    }
    st->region = region;
    if (SD_FABS(st->value - st->reported) >= d->value_step) {
        push(K, SD_EV_VALUE, d->widget, tick, st->value);
        st->reported = st->value;
    }
}

void sd_react_update(sd_renderer_t *R, sd_real x, sd_real y, sd_real press, sd_real t, sd_real h, int64_t tick)
{
    const sd_table_t *T = R->table;
    sd_react_t *K = &R->react;
    sd_real p_prev = K->press;
    int i, j, top = -1;
    K->tick_events = 0;
    /* releases: a pressed widget whose press fell below its release level (and what it held is dropped) */
    for (i = 0; i < K->n; i++) {
        const sd_react_def_t *d = &T->react[i];
        sd_react_state_t *st = &K->state[i];
        if (st->pressed != SD_R(0.0) && press < d->release_n) {
            st->pressed = SD_R(0.0);
            push(K, SD_EV_RELEASE, d->widget, tick, SD_R(0.0));
            if (K->held == i) drop(K, T, tick);
        }
    }
    /* a press crossing the threshold of the topmost reactive widget under the finger presses it */
    if (press > p_prev) {
        for (i = K->n - 1; i >= 0 && top < 0; i--)
            if (T->react[i].press_n > SD_R(0.0) && in_box(T, &T->react[i], &K->state[i], x, y)) top = i;
        if (top >= 0) {
            const sd_react_def_t *d = &T->react[top];
            if (K->state[top].pressed == SD_R(0.0) && p_prev < d->press_n && press >= d->press_n)
                press_widget(K, T, top, x, y, tick, t);
        }
    }
    K->press = press;
    if (K->held >= 0) {
        const sd_react_def_t *d = &T->react[K->held];
        sd_react_state_t *st = &K->state[K->held];
        if (d->kind == SD_REACT_SLIDER) {
            follow_thumb(K, T, K->held, x, y, tick, t);
        } else {                               /* an object: where the finger takes it */
            st->dx = x - st->grab_x;
            st->dy = y - st->grab_y;
        }
    }
    /* moving parts move on */
    for (j = 0; j < K->n_parts; j++) {
        const sd_react_def_t *d = &T->react[K->part[j]];
        sd_react_state_t *st = &K->state[K->part[j]];
        if (d->wrap) {
            sd_real W = d->x1 - d->x0, H = d->y1 - d->y0;
            st->dx = pmod(st->dx + d->vx * h, W);
            st->dy = H > SD_R(0.0) ? pmod(st->dy + d->vy * h, H) : SD_R(0.0);
        } else if (d->n_keys > 0) {
            sd_real vx, vy;
            st->clock = clock_after(T, d, st->clock, h);
            keyframe(T, d, st->clock, &st->dx, &st->dy, &vx, &vy);
        }
    }
    /* the click is over once its drive and its friction transient are, for every time of this tick (the audio
     * samples of the tick lie in (t - h, t]) */
    if (K->click_on && t - h - K->click_t >= (K->click_s > K->drop_s ? K->click_s : K->drop_s)) K->click_on = 0;
}
