/* The compiler's large-array kernels in C: the operations of shapedisplay/author/kernels.py (numpy) in the
 * same order on the same samples, so the same values bit for bit (IEEE double, no contraction into fused
 * multiply-adds: built with -ffp-contract=off), in one pass without numpy's temporaries; and the count of
 * wall regions that shapedisplay.author.gradients.wall_regions otherwise takes from scipy.ndimage.
 *
 * Wall regions (sd_regions): connected regions of a mask (4-connected) in one pass over its rows, their
 * count and the k largest with their bounding boxes, without a label per sample. The mask is cut into
 * runs (maximal horizontal stretches of set samples) in raster order. A run that shares a column with a
 * run of the row above joins that run's set, and unites it with the sets of the other runs above it
 * that it touches (union-find: the united set keeps the lower number as its root, path halving on the
 * way); a run with nothing above starts a set, numbered in order. A region's first run in raster order
 * holds its first sample and has nothing above it, so its set has the region's lowest number: ordering
 * the roots numbers the regions as scipy.ndimage.label does (raster order of each region's first
 * sample). Each root carries its region's size and bounding box, merged on every union. Memory: 24 bytes
 * per set, at most one per run (a first pass counts the runs); 48 bytes per column for two rows of runs.
 *
 * NaN (slopes that overflowed into inf - inf) is handled as numpy and the Python around it handle it
 * (see next_peak).
 *
 * Codes (sd_encode): a division per sample is what bounds coding a channel (numpy's, on wider vectors
 * than a portable build gets, is as fast as a plain C loop); sd_encode multiplies by the reciprocal
 * instead and divides only where that could round to another code (see there). */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#if defined(__SSE2__)
#include <emmintrin.h>
#endif

typedef struct {                                       /* 24 bytes: sd_regions takes under 2^31 samples */
    int32_t parent;
    int32_t size;
    int32_t r0, r1, c0, c1;
} sd_run_t;

static int64_t root_of(sd_run_t *runs, int64_t i)
{
    while (runs[i].parent != i) {
        runs[i].parent = runs[runs[i].parent].parent;
        i = runs[i].parent;
    }
    return i;
}

/* Unites the sets of a and b; returns the root kept (the lower number). */
static int64_t join(sd_run_t *runs, int64_t a, int64_t b)
{
    a = root_of(runs, a);
    b = root_of(runs, b);
    if (a == b)
        return a;
    if (b < a) {
        int64_t t = a;
        a = b;
        b = t;
    }
    sd_run_t *keep = &runs[a], *gone = &runs[b];
    gone->parent = (int32_t)a;
    keep->size += gone->size;
    if (gone->r0 < keep->r0) keep->r0 = gone->r0;
    if (gone->r1 > keep->r1) keep->r1 = gone->r1;
    if (gone->c0 < keep->c0) keep->c0 = gone->c0;
    if (gone->c1 > keep->c1) keep->c1 = gone->c1;
    return a;
}

/* mask: rows x cols bytes, 0 or 1 (a numpy bool array), C order. Writes the labels of the min(k, n) largest regions to
 * top (largest first; equal sizes in label order) and their inclusive bounds (row_min, row_max,
 * col_min, col_max) to spans (4 per region). Returns n, the number of regions, or -1 if memory runs out or
 * the mask holds 2^31 samples or more. */
int64_t sd_regions(const uint8_t *mask, int64_t rows, int64_t cols, int64_t k, int64_t *top, int64_t *spans)
{
    if (rows > INT32_MAX / (cols > 0 ? cols : 1))
        return -1;
    int64_t count = 0;
    for (int64_t r = 0; r < rows; r++) {
        const uint8_t *m = mask + r * cols;
        int64_t starts = m[0];
        for (int64_t c = 1; c < cols; c++)             /* 0/1 samples: a run starts where one exceeds the last */
            starts += m[c] > m[c - 1];
        count += starts;
    }
    if (count == 0)
        return 0;
    int64_t half = cols / 2 + 2;                       /* most runs a row can hold, and a candidate */
    sd_run_t *runs = malloc((size_t)count * sizeof *runs);
    int64_t *row_runs = malloc((size_t)(6 * half) * sizeof *row_runs);
    if (!runs || !row_runs) {
        free(runs);
        free(row_runs);
        return -1;
    }
    /* previous and current row: first column, last column, run number of each run */
    int64_t *ps = row_runs, *pe = ps + half, *pid = pe + half;
    int64_t *cs = pid + half, *ce = cs + half, *cid = ce + half;
    int64_t pn = 0, next = 0;
    for (int64_t r = 0; r < rows; r++) {
        const uint8_t *m = mask + r * cols;
        /* the row's runs, without a branch per sample: each position is written as a candidate start
         * and a candidate end, and kept by advancing the count only where a run starts or ends */
        int64_t cn = 0, ends = 0, j = 0;
        unsigned before = 0;
        for (int64_t c = 0; c < cols; c++) {
            unsigned v = m[c] != 0;
            cs[cn] = c;
            cn += v & (before ^ 1u);
            ce[ends] = c - 1;
            ends += (v ^ 1u) & before;
            before = v;
        }
        if (before)
            ce[ends] = cols - 1;
        for (int64_t i = 0; i < cn; i++) {
            int64_t a = cs[i], b = ce[i], id;
            while (j < pn && pe[j] < a)
                j++;
            if (j < pn && ps[j] <= b) {                /* joins the set of the first run above it */
                id = root_of(runs, pid[j]);
                sd_run_t *q = &runs[id];
                q->size += (int32_t)(b - a + 1);
                q->r1 = (int32_t)r;
                if (a < q->c0) q->c0 = (int32_t)a;
                if (b > q->c1) q->c1 = (int32_t)b;
                for (int64_t q2 = j + 1; q2 < pn && ps[q2] <= b; q2++)
                    id = join(runs, id, pid[q2]);
            } else {                                   /* nothing above: a set of its own */
                id = next++;
                runs[id] = (sd_run_t){(int32_t)id, (int32_t)(b - a + 1), (int32_t)r, (int32_t)r, (int32_t)a,
                                      (int32_t)b};
            }
            cid[i] = id;
        }
        int64_t *t;
        t = ps; ps = cs; cs = t;
        t = pe; pe = ce; ce = t;
        t = pid; pid = cid; cid = t;
        pn = cn;
    }
    /* number the regions (roots in run order) and keep the k largest: top[0..kept) sorted by size
     * descending, then label ascending (a later root of equal size ranks after the ones kept) */
    int64_t n = 0, kept = 0;
    int64_t *best = spans;                             /* root run of each kept region, until the end */
    for (int64_t id = 0; id < next; id++) {
        if (runs[id].parent != id)
            continue;
        n++;
        int64_t size = runs[id].size;
        if (kept == k && (k == 0 || size <= runs[best[k - 1]].size))
            continue;
        int64_t i = kept < k ? kept++ : k - 1;
        while (i > 0 && runs[best[i - 1]].size < size) {
            best[i] = best[i - 1];
            top[i] = top[i - 1];
            i--;
        }
        best[i] = id;
        top[i] = n;
    }
    for (int64_t i = kept - 1; i >= 0; i--) {          /* spans[4 i ..] from best[i]: backwards, no overlap */
        sd_run_t *q = &runs[best[i]];
        spans[4 * i] = q->r0;
        spans[4 * i + 1] = q->r1;
        spans[4 * i + 2] = q->c0;
        spans[4 * i + 3] = q->c1;
    }
    free(runs);
    free(row_runs);
    return n;
}

/* The largest squared magnitude as _kernels takes it: chunk by chunk of `chunk` samples, a chunk's
 * largest value (NaN if it holds one) replacing the running peak only if it is greater (Python's max of
 * the two, peak first: a chunk holding a NaN leaves the peak as it was). */
static double next_peak(double peak, double chunk_top, int chunk_nan)
{
    return !chunk_nan && chunk_top > peak ? chunk_top : peak;
}

/* _kernels.wall_scan: m2 = gx*gx + gy*gy; mask[i] = m2 > limit2; returns the count of such samples,
 * *peak the largest m2 (chunks as next_peak). */
int64_t sd_wall_scan(const double *gx, const double *gy, int64_t n, double limit2, uint8_t *mask, double *peak,
                     int64_t chunk)
{
    int64_t count = 0;
    double top = 0.0;
    for (int64_t s = 0; s < n; s += chunk) {
        int64_t e = s + chunk < n ? s + chunk : n;
        double ctop = -INFINITY;
        int cnan = 0;
        for (int64_t i = s; i < e; i++) {
            double m2 = gx[i] * gx[i] + gy[i] * gy[i];
            uint8_t w = m2 > limit2;
            mask[i] = w;
            count += w;
            cnan |= m2 != m2;
            ctop = m2 > ctop ? m2 : ctop;
        }
        top = next_peak(top, ctop, cnan);
    }
    *peak = top;
    return count;
}

/* gradients.central_band: rows r0..r1-1 of the central differences of h (rows x cols, both at least 3),
 * second-order one-sided at the edges, sx = 0.5 / dx and sy = 0.5 / dy: gx, gy hold (r1 - r0) x cols. */
int64_t sd_central_band(const double *h, int64_t rows, int64_t cols, int64_t r0, int64_t r1, double sx,
                        double sy, double *gx, double *gy)
{
    if (rows < 3 || cols < 3 || r0 < 0 || r1 > rows || r0 >= r1)
        return -1;
    for (int64_t r = r0; r < r1; r++) {
        const double *c = h + r * cols, *u = r > 0 ? c - cols : c, *d = r + 1 < rows ? c + cols : c;
        double *ox = gx + (r - r0) * cols, *oy = gy + (r - r0) * cols;
        int64_t m = cols - 1;
        ox[0] = (4.0 * (c[1] - c[0]) - (c[2] - c[0])) * sx;
        for (int64_t j = 1; j < m; j++)
            ox[j] = (c[j + 1] - c[j - 1]) * sx;
        ox[m] = (4.0 * (c[m] - c[m - 1]) - (c[m] - c[m - 2])) * sx;
        if (r == 0) {
            const double *d2 = c + 2 * cols;
            for (int64_t j = 0; j < cols; j++)
                oy[j] = (4.0 * (d[j] - c[j]) - (d2[j] - c[j])) * sy;
        } else if (r == rows - 1) {
            const double *u2 = c - 2 * cols;
            for (int64_t j = 0; j < cols; j++)
                oy[j] = (4.0 * (c[j] - u[j]) - (c[j] - u2[j])) * sy;
        } else {
            for (int64_t j = 0; j < cols; j++)
                oy[j] = (d[j] - u[j]) * sy;
        }
    }
    return 0;
}

/* _kernels.clip_where: where mask[i], (fx, fy)[i] *= limit / sqrt(fx^2 + fy^2). Returns the count.
 * A noisy map's mask is as good as random, so a branch per sample is mispredicted about as often as
 * not: the mask's samples are first gathered a block at a time without a branch, then clipped. */
int64_t sd_clip_where(double *fx, double *fy, int64_t n, double limit, const uint8_t *mask)
{
    enum { BLOCK = 1024 };
    int32_t at[BLOCK];
    int64_t count = 0;
    for (int64_t s = 0; s < n; s += BLOCK) {
        int32_t e = (int32_t)(n - s < BLOCK ? n - s : BLOCK), k = 0;
        for (int32_t i = 0; i < e; i++) {
            at[k] = i;
            k += mask[s + i] != 0;
        }
        double *x = fx + s, *y = fy + s;
        for (int32_t j = 0; j < k; j++) {
            int32_t i = at[j];
            double f = limit / sqrt(x[i] * x[i] + y[i] * y[i]);
            x[i] *= f;
            y[i] *= f;
        }
        count += k;
    }
    return count;
}

/* _kernels.clip_magnitude: (fx, fy)[i] *= gain (1 leaves every value as it is); then where
 * fx^2 + fy^2 > limit^2, (fx, fy)[i] *= limit / sqrt(fx^2 + fy^2). Returns the count; *peak2 the largest
 * squared magnitude before clipping (chunks as next_peak). */
int64_t sd_clip_magnitude(double *fx, double *fy, int64_t n, double limit, double *peak2, int64_t chunk,
                          double gain)
{
    double limit2 = limit * limit, top = 0.0;
    int64_t count = 0;
    for (int64_t s = 0; s < n; s += chunk) {
        int64_t e = s + chunk < n ? s + chunk : n;
        double ctop = -INFINITY;
        int cnan = 0;
        for (int64_t i = s; i < e; i++) {
            double x = fx[i] * gain, y = fy[i] * gain;
            double m2 = x * x + y * y;
            cnan |= m2 != m2;
            ctop = m2 > ctop ? m2 : ctop;
            if (m2 > limit2) {
                double f = limit / sqrt(m2);
                x *= f;
                y *= f;
                count++;
            }
            fx[i] = x;
            fy[i] = y;
        }
        top = next_peak(top, ctop, cnan);
    }
    *peak2 = top;
    return count;
}

/* _kernels.encode: out[i] = clip(rint((v - offset) / scale), 0, top) of v = values[i] * gain + base (gain 1
 * and base 0 leave the values as they are but -0.0, which makes the same code as 0.0), top 255 (uint8 out)
 * or 65535 (uint16), rint rounding half to even as numpy's. Returns n, or -1 if a quotient is NaN (nothing
 * meaningful is written then: the caller codes the array in numpy).
 *
 * Every sample is first coded from y = x * (1 / scale), x = v - offset, instead of the
 * quotient q = x / scale. Both are within 2 and 1 units in the last place of the exact x / scale, so
 * |y - q| < 2^-51 |y|. Clipped to [-1, top + 1] (integers: clipping there before rounding gives the
 * code clipping after rounding gives, rint being monotonic) y is below 2^17, so |y - q| < 2^-34, and y
 * rounds to q's integer unless a half-integer lies within that of y. In a group of SD_GROUP samples
 * where some clipped y lies within 2^-20 of a half-integer, those samples are coded again by division:
 * every code is the quotient's. (Where quotients fall on half-way points exactly, as differences of
 * integer gray levels can, a few groups in a hundred hold one: small groups mend few samples.) Beyond the
 * clip bounds y and q (same sign, within a relative 2^-51) clip to the same end. Rounding is
 * (c + 1.5 * 2^52) - 1.5 * 2^52: the nearest integer, ties to even, exact for |c| < 2^51. */
#define SD_RINT(c) (((c) + 6755399441055744.0) - 6755399441055744.0)
#define SD_CLAMP(c, lo, hi) ((c) > (lo) ? ((c) < (hi) ? (c) : (hi)) : (lo))

enum { SD_GROUP = 32 };                                 /* samples mended together (see sd_encode) */

/* Codes of values[0..k) from the product by inv (clipped to [-1, top + 1], rounded, clipped to [0, top]);
 * near[g] is set nonzero where a code of group g (samples g * SD_GROUP ..) must come from the quotient
 * instead (a clipped product within 2^-20 of a half-integer) or a product is NaN. Two samples per SSE2
 * instruction where the compiler targets it. */
static void codes_by_product(const double *values, int64_t k, double gain, double base, double offset,
                             double inv, double top, int32_t *codes, uint8_t *near)
{
    double hi = top + 1.0, edge = 0.5 - 0x1p-20;
#if defined(__SSE2__)
    __m128d g = _mm_set1_pd(gain), b = _mm_set1_pd(base), off = _mm_set1_pd(offset), r = _mm_set1_pd(inv),
            lo2 = _mm_set1_pd(-1.0), hi2 = _mm_set1_pd(hi), m = _mm_set1_pd(6755399441055744.0),
            zero = _mm_setzero_pd(), top2 = _mm_set1_pd(top), sign = _mm_set1_pd(-0.0), edge2 = _mm_set1_pd(edge);
#endif
    for (int64_t s = 0; s < k; s += SD_GROUP) {
        int64_t e = s + SD_GROUP < k ? s + SD_GROUP : k, i = s;
        int flag = 0;
#if defined(__SSE2__)
        __m128d bad = _mm_setzero_pd();
        for (; i + 2 <= e; i += 2) {
            __m128d v = _mm_add_pd(_mm_mul_pd(_mm_loadu_pd(values + i), g), b);
            __m128d y = _mm_mul_pd(_mm_sub_pd(v, off), r);
            bad = _mm_or_pd(bad, _mm_cmpunord_pd(y, y));
            __m128d c = _mm_min_pd(_mm_max_pd(y, lo2), hi2);            /* as SD_CLAMP for all but NaN */
            __m128d q = _mm_sub_pd(_mm_add_pd(c, m), m);
            bad = _mm_or_pd(bad, _mm_cmpgt_pd(_mm_andnot_pd(sign, _mm_sub_pd(c, q)), edge2));
            q = _mm_min_pd(_mm_max_pd(q, zero), top2);
            _mm_storel_epi64((__m128i *)(codes + i), _mm_cvttpd_epi32(q));
        }
        flag = _mm_movemask_pd(bad) != 0;
#endif
        for (; i < e; i++) {
            double y = (values[i] * gain + base - offset) * inv;
            double c = SD_CLAMP(y, -1.0, hi), q = SD_RINT(c);
            flag |= (y != y) | (fabs(c - q) > edge);
            codes[i] = (int32_t)SD_CLAMP(q, 0.0, top);
        }
        near[s / SD_GROUP] = (uint8_t)flag;
    }
}

/* codes_by_product's codes mended: the code of each sample whose product needs it from the quotient, or
 * of every sample if all; -1 if a quotient is NaN. */
static int codes_by_quotient(const double *values, int64_t k, double gain, double base, double offset,
                             double scale, double inv, double top, int all, int32_t *codes)
{
    double hi = top + 1.0, edge = 0.5 - 0x1p-20;
    for (int64_t i = 0; i < k; i++) {
        double x = values[i] * gain + base - offset, y = x * inv;
        double c = SD_CLAMP(y, -1.0, hi), q = SD_RINT(c);
        if (all || y != y || fabs(c - q) > edge) {
            y = x / scale;
            if (y != y)
                return -1;
            c = SD_CLAMP(y, -1.0, hi);
            q = SD_RINT(c);
            codes[i] = (int32_t)SD_CLAMP(q, 0.0, top);
        }
    }
    return 0;
}

int64_t sd_encode(const double *values, int64_t n, double gain, double base, double offset, double scale,
                  double top, void *out, int64_t itemsize)
{
    enum { BLOCK = 1024 };
    int32_t codes[BLOCK];
    uint8_t near[BLOCK / SD_GROUP];
    double inv = 1.0 / scale;
    int exact = !(inv < INFINITY);
    for (int64_t s = 0; s < n; s += BLOCK) {
        int64_t k = n - s < BLOCK ? n - s : BLOCK;
        if (!exact)
            codes_by_product(values + s, k, gain, base, offset, inv, top, codes, near);
        for (int64_t g = 0; g * SD_GROUP < k; g++) {
            int64_t a = g * SD_GROUP, e = a + SD_GROUP < k ? a + SD_GROUP : k;
            if ((exact || near[g])
                    && codes_by_quotient(values + s + a, e - a, gain, base, offset, scale, inv, top, exact,
                                         codes + a) < 0)
                return -1;
        }
        int64_t i = 0;
#if defined(__SSE2__)                                  /* codes are within 0..top: packing cannot saturate */
        if (itemsize == 1)
            for (; i + 16 <= k; i += 16) {
                __m128i w0 = _mm_packs_epi32(_mm_loadu_si128((const __m128i *)(codes + i)),
                                             _mm_loadu_si128((const __m128i *)(codes + i + 4)));
                __m128i w1 = _mm_packs_epi32(_mm_loadu_si128((const __m128i *)(codes + i + 8)),
                                             _mm_loadu_si128((const __m128i *)(codes + i + 12)));
                _mm_storeu_si128((__m128i *)((uint8_t *)out + s + i), _mm_packus_epi16(w0, w1));
            }
        else {                                         /* 0..65535 as signed 16 bits, then back */
            __m128i half = _mm_set1_epi32(32768), flip = _mm_set1_epi16(-32768);
            for (; i + 8 <= k; i += 8) {
                __m128i w = _mm_packs_epi32(_mm_sub_epi32(_mm_loadu_si128((const __m128i *)(codes + i)), half),
                                            _mm_sub_epi32(_mm_loadu_si128((const __m128i *)(codes + i + 4)), half));
                _mm_storeu_si128((__m128i *)((uint16_t *)out + s + i), _mm_xor_si128(w, flip));
            }
        }
#endif
        if (itemsize == 1)
            for (; i < k; i++)
                ((uint8_t *)out)[s + i] = (uint8_t)codes[i];
        else
            for (; i < k; i++)
                ((uint16_t *)out)[s + i] = (uint16_t)codes[i];
    }
    return n;
}

/* sources.gray_to_heights: out[r][c] = (double)codes[r * stride + c] * step + lo for rows x cols codes (uint8
 * if itemsize is 1, else uint16) whose rows lie `stride` codes apart (negative: rows in reverse order, a
 * picture read bottom row first); out is C order. The product is rounded, then the sum, as numpy does them
 * one after the other. */
void sd_gray_to_heights(const void *codes, int64_t rows, int64_t cols, int64_t stride, int64_t itemsize,
                        double step, double lo, double *out)
{
    for (int64_t r = 0; r < rows; r++) {
        double *o = out + r * cols;
        if (itemsize == 1) {
            const uint8_t *g = (const uint8_t *)codes + r * stride;
            for (int64_t c = 0; c < cols; c++)
                o[c] = (double)g[c] * step + lo;
        } else {
            const uint16_t *g = (const uint16_t *)codes + r * stride;
            for (int64_t c = 0; c < cols; c++)
                o[c] = (double)g[c] * step + lo;
        }
    }
}

/* raster.rasterize_mesh: max z-buffer of the triangles faces (m x 3 vertex indices) of vert (n x 3, grid
 * units: u = column, v = row, z), into zbuf (rows x cols, filled by the caller). A sample takes a
 * triangle's height where its three edge functions are each at least -tol times that edge's length (inside
 * or within tol samples of the edge); the height is interpolated from the first vertex and clamped to the
 * triangle's own range; triangles of zero projected area cover nothing. Returns 0, or -1 for a face index
 * outside 0..n-1. Per triangle: the samples of its bounding box clipped to the grid. */
int64_t sd_zbuffer(const double *vert, int64_t n, const int64_t *faces, int64_t m, double *zbuf, int64_t rows,
                   int64_t cols, double tol)
{
    for (int64_t t = 0; t < m; t++) {
        int64_t i = faces[3 * t], j = faces[3 * t + 1], k = faces[3 * t + 2];
        if (i < 0 || j < 0 || k < 0 || i >= n || j >= n || k >= n)
            return -1;
        double ax = vert[3 * i], ay = vert[3 * i + 1], az = vert[3 * i + 2];
        double bx = vert[3 * j], by = vert[3 * j + 1], bz = vert[3 * j + 2];
        double cx = vert[3 * k], cy = vert[3 * k + 1], cz = vert[3 * k + 2];
        double area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax);
        if (area == 0.0)
            continue;
        double s = area > 0.0 ? 1.0 : -1.0;
        area = area * s;
        /* edge lengths scale the tolerance into edge-function units */
        double la = sqrt((cx - bx) * (cx - bx) + (cy - by) * (cy - by)) * tol;
        double lb = sqrt((ax - cx) * (ax - cx) + (ay - cy) * (ay - cy)) * tol;
        double lc = sqrt((bx - ax) * (bx - ax) + (by - ay) * (by - ay)) * tol;
        double umin = ax < bx ? ax : bx, umax = ax > bx ? ax : bx;
        double vmin = ay < by ? ay : by, vmax = ay > by ? ay : by;
        umin = cx < umin ? cx : umin;
        umax = cx > umax ? cx : umax;
        vmin = cy < vmin ? cy : vmin;
        vmax = cy > vmax ? cy : vmax;
        /* columns ceil(umin - tol)..floor(umax + tol) clipped to the grid, rows likewise; decided in double
         * (a vertex far outside the grid, or NaN, is skipped before any conversion to an integer) */
        double u0 = umin - tol, u1 = umax + tol, v0 = vmin - tol, v1 = vmax + tol;
        if (!(u0 <= (double)(cols - 1) && u1 >= 0.0 && v0 <= (double)(rows - 1) && v1 >= 0.0))
            continue;
        int64_t c0 = 0, c1 = cols - 1, r0 = 0, r1 = rows - 1;
        if (u0 > 0.0) {
            c0 = (int64_t)u0;                               /* truncation: floor of a positive value */
            c0 += (double)c0 < u0;
        }
        if (u1 < (double)(cols - 1))
            c1 = (int64_t)u1;
        if (v0 > 0.0) {
            r0 = (int64_t)v0;
            r0 += (double)r0 < v0;
        }
        if (v1 < (double)(rows - 1))
            r1 = (int64_t)v1;
        double zlo = az < bz ? az : bz, zhi = az > bz ? az : bz;
        zlo = cz < zlo ? cz : zlo;
        zhi = cz > zhi ? cz : zhi;
        /* Along a row each edge function, rounded as written, is monotonic in px (every rounding step is),
         * so the samples that pass all three tests are one run: the row ends where the run does. */
        for (int64_t r = r0; r <= r1; r++) {
            double py = (double)r;
            double *row = zbuf + r * cols;
            int in_run = 0;
            for (int64_t c = c0; c <= c1; c++) {
                double px = (double)c;
                double wa = s * ((cx - bx) * (py - by) - (cy - by) * (px - bx));
                double wb = s * ((ax - cx) * (py - cy) - (ay - cy) * (px - cx));
                double wc = s * ((bx - ax) * (py - ay) - (by - ay) * (px - ax));
                if (wa < -la || wb < -lb || wc < -lc) {
                    if (in_run)
                        break;
                    continue;
                }
                in_run = 1;
                double z = az + (wb * (bz - az) + wc * (cz - az)) / area;
                z = z > zlo ? z : zlo;                      /* no overshoot just outside a steep sliver */
                z = z < zhi ? z : zhi;
                if (z > row[c])
                    row[c] = z;
            }
        }
    }
    return 0;
}
