/* Windowed peak-to-peak: the largest range (max - min) over every window of w
 * consecutive samples, one value per row (C99, libc only).
 *
 * Monotone queues of the running maximum and minimum (each sample enters and leaves
 * each queue once: O(n) per row whatever w).  The result is max - min of one window,
 * the same subtraction of the same two samples as the running filters of
 * orchestrator.metrics.peak, so the value is identical.  Rows must be finite (the
 * caller checks); returns 0, or 1 when out of memory.
 */
#include <stdlib.h>

int window_range_max(const double *x, long rows, long n, long w, double *out) {
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
        const double *y = x + r * n;
        long hmax = 0, tmax = 0, hmin = 0, tmin = 0;
        double best = 0.0;
        int first = 1;
        for (i = 0; i < n; i++) {
            while (tmax > hmax && y[qmax[tmax - 1]] <= y[i]) tmax--;
            qmax[tmax++] = i;
            while (tmin > hmin && y[qmin[tmin - 1]] >= y[i]) tmin--;
            qmin[tmin++] = i;
            if (qmax[hmax] <= i - w) hmax++;
            if (qmin[hmin] <= i - w) hmin++;
            if (i >= w - 1) {
                double d = y[qmax[hmax]] - y[qmin[hmin]];
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
