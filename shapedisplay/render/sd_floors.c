/* Timing floors for the reports: the least work any renderer of a stroke does (reports.common).
 *
 * Not part of the runtime: loops that read and write as much as a renderer must and compute almost
 * nothing, timed next to a model to bound its speed-up from above (floor_costs, interface_floor).
 * Plain C99 in IEEE double; each loop body is one multiply, so the compiler may vectorise it.
 */
#include <stdint.h>

/* Per tick: read the tick's input, write one output. out[i] = V[i] * h for i < n. */
void sd_floor_tick(const double *V, double *out, int64_t n, double h)
{
    for (int64_t i = 0; i < n; i++)
        out[i] = V[i] * h;
}

/* Per audio sample: a stored carrier period (p samples) times an envelope value, whole periods only:
 * out[j + q] = e * period[q] for every whole period j that fits in n samples. */
void sd_floor_audio(double *out, int64_t n, const double *period, int64_t p, double e)
{
    if (p <= 0)
        return;
    for (int64_t j = 0; j + p <= n; j += p)
        for (int64_t q = 0; q < p; q++)
            out[j + q] = e * period[q];
}

/* The model interface (run_kernel's): six input rows read, four output rows (row-major 4 x n) written, one
 * multiply or a sum and a multiply each. */
void sd_floor_interface(const double *t, const double *V, const double *N, const double *mus,
                        const double *muk, const double *gain, double *out, int64_t n, double h)
{
    for (int64_t i = 0; i < n; i++) {
        out[i] = V[i] * h;
        out[n + i] = N[i] * h;
        out[2 * n + i] = (mus[i] + muk[i]) * h;
        out[3 * n + i] = (gain[i] + t[i]) * h;
    }
}
