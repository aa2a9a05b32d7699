/* Matrix exponential of a small dense matrix (C99, libm only).
 *
 * Scaling and squaring with the [13/13] Pade approximant (Higham, SIAM J. Matrix
 * Anal. Appl. 26(4), 2005, Algorithm 2.3, degree 13 only): the matrix is scaled by
 * 2^-s so that its 1-norm is at most theta_13 = 5.37, the approximant is evaluated
 * with six matrix products and one LU solve, and the result squared s times.  This is
 * the algorithm scipy.linalg.expm uses for norms above theta_9; below, scipy takes a
 * lower degree, and both agree to a few units of round-off.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "jfmu.h"

static void matmul(const double *a, const double *b, size_t n, double *out) {
    size_t i, j, k;
    for (i = 0; i < n; i++) {
        for (j = 0; j < n; j++) out[i * n + j] = 0.0;
        for (k = 0; k < n; k++) {
            double aik = a[i * n + k];
            if (aik == 0.0) continue;
            for (j = 0; j < n; j++) out[i * n + j] += aik * b[k * n + j];
        }
    }
}

/* Solve p x = q in place (q becomes x), n right-hand sides, partial pivoting. */
static int solve(double *p, double *q, size_t n) {
    size_t i, j, k;
    for (k = 0; k < n; k++) {
        size_t piv = k;
        double best = fabs(p[k * n + k]);
        for (i = k + 1; i < n; i++)
            if (fabs(p[i * n + k]) > best) {
                best = fabs(p[i * n + k]);
                piv = i;
            }
        if (best == 0.0) return JF_ERROR;
        if (piv != k)
            for (j = 0; j < n; j++) {
                double t = p[k * n + j];
                p[k * n + j] = p[piv * n + j];
                p[piv * n + j] = t;
                t = q[k * n + j];
                q[k * n + j] = q[piv * n + j];
                q[piv * n + j] = t;
            }
        for (i = k + 1; i < n; i++) {
            double f = p[i * n + k] / p[k * n + k];
            if (f == 0.0) continue;
            for (j = k; j < n; j++) p[i * n + j] -= f * p[k * n + j];
            for (j = 0; j < n; j++) q[i * n + j] -= f * q[k * n + j];
        }
    }
    for (k = n; k-- > 0;) {
        for (j = 0; j < n; j++) {
            double s = q[k * n + j];
            for (i = k + 1; i < n; i++) s -= p[k * n + i] * q[i * n + j];
            q[k * n + j] = s / p[k * n + k];
        }
    }
    return JF_OK;
}

int jf_expm(const double *a, size_t n, double *out) {
    static const double b[14] = {
        64764752532480000.0, 32382376266240000.0, 7771770303897600.0,
        1187353796428800.0, 129060195264000.0, 10559470521600.0, 670442572800.0,
        33522128640.0, 1323241920.0, 40840800.0, 960960.0, 16380.0, 182.0, 1.0};
    const double theta13 = 5.371920351148152;
    size_t nn = n * n, i, j;
    double norm = 0.0, scale;
    int s = 0, k, status = JF_OK;
    double *w;
    double *A, *A2, *A4, *A6, *U, *V, *T;
    if (n == 0) return JF_OK;
    w = (double *)calloc(7 * nn, sizeof(double));
    if (w == NULL) return JF_ERROR;
    A = w;
    A2 = w + nn;
    A4 = w + 2 * nn;
    A6 = w + 3 * nn;
    U = w + 4 * nn;
    V = w + 5 * nn;
    T = w + 6 * nn;
    for (j = 0; j < n; j++) { /* 1-norm: largest column sum */
        double col = 0.0;
        for (i = 0; i < n; i++) col += fabs(a[i * n + j]);
        if (col > norm) norm = col;
    }
    if (norm > theta13) s = jm_ceil_log2(norm / theta13);
    if (s < 0) s = 0;
    scale = ldexp(1.0, -s);
    for (i = 0; i < nn; i++) A[i] = a[i] * scale;
    matmul(A, A, n, A2);
    matmul(A2, A2, n, A4);
    matmul(A4, A2, n, A6);
    /* U = A [A6 (b13 A6 + b11 A4 + b9 A2) + b7 A6 + b5 A4 + b3 A2 + b1 I] */
    for (i = 0; i < nn; i++) T[i] = b[13] * A6[i] + b[11] * A4[i] + b[9] * A2[i];
    matmul(A6, T, n, U);
    for (i = 0; i < nn; i++) U[i] += b[7] * A6[i] + b[5] * A4[i] + b[3] * A2[i];
    for (i = 0; i < n; i++) U[i * n + i] += b[1];
    memcpy(T, U, nn * sizeof(double));
    matmul(A, T, n, U);
    /* V = A6 (b12 A6 + b10 A4 + b8 A2) + b6 A6 + b4 A4 + b2 A2 + b0 I */
    for (i = 0; i < nn; i++) T[i] = b[12] * A6[i] + b[10] * A4[i] + b[8] * A2[i];
    matmul(A6, T, n, V);
    for (i = 0; i < nn; i++) V[i] += b[6] * A6[i] + b[4] * A4[i] + b[2] * A2[i];
    for (i = 0; i < n; i++) V[i * n + i] += b[0];
    /* (V - U) X = V + U */
    for (i = 0; i < nn; i++) {
        double v = V[i], u = U[i];
        T[i] = v - u;
        out[i] = v + u;
    }
    if (solve(T, out, n) != JF_OK) status = JF_ERROR;
    for (k = 0; k < s && status == JF_OK; k++) {
        matmul(out, out, n, T);
        memcpy(out, T, nn * sizeof(double));
    }
    free(w);
    return status;
}

/* expm(a) after power-of-two diagonal balancing (Parlett-Reinsch, LAPACK's dgebal without
 * permutations): out = D expm(D^-1 a D) D^-1 with D exact powers of two.  A stiff block
 * (rows of order w^2 h next to rows of order h) balances to entries of order w h, so the
 * scaling and squaring needs far fewer squarings and keeps its relative accuracy. */
int jf_expm_balanced(const double *a, size_t n, double *out) {
    double *b = (double *)malloc((n * n + n) * sizeof(double)), *d;
    size_t i, j;
    int iter, noconv = 1, status;
    if (b == NULL) return JF_ERROR;
    d = b + n * n;
    memcpy(b, a, n * n * sizeof(double));
    for (i = 0; i < n; i++) d[i] = 1.0;
    for (iter = 0; noconv && iter < 100; iter++) {
        noconv = 0;
        for (i = 0; i < n; i++) {
            double c = 0.0, r = 0.0, f = 1.0, s;
            for (j = 0; j < n; j++)
                if (j != i) {
                    c += fabs(b[j * n + i]);
                    r += fabs(b[i * n + j]);
                }
            if (c == 0.0 || r == 0.0) continue;
            s = c + r;
            while (c < r / 2.0) { c *= 2.0; r /= 2.0; f *= 2.0; }
            while (c >= r * 2.0) { c /= 2.0; r *= 2.0; f /= 2.0; }
            if (c + r < 0.95 * s) {
                noconv = 1;
                d[i] *= f;
                for (j = 0; j < n; j++) {
                    b[i * n + j] /= f;
                    b[j * n + i] *= f;
                }
            }
        }
    }
    status = jf_expm(b, n, out);
    if (status == JF_OK)
        for (i = 0; i < n; i++)
            for (j = 0; j < n; j++) out[i * n + j] = out[i * n + j] * d[i] / d[j];
    free(b);
    return status;
}
