/* Windowed peak-to-peak: the largest range (max - min) over every window of w
 * consecutive samples, one value per row (C99, libc only).
 *
 * Monotone queues of the running maximum and minimum (each sample enters and leaves
 * each queue once: O(n) per row whatever w).  The result is max - min of one window,
 * the same subtraction of the same two samples as the running filters of
 * orchestrator.metrics.peak, so the value is identical.  Row r's sample i is
 * x[r * srow + i * ssamp] (strides in elements: a transposed view is read in place).
 * Rows must be finite (the caller checks); returns 0, 1 when out of memory, 2 for a
 * window that is empty or longer than the rows.
 */
#include <stdlib.h>

int window_range_max(const double *x, long rows, long n, long w, long srow, long ssamp,
                     double *out) {
    long r, i;
    long *qmax, *qmin;
    if (n <= 0 || w <= 0 || w > n) return 2;
    qmax = (long *)malloc((size_t)n * sizeof(long));
    qmin = (long *)malloc((size_t)n * sizeof(long));
    if (qmax == NULL || qmin == NULL) {
        free(qmax);
        free(qmin);
        return 1;
    }
    for (r = 0; r < rows; r++) {
        const double *y = x + r * srow;
        long hmax = 0, tmax = 0, hmin = 0, tmin = 0;
        double best = 0.0;
        int first = 1;
        for (i = 0; i < n; i++) {
            double v = y[i * ssamp];
            while (tmax > hmax && y[qmax[tmax - 1] * ssamp] <= v) tmax--;
            qmax[tmax++] = i;
            while (tmin > hmin && y[qmin[tmin - 1] * ssamp] >= v) tmin--;
            qmin[tmin++] = i;
            if (qmax[hmax] <= i - w) hmax++;
            if (qmin[hmin] <= i - w) hmin++;
            if (i >= w - 1) {
                double d = y[qmax[hmax] * ssamp] - y[qmin[hmin] * ssamp];
                if (first || d > best) best = d;
                first = 0;
            }
        }
        out[r] = best;
    }
    free(qmax);
    free(qmin);
    return 0;
}
