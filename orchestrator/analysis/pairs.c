/* The modal 2x2 blocks of the structured engine (orchestrator/analysis/structured.py),
 * multiplied block by block in one pass (C99, libc only).
 *
 * Pair j's block is b = a + 4 j, row major: [[b0, b1], [b2, b3]].  The numpy
 * expressions these replace make a temporary of every strided column: 26-61 us on the
 * EOS loop's rows, 10-19 us here.  Each value is computed in the same order as there
 * (products, then their sum, then the sum added; compiled without contraction into
 * fused multiply-adds), so a left product is the same to the last bit.  Row strides
 * are in elements; a row's entries are contiguous.
 */

/* Y[i, 2j:2j+2] += O[i, 2j:2j+2] b_j for every row i < r and pair j < n. */
void pair_left(const double *O, long r, long ldo, const double *a, long n, double *Y,
               long ldy) {
    long i, j;
    for (i = 0; i < r; i++) {
        const double *o = O + i * ldo;
        double *y = Y + i * ldy;
        for (j = 0; j < n; j++) {
            const double *b = a + 4 * j;
            double q = o[2 * j], v = o[2 * j + 1];
            y[2 * j] += q * b[0] + v * b[2];
            y[2 * j + 1] += q * b[1] + v * b[3];
        }
    }
}

/* Y[2j:2j+2, :c] = b_j X[2j:2j+2, :c] for every pair j < n, or += with add != 0. */
void pair_right(const double *a, long n, const double *X, long c, long ldx, double *Y,
                long ldy, int add) {
    long j, k;
    for (j = 0; j < n; j++) {
        const double *b = a + 4 * j, *x0 = X + 2 * j * ldx, *x1 = x0 + ldx;
        double *y0 = Y + 2 * j * ldy, *y1 = y0 + ldy;
        if (add) {
            for (k = 0; k < c; k++) {
                double p = x0[k], q = x1[k];
                y0[k] += b[0] * p + b[1] * q;
                y1[k] += b[2] * p + b[3] * q;
            }
        } else {
            for (k = 0; k < c; k++) {
                double p = x0[k], q = x1[k];
                y0[k] = b[0] * p + b[1] * q;
                y1[k] = b[2] * p + b[3] * q;
            }
        }
    }
}
