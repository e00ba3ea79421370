/* sd_karnopp.c -- the modified Karnopp virtual spring (Provancher and Sylvester), one renderer tick at a time.
 *
 * Rules of the arithmetic in sd_pad.c (compile with -ffp-contract=off). No libm call: stick is linear in time, so every breakaway is located inside the
 * tick in closed form.
 *
 * S->x is the spring stretch z (finger minus anchor), the friction force k_K z. Stuck: z' = V, breakaway
 * (the burst, amplitude B mu_s N) when |k_K z| reaches mu_s N. Sliding: z = s mu_k N / k_K, the anchor
 * dragged behind the finger while |V| >= v_T and the finger moves in the slip direction. Re-stick (force
 * kept) when |V| < v_T (at once after a breakaway: a slow finger plays a sawtooth inside the tick) or on
 * a reversal.
 *
 * Work per tick: O(1) plus O(1) per breakaway; at most SD_MAX_EVENTS_PER_TICK loop passes (a tick cut
 * there counts in S->truncated). A sawtooth tooth lasts (mu_s - mu_k) N / (k_K |V|), with |V| < v_T.
 */
#include "sd_pad_common.h"

int sd_karnopp_tick(sd_pad_state_t *S, const sd_pad_t *P, sd_real t0, sd_real h, sd_real V, sd_real N,
                    sd_real mus, sd_real muk, sd_real gain, sd_real *ev_t, sd_real *ev_a, int cap, int n_ev)
{
    sd_real kk = P->p.karnopp_spring;
    sd_real vt = P->p.karnopp_v_threshold;
    sd_real B = P->p.burst_gain * gain;
    sd_real z = S->x, phase = S->phase, s = S->s;
    sd_real thr = mus * N;
    sd_real zk = muk * N / kk;              /* stretch while sliding (anchor dragged) */
    int drops = kk * zk < thr;              /* a breakaway lowers the force: a slow finger sticks again */
    int nev0 = n_ev;
    sd_real t = SD_R(0.0);
    long it = 0;
    if (phase == SD_R(1.0) && ((SD_FABS(V) < vt && drops) || V * s <= SD_R(0.0)))
        phase = SD_R(0.0);                  /* stuck again, force preserved (slow finger, or a reversal) */
    while (t < h && phase == SD_R(0.0)) {
        sd_real rem, tb, sb;
        it += 1;
        if (it > SD_MAX_EVENTS_PER_TICK) {
            S->truncated += 1;
            break;
        }
        rem = h - t;
        if (SD_FABS(kk * z) > thr * (SD_R(1.0) + SD_R(SD_TOL_BREAK)) || (thr == SD_R(0.0) && z != SD_R(0.0))) {
            tb = SD_R(0.0);                 /* over the limit already (N dropped): breakaway at once */
            sb = sd_sgn(z);
        } else if (V == SD_R(0.0)) {
            break;
        } else {
            sb = sd_sgn(V);
            tb = (sb * thr / kk - z) / V;
            if (tb < SD_R(0.0)) tb = SD_R(0.0);
            if (tb >= rem) {
                z += V * rem;
                break;
            }
        }
        t += tb;
        s = sb;
        n_ev = record(ev_t, ev_a, cap, n_ev, t0 + t, B * thr);
        z = s * zk;
        if (V * s > SD_R(0.0) && (SD_FABS(V) >= vt || !drops))
            phase = SD_R(1.0);              /* sliding: the anchor is dragged behind the finger */
    }
    if (phase == SD_R(1.0)) z = s * zk;
    S->x = z;
    S->v = V;
    S->phase = phase;
    S->s = s;
    S->f = kk * z;
    S->n_events = n_ev - nev0;
    return n_ev;
}
