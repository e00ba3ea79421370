/* sd_play_path.c -- an offline play of a whole cursor path through the C runtime.
 *
 * The loop the Python binding (shapedisplay/runtime/native.py) needs so that a path of many
 * ticks costs one call from Python: sd_renderer_step per cursor sample, keeping every tick's
 * outputs, every audio sample and every stick-to-slip event. It uses only the runtime's public
 * API (sd_runtime.h) and is built into the same shared library as the runtime.
 *
 * The offline renderer keeps every event; the runtime's event ring forgets finished bursts and
 * drops events only when more than half the ring is still sounding. A path where that happens,
 * or where a cursor position had to be held, is reported instead of played differently. */
#include "sd_runtime.h"

enum {
    SD_PLAY_AUDIO_FULL = -30,   /* more audio samples than audio_cap */
    SD_PLAY_EVENTS_FULL = -31,  /* more events than ev_cap */
    SD_PLAY_DROPPED = -32,      /* the event ring dropped events */
    SD_PLAY_HELD = -33          /* a non-finite or absurd cursor position was held */
};

/* Play n cursor samples (x[i], y[i]) m from the renderer's current state. Writes out[0..n-1],
 * audio[0..counts[0]-1] and the events ev_t/ev_a[0..counts[1]-1]; counts[2] is the number of
 * audio samples limited to full scale. Returns SD_OK or an SD_PLAY_* code (outputs then partial). */
int sd_play_path(sd_renderer_t *R, const double *x, const double *y, int64_t n, sd_outputs_t *out,
                 double *audio, int64_t audio_cap, double *ev_t, double *ev_a, int64_t ev_cap, int64_t *counts)
{
    int64_t i, k, na = 0, ne = 0, nev, nrec;
    for (i = 0; i < n; i++) {
        sd_renderer_step(R, x[i], y[i]);
        if (R->run.events_dropped != 0) return SD_PLAY_DROPPED;
        if (R->position_faults != 0) return SD_PLAY_HELD;
        out[i] = R->out;
        if (na + (int64_t)R->n_audio > audio_cap) return SD_PLAY_AUDIO_FULL;
        for (k = 0; k < (int64_t)R->n_audio; k++) audio[na + k] = (double)R->audio[k];
        na += (int64_t)R->n_audio;
        nev = (int64_t)R->out.events;
        nrec = (int64_t)R->run.n_recent;     /* the tick's events are the last nev held in the ring */
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
    return SD_OK;
}
