/* jfmath.c: sin, cos, tan, exp, expm1, log and log1p of the native FMUs, with the
 * same bits on every platform.
 *
 * A C library's functions differ between systems by an ulp here and there, so an FMU
 * built for Linux and for Windows would not give the same numbers.  These functions
 * use IEEE double additions, multiplications and divisions only (and exact operations
 * on the bits), in a fixed order; built with -ffp-contract=off (no fused multiply-add)
 * on SSE2 they give the same bits wherever they run.  Each is within one ulp of the
 * exact value (tests/nativefmu/test_jfmath.py checks them against 50-digit references).
 *
 * Method: argument reduction (x = n pi/2 + r for the trigonometric functions, exactly
 * for any double through the bits of 2/pi; x = k ln 2 + r for exp; x = 2^k m for log)
 * to a small range where a Taylor series, summed in Horner's order, is exact to far
 * below an ulp; the rounding of the last addition is kept small the way fdlibm does
 * it (the leading terms added last, the reduced argument's tail carried along).
 */
#include <stdint.h>
#include <string.h>

#include "jfmath.h"

static uint64_t bits_of(double x) { uint64_t u; memcpy(&u, &x, sizeof u); return u; }
static double of_bits(uint64_t u) { double x; memcpy(&x, &u, sizeof x); return x; }

#define JF_INF_BITS 0x7ff0000000000000u
#define JF_NAN_BITS 0x7ff8000000000000u
#define ROUNDER 0x1.8p52 /* adding and subtracting it rounds to an integer, half to even */

/* 1/n! and 2/(2n+1) rounded to the nearest double; tan's Taylor coefficients. */
static const double SIN_C[] = {
    -0x1.5555555555555p-3, 0x1.1111111111111p-7, -0x1.a01a01a01a01ap-13,
    0x1.71de3a556c734p-19, -0x1.ae64567f544e4p-26, 0x1.6124613a86d09p-33,
    -0x1.ae7f3e733b81fp-41, 0x1.952c77030ad4ap-49, -0x1.2f49b46814157p-57,
}; /* x^3 .. x^19 */
static const double COS_C[] = {
    0x1.5555555555555p-5, -0x1.6c16c16c16c17p-10, 0x1.a01a01a01a01ap-16,
    -0x1.27e4fb7789f5cp-22, 0x1.1eed8eff8d898p-29, -0x1.93974a8c07c9dp-37,
    0x1.ae7f3e733b81fp-45, -0x1.6827863b97d97p-53, 0x1.e542ba4020225p-62,
}; /* x^4 .. x^20 */
static const double EXP_C[] = {
    0x1.0000000000000p-1, 0x1.5555555555555p-3, 0x1.5555555555555p-5,
    0x1.1111111111111p-7, 0x1.6c16c16c16c17p-10, 0x1.a01a01a01a01ap-13,
    0x1.a01a01a01a01ap-16, 0x1.71de3a556c734p-19, 0x1.27e4fb7789f5cp-22,
    0x1.ae64567f544e4p-26, 0x1.1eed8eff8d898p-29, 0x1.6124613a86d09p-33,
    0x1.93974a8c07c9dp-37, 0x1.ae7f3e733b81fp-41,
}; /* r^2 .. r^15 */
static const double LOG_C[] = {
    0x1.5555555555555p-1, 0x1.999999999999ap-2, 0x1.2492492492492p-2,
    0x1.c71c71c71c71cp-3, 0x1.745d1745d1746p-3, 0x1.3b13b13b13b14p-3,
    0x1.1111111111111p-3, 0x1.e1e1e1e1e1e1ep-4, 0x1.af286bca1af28p-4,
    0x1.8618618618618p-4, 0x1.642c8590b2164p-4,
}; /* 2 atanh(s) = 2 s + s (s^2 .. s^22 terms) */
static const double TAN_C[] = {
    0x1.5555555555555p-2, 0x1.1111111111111p-3,
    0x1.ba1ba1ba1ba1cp-5, 0x1.664f4882c10fap-6, 0x1.226e355e6c23dp-7,
    0x1.d6d3d0e157de0p-9, 0x1.7da36452b75e3p-10, 0x1.3558248036744p-11,
    0x1.f57d7734d1664p-13, 0x1.967e18afcafadp-14, 0x1.497d8eea25259p-15,
    0x1.0b132d39a6050p-16, 0x1.b0f72d3ee24e9p-18, 0x1.5ef2da474e5b7p-19,
    0x1.1c77df95c1c0dp-20, 0x1.cd299de4ae6bbp-22, 0x1.75cde6563fed9p-23,
    0x1.2efe8db3aff1fp-24, 0x1.eb3229047434cp-26, 0x1.8e25ff9327e2cp-27,
    0x1.42ba1a349b490p-28, 0x1.0597b61cb3092p-29, 0x1.a813f6eaa7058p-31,
    0x1.57bea2950f11ep-32, 0x1.16a101c5fde96p-33,
}; /* x^3 .. x^51 */
#define N_OF(a) ((int)(sizeof(a) / sizeof((a)[0])))

/* Bits of 2/pi after the binary point, 64 a word, most significant first. */
static const uint64_t TWO_OVER_PI[] = {
    0xa2f9836e4e441529u, 0xfc2757d1f534ddc0u, 0xdb6295993c439041u,
    0xfe5163abdebbc561u, 0xb7246e3a424dd2e0u, 0x06492eea09d1921cu,
    0xfe1deb1cb129a73eu, 0xe88235f52ebb4484u, 0xe99c7026b45f7e41u,
    0x3991d639835339f4u, 0x9c845f8bbdf9283bu, 0x1ff897ffde05980fu,
    0xef2f118b5a0a6d1fu, 0x6d367ecf27cb09b7u, 0x4f463f669e5fea2du,
    0x7527bac7ebe5f17bu, 0x3d0739f78a5292eau, 0x6bfb5fb11f8d5d08u,
    0x56033046fc7b6babu, 0xf0cfbc209af4361du,
};

static const double PIO2_HI = 0x1.921fb54442d18p+0, PIO2_LO = 0x1.1a62633145c07p-54;
static const double PIO4_HI = 0x1.921fb54442d18p-1, PIO4_LO = 0x1.1a62633145c07p-55;
static const double INV_PIO2 = 0x1.45f306dc9c883p-1;
/* pi/2 = P1 + P2 + P3 + O(2^-130): P1, P2 of 37 bits (n P1, n P2 exact for n < 2^16) */
static const double P1 = 0x1.921fb54440000p+0, P2 = 0x1.68c234c4c0000p-39,
                    P3 = 0x1.98a2e03707345p-77;
/* ln 2 = LN2_HI + LN2_LO, LN2_HI of 42 bits (k LN2_HI exact for |k| < 2^11) */
static const double LN2_HI = 0x1.62e42fefa3800p-1, LN2_LO = 0x1.ef35793c76730p-45;
static const double INV_LN2 = 0x1.71547652b82fep+0, SQRT2 = 0x1.6a09e667f3bcdp+0;

static double horner(const double *c, int n, double z) {
    double p = c[n - 1];
    int i;
    for (i = n - 2; i >= 0; i--) p = c[i] + z * p;
    return p;
}

static double fabs_(double x) { return of_bits(bits_of(x) & ~((uint64_t)1 << 63)); }

/* 2^k for -1022 <= k <= 1023 */
static double pow2(int k) { return of_bits((uint64_t)(k + 1023) << 52); }

/* a b = p + e exactly (Dekker's product: no fused multiply-add needed) */
static void two_prod(double a, double b, double *p, double *e) {
    const double split = 134217729.0; /* 2^27 + 1 */
    double ca = split * a, cb = split * b;
    double ah = ca - (ca - a), al = a - ah, bh = cb - (cb - b), bl = b - bh;
    *p = a * b;
    *e = (((ah * bh - *p) + ah * bl) + al * bh) + al * bl;
}

/* ------------------------------------------------------- argument reduction */

/* a b = hi 2^64 + lo for 64-bit a, b */
static void mul64(uint64_t a, uint64_t b, uint64_t *hi, uint64_t *lo) {
    uint64_t a0 = a & 0xffffffffu, a1 = a >> 32, b0 = b & 0xffffffffu, b1 = b >> 32;
    uint64_t p00 = a0 * b0, p01 = a0 * b1, p10 = a1 * b0, p11 = a1 * b1;
    uint64_t mid = (p00 >> 32) + (p01 & 0xffffffffu) + (p10 & 0xffffffffu);
    *lo = (mid << 32) | (p00 & 0xffffffffu);
    *hi = p11 + (p01 >> 32) + (p10 >> 32) + (mid >> 32);
}

/* 64 bits of the 256-bit number w (w[0] least significant) from bit pos upwards */
static uint64_t bits64(const uint64_t w[4], int pos) {
    int i = pos / 64, s = pos % 64;
    uint64_t v = i < 4 ? w[i] >> s : 0;
    if (s && i + 1 < 4) v |= w[i + 1] << (64 - s);
    return v;
}

/* ax = n pi/2 + (hi + lo), |hi + lo| <= pi/4, for finite ax >= pi/4: exactly (to
 * 2^-100 relative) for every double, from 192 bits of 2/pi chosen by ax's exponent.
 * Returns n mod 4. */
static int reduce_exact(double ax, double *hi, double *lo) {
    uint64_t u = bits_of(ax), m = (u & 0xfffffffffffffu) | ((uint64_t)1 << 52);
    uint64_t w[3], p[4], h0, l0, h1, l1, h2, l2, c, fh, fl, top, mid;
    int e = (int)(u >> 52) - 1075; /* ax = m 2^e */
    /* the bits of 2/pi at 2^-i with i < e - 1 add multiples of 4 to ax 2/pi */
    int i0 = e - 1 > 1 ? e - 1 : 1, k = (i0 - 1) / 64, sh = (i0 - 1) % 64, j, b0, q, lz, neg;
    double a, b, ph, pe, t, s;
    for (j = 0; j < 3; j++)
        w[j] = sh ? (TWO_OVER_PI[k + j] << sh) | (TWO_OVER_PI[k + j + 1] >> (64 - sh))
                  : TWO_OVER_PI[k + j];
    mul64(m, w[2], &h2, &l2);
    mul64(m, w[1], &h1, &l1);
    mul64(m, w[0], &h0, &l0);
    p[0] = l2;
    p[1] = h2 + l1;
    c = p[1] < h2;
    p[2] = h1 + l0;
    j = p[2] < h1;          /* carries, added one at a time */
    p[2] += c;
    c = (uint64_t)j + (p[2] < c);
    p[3] = h0 + c;
    b0 = i0 + 191 - e; /* bit of p worth 2^0 */
    q = (int)(bits64(p, b0) & 3u);
    fh = bits64(p, b0 - 64);
    fl = bits64(p, b0 - 128);
    neg = (int)(fh >> 63); /* fraction >= 1/2: round n up, the fraction becomes negative */
    if (neg) {
        q = (q + 1) & 3;
        fl = ~fl + 1u;
        fh = ~fh + (fl == 0);
    }
    lz = 0;
    if (fh == 0) { fh = fl; fl = 0; lz = 64; }
    if (fh == 0) { *hi = *lo = 0.0; return q; } /* never for a double: 2/pi is irrational */
    while (!(fh >> 63)) {
        fh = (fh << 1) | (fl >> 63);
        fl <<= 1;
        lz++;
    }
    top = fh >> 11;                              /* 53 bits */
    mid = ((fh & 0x7ffu) << 42) | (fl >> 22);    /* the next 53 */
    a = (double)top * 0x1p-53;                   /* fraction = (a + b) 2^-lz */
    b = (double)mid * 0x1p-106;
    two_prod(a, PIO2_HI, &ph, &pe);
    t = pe + (a * PIO2_LO + b * PIO2_HI);
    s = ph + t;
    t = t - (s - ph);
    *hi = s * of_bits((uint64_t)(1023 - lz) << 52);
    *lo = t * of_bits((uint64_t)(1023 - lz) << 52);
    if (neg) { *hi = -*hi; *lo = -*lo; }
    return q;
}

/* x = n pi/2 + (hi + lo) for finite x; returns n mod 4 */
static int reduce(double x, double *hi, double *lo) {
    double ax = fabs_(x), fn, d, wv, s, bb, e;
    int n;
    if (ax <= PIO4_HI) { *hi = x; *lo = 0.0; return 0; }
    n = -1;
    if (ax < 65536.0) { /* Cody and Waite: fast, exact unless r is small */
        fn = (ax * INV_PIO2 + ROUNDER) - ROUNDER;
        d = ax - fn * P1;  /* exact */
        wv = fn * P2;      /* exact */
        s = d - wv;
        bb = s - d;
        e = ((d - (s - bb)) - (wv + bb)) - fn * P3;
        *hi = s + e;
        *lo = e - (*hi - s);
        if (fabs_(*hi) > 0x1p-10) n = (int)fn & 3;
    }
    if (n < 0) n = reduce_exact(ax, hi, lo);
    if (x < 0) { *hi = -*hi; *lo = -*lo; n = (4 - n) & 3; }
    return n;
}

/* ------------------------------------------------------------------- kernels */

/* sin(x + y), |x| <= pi/4, |y| small against ulp(x) */
static double k_sin(double x, double y) {
    double z = x * x, v = z * x, r = horner(SIN_C + 1, N_OF(SIN_C) - 1, z);
    return x - (((z * (0.5 * y - v * r)) - y) - v * SIN_C[0]);
}

/* cos(x + y), |x| <= pi/4 */
static double k_cos(double x, double y) {
    double z = x * x, hz = 0.5 * z, w = 1.0 - hz;
    double r = z * z * horner(COS_C, N_OF(COS_C), z);
    return w + (((1.0 - w) - hz) + (r - x * y));
}

/* tan(x + y) (odd = 0) or -1/tan(x + y) (odd = 1), |x| <= pi/4 */
static double k_tan(double x, double y, int odd) {
    double ax = fabs_(x), sg = x < 0 ? -1.0 : 1.0, z, v, t, tl, q, p, pe, rr, w;
    if (ax >= 0.6744) { /* tan(pi/4 - y') = (1 - w) / (1 + w), w = tan(y'), y' <= 0.11 */
        double yy = (PIO4_HI - ax) + (PIO4_LO - sg * y);
        z = yy * yy;
        w = yy + yy * z * horner(TAN_C, 10, z);
        return odd ? -sg * (1.0 + 2.0 * w / (1.0 - w)) : sg * (1.0 - 2.0 * w / (1.0 + w));
    }
    z = x * x;
    v = x * z * horner(TAN_C, N_OF(TAN_C), z) + y * (1.0 + z);
    t = x + v;
    if (!odd) return t;
    tl = v - (t - x);
    /* -1/(t + tl) = q (1 - rr), rr = 1 + q (t + tl) */
    q = -1.0 / t;
    two_prod(q, t, &p, &pe);
    rr = ((1.0 + p) + pe) + q * tl;
    return q + q * rr;
}

/* ------------------------------------------------------------ trigonometric */

double jm_sin(double x) {
    double hi, lo;
    uint64_t u = bits_of(x);
    if ((u & JF_INF_BITS) == JF_INF_BITS) return x - x; /* NaN for inf and NaN */
    switch (reduce(x, &hi, &lo)) {
    case 0: return k_sin(hi, lo);
    case 1: return k_cos(hi, lo);
    case 2: return -k_sin(hi, lo);
    default: return -k_cos(hi, lo);
    }
}

double jm_cos(double x) {
    double hi, lo;
    uint64_t u = bits_of(x);
    if ((u & JF_INF_BITS) == JF_INF_BITS) return x - x;
    switch (reduce(x, &hi, &lo)) {
    case 0: return k_cos(hi, lo);
    case 1: return -k_sin(hi, lo);
    case 2: return -k_cos(hi, lo);
    default: return k_sin(hi, lo);
    }
}

double jm_tan(double x) {
    double hi, lo;
    int n;
    uint64_t u = bits_of(x);
    if ((u & JF_INF_BITS) == JF_INF_BITS) return x - x;
    n = reduce(x, &hi, &lo);
    return k_tan(hi, lo, n & 1);
}

/* ------------------------------------------------------------ exponential */

/* x = k ln 2 + (hi - lo), |hi - lo| <= 0.35; returns k */
static int reduce_ln2(double x, double *hi, double *lo) {
    double fk = (x * INV_LN2 + ROUNDER) - ROUNDER;
    *hi = x - fk * LN2_HI; /* exact */
    *lo = fk * LN2_LO;
    return (int)fk;
}

/* y 2^k for 1 <= y < 4 (underflow rounds twice, the same way everywhere) */
static double scale(double y, int k) {
    if (k > 1023) return y * 2.0 * pow2(k - 1);
    if (k < -1021) return y * pow2(k + 1000) * 0x1p-1000;
    return y * pow2(k);
}

double jm_exp(double x) {
    double hi, lo, r, p;
    int k;
    if (x != x) return x + x;
    if (x > 709.782712893384) return of_bits(JF_INF_BITS);
    if (x < -745.1332191019412) return 0.0;
    k = reduce_ln2(x, &hi, &lo);
    r = hi - lo;
    p = r * r * horner(EXP_C, N_OF(EXP_C), r);
    return scale(1.0 + (hi - (lo - p)), k);
}

double jm_expm1(double x) {
    double hi, lo, r, tail, two, a, b, s, bb;
    int k;
    if (x != x) return x + x;
    if (x > 709.782712893384) return of_bits(JF_INF_BITS);
    if (x < -40.0) return -1.0; /* exp(x) < 2^-57: -1 is the nearest double */
    if (fabs_(x) < 0.3465) /* x + x^2/2 + x^3 (1/6 + ...) */
        return x + (0.5 * x * x + x * x * x * horner(EXP_C + 1, N_OF(EXP_C) - 1, x));
    k = reduce_ln2(x, &hi, &lo);
    r = hi - lo;
    tail = lo - r * r * horner(EXP_C, N_OF(EXP_C), r); /* exp(r) - 1 = hi - tail */
    if (k > 53) return scale(1.0 + (hi - tail), k);
    two = pow2(k);
    if (k < -53) return two * (1.0 + (hi - tail)) - 1.0;
    /* 2^k (hi - tail) + (2^k - 1): (2^k - 1) + 2^k hi summed exactly first (it cancels) */
    a = two - 1.0;
    b = two * hi;
    s = a + b;
    bb = s - a;
    return s + (((a - (s - bb)) + (b - bb)) - two * tail);
}

/* ------------------------------------------------------------- logarithm */

/* k ln 2 + log(1 + f) + c, f = m - 1 with sqrt(2)/2 <= m < sqrt(2) (fdlibm's way) */
static double log_kernel(int k, double f, double c) {
    double s = f / (2.0 + f), z = s * s, hfsq = 0.5 * f * f;
    double rr = z * horner(LOG_C, N_OF(LOG_C), z);
    return k * LN2_HI - ((hfsq - (s * (hfsq + rr) + (k * LN2_LO + c))) - f);
}

/* u = 2^k m with sqrt(2)/2 <= m < sqrt(2), for finite u > 0; returns k */
static int split_exp(double u, double *m) {
    int k = 0;
    uint64_t b;
    if (u < 0x1p-1022) { u *= 0x1p54; k = -54; }
    b = bits_of(u);
    k += (int)(b >> 52) - 1023;
    *m = of_bits((b & 0xfffffffffffffu) | ((uint64_t)1023 << 52));
    if (*m >= SQRT2) { *m *= 0.5; k++; }
    return k;
}

double jm_log(double x) {
    double m;
    int k;
    if (x != x) return x + x;
    if (x < 0.0) return of_bits(JF_NAN_BITS);
    if (x == 0.0) return -of_bits(JF_INF_BITS);
    if (bits_of(x) == JF_INF_BITS) return x;
    k = split_exp(x, &m);
    return log_kernel(k, m - 1.0, 0.0); /* m - 1 exact */
}

double jm_log1p(double x) {
    double u, m, c;
    int k;
    if (x != x) return x + x;
    if (x < -1.0) return of_bits(JF_NAN_BITS);
    if (x == -1.0) return -of_bits(JF_INF_BITS);
    if (bits_of(x) == JF_INF_BITS) return x;
    if (x > -0.2928 && x < 0.4142) return log_kernel(0, x, 0.0);
    u = 1.0 + x;
    /* c/u: the rounding of 1 + x, log(1 + x) = log(u) + c/u to first order */
    c = u < 0x1p53 ? (u >= 2.0 ? 1.0 - (u - x) : x - (u - 1.0)) / u : 0.0;
    k = split_exp(u, &m);
    return log_kernel(k, m - 1.0, c);
}

int jm_ceil_log2(double v) {
    int e = 0;
    uint64_t b;
    if (v < 0x1p-1022) { v *= 0x1p54; e = -54; }
    b = bits_of(v);
    e += (int)(b >> 52) - 1023; /* v = 2^e (1 + fraction) */
    return (b & 0xfffffffffffffu) ? e + 1 : e;
}
