/* sd_play_path.c -- whole runs in one call: the host entry points of the Python binding.
 *
 * sd_play_path plays a cursor path through the renderer (sd_renderer_step per sample, keeping every
 * tick's outputs, every audio sample and every stick-to-slip event); sd_pad_run runs a pad model
 * alone over per-tick inputs (no table). Both use only the runtime's public API (sd_runtime.h) and
 * are built into the package's engine library with it (double precision). */
#include <string.h>

#include "sd_runtime.h"

enum {
    SD_PLAY_AUDIO_FULL = -30,   /* more audio samples than audio_cap */
    SD_PLAY_EVENTS_FULL = -31,  /* more events than ev_cap */
    SD_PLAY_REACT_FULL = -32,   /* more reaction events than rev_cap */
    SD_RUN_MODEL = -34          /* no tick for this model id */
};

/* Play n cursor samples (x[i], y[i]) m, pressing with press[i] N (press NULL: not pressing), from the
 * renderer's current state. Writes out[0..n-1], audio[0..counts[0]-1], the stick-to-slip events
 * ev_t/ev_a[0..counts[1]-1] and the reaction events rev[0..counts[5]-1] (every one: the queue is emptied
 * each tick); counts[2] is the number of audio samples limited to full scale, counts[3] the events the ring
 * could not hold while they sounded (the audio of the add and max policies then misses them; the event
 * list keeps them), counts[4] the cursor samples held (not finite or beyond SD_POSITION_LIMIT_M).
 * Returns SD_OK or an SD_PLAY_* code (outputs then partial). */
int sd_play_path(sd_renderer_t *R, const double *x, const double *y, const double *press, int64_t n,
                 sd_outputs_t *out, double *audio, int64_t audio_cap, double *ev_t, double *ev_a, int64_t ev_cap,
                 sd_react_event_t *rev, int64_t rev_cap, int64_t *counts)
{
    int64_t i, k, na = 0, ne = 0, nr = 0, nev, nrec;
    sd_react_event_t e;
    for (i = 0; i < n; i++) {
        sd_renderer_step_press(R, x[i], y[i], press ? press[i] : 0.0);
        while (sd_react_pop(R, &e)) {
            if (nr >= rev_cap) return SD_PLAY_REACT_FULL;
            rev[nr++] = e;
        }
        out[i] = R->out;
        if (na + (int64_t)R->n_audio > audio_cap) return SD_PLAY_AUDIO_FULL;
        for (k = 0; k < (int64_t)R->n_audio; k++) audio[na + k] = (double)R->audio[k];
        na += (int64_t)R->n_audio;
        nev = (int64_t)R->out.events;
        nrec = (int64_t)R->run.n_recent;     /* the tick's events are the last nev held in the ring */
        if (nev > nrec) nev = nrec;          /* a tick with more events than the ring: those it kept */
        if (ne + nev > ev_cap) return SD_PLAY_EVENTS_FULL;
        for (k = nrec - nev; k < nrec; k++) {
            ev_t[ne] = (double)R->ev_t[k];
            ev_a[ne] = (double)R->ev_a[k];
            ne++;
        }
    }
    counts[0] = na;
    counts[1] = ne;
    counts[2] = (int64_t)R->run.clipped;
    counts[3] = (int64_t)R->run.events_dropped;
    counts[4] = (int64_t)R->position_faults;
    counts[5] = nr;
    return SD_OK;
}

/* Run pad model `model` (SD_MODEL_*) over n ticks from state S (updated in place). Tick i runs from
 * t[i-1] to t[i] with the inputs V[i], N[i], mus[i], muk[i], gain[i] (tick 0 has zero length and
 * reports the initial state); mus, muk and gain may hold one value for every tick (their *_one flag
 * set). Writes the state at the end of each tick (friction force f, phase, stretch x, pad velocity v)
 * and the events ev_t/ev_a[0..ev_cap-1]. Returns the number of events (more than ev_cap: only the
 * first ev_cap are stored; run again with more room) or SD_RUN_MODEL. */
int64_t sd_pad_run(int model, const sd_pad_params_t *params, sd_pad_state_t *S, const double *t, int64_t n,
                   const double *V, const double *N, const double *mus, const double *muk, const double *gain,
                   int mus_one, int muk_one, int gain_one, double *f, double *phase, double *x, double *v,
                   double *ev_t, double *ev_a, int64_t ev_cap)
{
    sd_pad_t P;
    sd_tick_fn tick = sd_model_tick(model);
    int64_t i, ne = 0;
    if (tick == NULL) return SD_RUN_MODEL;
    sd_pad_prepare(&P, params);
    for (i = 0; i < n; i++) {
        if (i > 0) {
            int64_t room = ne < ev_cap ? ev_cap - ne : 0;
            int cap = room > 2147483647 ? 2147483647 : (int)room;
            int got = tick(S, &P, t[i - 1], t[i] - t[i - 1], V[i], N[i], mus[mus_one ? 0 : i],
                           muk[muk_one ? 0 : i], gain[gain_one ? 0 : i], room > 0 ? ev_t + ne : ev_t,
                           room > 0 ? ev_a + ne : ev_a, cap, 0);
            ne += got;
        }
        f[i] = S->f;
        phase[i] = S->phase;
        x[i] = S->x;
        v[i] = S->v;
    }
    return ne;
}

/* Breakaway and kinetic force (mu_s N, mu_k N) of n cursor-at-rest samples, as every renderer tick derives
 * them (sd_derive): vals holds SD_NSLOT slot values per sample, present[s] != 0 where the table stores slot s. */
void sd_friction_limits(const sd_config_t *C, const int32_t *present, const double *vals, int64_t n,
                        double *breakaway, double *kinetic)
{
    sd_table_t T;
    sd_channel_t stored;
    sd_real N, mus, muk, gain;
    int64_t i;
    int s;
    memset(&T, 0, sizeof T);
    memset(&stored, 0, sizeof stored);
    for (s = 0; s < SD_NSLOT; s++) T.slot[s] = present[s] ? &stored : NULL;
    for (i = 0; i < n; i++) {
        sd_derive(&T, C, vals + i * SD_NSLOT, 0.0, 0.0, 0.0, &N, &mus, &muk, &gain);
        breakaway[i] = mus * N;
        kinetic[i] = muk * N;
    }
}

/* Byte offsets of the parts of a renderer the binding reads (out, run, pad, audio, ev_t, ev_a,
 * position_faults), the sizes of the event ring and the audio block, n_audio; then the reactions: the
 * widget states, the count of widgets played, SD_MAX_REACTIVE, the queue's counters (head, count, total,
 * dropped) and the widgets held back (skipped). */
void sd_renderer_layout(int64_t *offsets)
{
    static sd_renderer_t R;
    const char *base = (const char *)&R;
    offsets[0] = (const char *)&R.out - base;
    offsets[1] = (const char *)&R.run - base;
    offsets[2] = (const char *)&R.pad - base;
    offsets[3] = (const char *)R.audio - base;
    offsets[4] = (const char *)R.ev_t - base;
    offsets[5] = (const char *)R.ev_a - base;
    offsets[6] = (const char *)&R.position_faults - base;
    offsets[7] = SD_EVENT_RING;
    offsets[8] = SD_AUDIO_BLOCK_MAX;
    offsets[9] = (const char *)&R.n_audio - base;
    offsets[10] = (const char *)R.react.state - base;
    offsets[11] = (const char *)&R.react.n - base;
    offsets[12] = SD_MAX_REACTIVE;
    offsets[13] = (const char *)&R.react.total - base;
    offsets[14] = (const char *)&R.react.dropped - base;
    offsets[15] = (const char *)&R.react.skipped - base;
    offsets[16] = (const char *)&R.react.held - base;
}
