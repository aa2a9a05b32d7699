/* Windowed peak-to-peak: the largest range (max - min) over every window of w
 * consecutive samples, one value per row (C99, libc only).
 *
 * van Herk / Gil-Werman: the row is cut into blocks of w samples; within each block the
 * running maximum and minimum from its start (g) and from its end (h) are one pass each,
 * and the window starting at i, which spans at most two blocks, has the maximum
 * max(h[i], g[i + w - 1]) (the same for the minimum).  Three passes, a few comparisons
 * per sample whatever w and whatever the signal.  The result is max - min of one window,
 * the same subtraction of the same two samples as the running filters of
 * orchestrator.metrics.peak, so the value is identical.  Row r's sample i is
 * x[r * srow + i * ssamp] (strides in elements: a transposed view is read in place,
 * GROUP rows per pass).
 * Rows must be finite (the caller checks); returns 0, 1 when out of memory, 2 for a
 * window that is empty or longer than the rows.
 */
#include <stdlib.h>

/* Rows gathered together when they are not contiguous (a transposed view): one pass
 * over the samples for GROUP rows at a time, instead of one strided pass per row. */
#define GROUP 16

int window_range_max(const double *x, long rows, long n, long w, long srow, long ssamp,
                     double *out) {
    long r, i, b0, g, r0 = -GROUP;
    double *buf, *gx, *gn, *hx, *hn;
    if (n <= 0 || w <= 0 || w > n) return 2;
    buf = (double *)malloc((size_t)((GROUP + 4) * n) * sizeof(double));
    if (buf == NULL) return 1;
    gx = buf + GROUP * n;
    gn = gx + n;
    hx = gn + n;
    hn = hx + n;
    for (r = 0; r < rows; r++) {
        const double *y = x + r * srow;
        double best = 0.0;
        if (ssamp != 1) {
            if (r >= r0 + GROUP) {   /* gather this row and the next ones */
                long k = rows - r < GROUP ? rows - r : GROUP;
                r0 = r;
                for (i = 0; i < n; i++)
                    for (g = 0; g < k; g++) buf[g * n + i] = x[(r0 + g) * srow + i * ssamp];
            }
            y = buf + (r - r0) * n;
        }
        for (b0 = 0; b0 < n; b0 += w) {
            long b1 = b0 + w < n ? b0 + w : n;
            double hi = y[b0], lo = y[b0];
            gx[b0] = hi;
            gn[b0] = lo;
            for (i = b0 + 1; i < b1; i++) {
                double v = y[i];
                hi = v > hi ? v : hi;
                lo = v < lo ? v : lo;
                gx[i] = hi;
                gn[i] = lo;
            }
            hi = lo = y[b1 - 1];
            hx[b1 - 1] = hi;
            hn[b1 - 1] = lo;
            for (i = b1 - 2; i >= b0; i--) {
                double v = y[i];
                hi = v > hi ? v : hi;
                lo = v < lo ? v : lo;
                hx[i] = hi;
                hn[i] = lo;
            }
        }
        for (i = 0; i + w - 1 < n; i++) {
            double p = hx[i], q = gx[i + w - 1], s = hn[i], t = gn[i + w - 1];
            double d = (p > q ? p : q) - (s < t ? s : t);
            best = (i == 0 || d > best) ? d : best;
        }
        out[r] = best;
    }
    free(buf);
    return 0;
}
