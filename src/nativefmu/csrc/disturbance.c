/* Disturbance kernel: one preset of distfmu.presets at its mount (distfmu.slave).
 *
 * resources/disturbance.dat holds every preset as a list of terms (harmonic, chopper,
 * scan mirror, slew, stepper, wheel imbalance, table, band-limited random; a preset is
 * one term or their sum), written from distfmu.presets at build time, plus the FMU's own
 * source as preset "custom" when it carries one.  Each term is a line-by-line port of its
 * wrench(t) in distfmu.sources.  A non-zero `seed` draws the phases exactly as
 * distfmu.presets.randomized does: numpy's SeedSequence (spawned per term of a sum)
 * and PCG64 with Generator.uniform, ported here bit for bit.  A band-limited random
 * term synthesises its record the same way: phases from default_rng(seed), then an
 * inverse FFT (radix 2 here, pocketfft in numpy: equal to round-off).
 * State: [time, theta, omega] (the input-driven wheel's rotor angle and held speed).
 */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "jfmu.h"

#define PI 3.141592653589793
#define MAX_TERMS 16

enum { HARMONIC = 1, CHOPPER = 2, SCAN = 3, SLEW = 4, STEPPER = 5, WHEEL = 6, TABLE = 7,
       RANDOM = 8 };

typedef struct {
    size_t len;
    double *p;   /* [type, parameters...] as written by nativefmu.data */
    double *rec; /* a band-limited random term's record, built by choose() */
} Term;

typedef struct {
    char name[64];
    int is_sum;
    size_t n;
    Term terms[MAX_TERMS];
} Preset;

typedef struct {
    size_t n_presets;
    Preset *presets;
    const Preset *chosen;
    Term active[MAX_TERMS]; /* chosen preset's terms, phases randomised */
    size_t n_active;
    int input_driven;
    long preset, seed, use_speed, scale, start_time, stop_time, wheel_speed, out[6], freq;
} Dist;

#define DS ((Dist *)inst->model)

/* ------------------------------------------------------------------ numpy's generators */

static uint32_t hashmix(uint32_t value, uint32_t *hash_const) {
    value ^= *hash_const;
    *hash_const *= 0x931e8875u;
    value *= *hash_const;
    value ^= value >> 16;
    return value;
}

static uint32_t mix(uint32_t x, uint32_t y) {
    uint32_t result = 0xca01f9ddu * x - 0x4973f715u * y;
    result ^= result >> 16;
    return result;
}

/* numpy.random.SeedSequence(entropy words): the pool of 4 words. */
static void seed_pool(const uint32_t *entropy, size_t n, uint32_t pool[4]) {
    uint32_t hash_const = 0x43b0d7e5u;
    size_t i, j;
    for (i = 0; i < 4; i++) pool[i] = hashmix(i < n ? entropy[i] : 0u, &hash_const);
    for (i = 0; i < 4; i++)
        for (j = 0; j < 4; j++)
            if (i != j) pool[j] = mix(pool[j], hashmix(pool[i], &hash_const));
    for (i = 4; i < n; i++)
        for (j = 0; j < 4; j++) pool[j] = mix(pool[j], hashmix(entropy[i], &hash_const));
}

/* SeedSequence.generate_state(n_words) as uint32 words. */
static void generate_state(const uint32_t pool[4], size_t n_words, uint32_t *out) {
    uint32_t hash_const = 0x8b51f9ddu;
    size_t i;
    for (i = 0; i < n_words; i++) {
        uint32_t v = pool[i % 4];
        v ^= hash_const;
        hash_const *= 0x58f38dedu;
        v *= hash_const;
        v ^= v >> 16;
        out[i] = v;
    }
}

typedef struct {
    uint64_t hi, lo;
} U128;

static U128 add128(U128 a, U128 b) {
    U128 r;
    r.lo = a.lo + b.lo;
    r.hi = a.hi + b.hi + (r.lo < a.lo);
    return r;
}

static U128 mul128(U128 a, U128 b) { /* low 128 bits of a * b */
    uint64_t a0 = a.lo & 0xffffffffu, a1 = a.lo >> 32, b0 = b.lo & 0xffffffffu, b1 = b.lo >> 32;
    uint64_t p00 = a0 * b0, p01 = a0 * b1, p10 = a1 * b0, p11 = a1 * b1;
    uint64_t mid = (p00 >> 32) + (p01 & 0xffffffffu) + (p10 & 0xffffffffu);
    U128 r;
    r.lo = (p00 & 0xffffffffu) | (mid << 32);
    r.hi = p11 + (p01 >> 32) + (p10 >> 32) + (mid >> 32) + a.hi * b.lo + a.lo * b.hi;
    return r;
}

typedef struct {
    U128 state, inc;
} Pcg64;

static void pcg_step(Pcg64 *g) {
    U128 mult;
    mult.hi = 2549297995355413924u;
    mult.lo = 4865540595714422341u;
    g->state = add128(mul128(g->state, mult), g->inc);
}

/* numpy.random.default_rng(seed): PCG64 seeded through SeedSequence(seed). */
static void pcg_seed(Pcg64 *g, uint32_t seed) {
    uint32_t pool[4], w[8];
    U128 init, seq;
    seed_pool(&seed, 1, pool);
    generate_state(pool, 8, w);
    init.hi = (uint64_t)w[0] | ((uint64_t)w[1] << 32);
    init.lo = (uint64_t)w[2] | ((uint64_t)w[3] << 32);
    seq.hi = (uint64_t)w[4] | ((uint64_t)w[5] << 32);
    seq.lo = (uint64_t)w[6] | ((uint64_t)w[7] << 32);
    g->state.hi = g->state.lo = 0;
    g->inc.hi = (seq.hi << 1) | (seq.lo >> 63);
    g->inc.lo = (seq.lo << 1) | 1u;
    pcg_step(g);
    g->state = add128(g->state, init);
    pcg_step(g);
}

static uint64_t pcg_next(Pcg64 *g) {
    uint64_t x;
    unsigned rot;
    pcg_step(g);
    x = g->state.hi ^ g->state.lo;
    rot = (unsigned)(g->state.hi >> 58);
    return (x >> rot) | (x << ((64u - rot) & 63u));
}

/* Generator.uniform(low, high): low + (high - low) * next_double. */
static double pcg_uniform(Pcg64 *g, double low, double high) {
    double d = (double)(pcg_next(g) >> 11) * (1.0 / 9007199254740992.0);
    return low + (high - low) * d;
}

/* ------------------------------------------------------------------ instantiation */

static int read_presets(JfInstance *inst, Dist *m) {
    JfData *d = jf_data_open(inst, "disturbance.dat");
    double v;
    size_t i, j, k;
    char name[64];
    if (d == NULL || jf_data_scalar(d, "n_presets", &v)) {
        jf_data_close(d);
        return JF_ERROR;
    }
    m->n_presets = (size_t)v;
    m->presets = (Preset *)jf_alloc(inst, m->n_presets, sizeof(Preset));
    if (m->presets == NULL) goto bad;
    for (i = 0; i < m->n_presets; i++) {
        Preset *p = &m->presets[i];
        double len, *codes;
        sprintf(name, "preset%lu_name_len", (unsigned long)i);
        if (jf_data_scalar(d, name, &len) || len >= 63) goto bad;
        sprintf(name, "preset%lu_name", (unsigned long)i);
        if ((codes = jf_data_array(d, name, 1, (size_t)len)) == NULL) goto bad;
        for (k = 0; k < (size_t)len; k++) p->name[k] = (char)codes[k];
        p->name[(size_t)len] = '\0';
        free(codes);
        sprintf(name, "preset%lu_sum", (unsigned long)i);
        if (jf_data_scalar(d, name, &v)) goto bad;
        p->is_sum = v != 0.0;
        sprintf(name, "preset%lu_n", (unsigned long)i);
        if (jf_data_scalar(d, name, &v) || v > MAX_TERMS) goto bad;
        p->n = (size_t)v;
        for (j = 0; j < p->n; j++) {
            sprintf(name, "preset%lu_term%lu_len", (unsigned long)i, (unsigned long)j);
            if (jf_data_scalar(d, name, &len)) goto bad;
            p->terms[j].len = (size_t)len;
            sprintf(name, "preset%lu_term%lu", (unsigned long)i, (unsigned long)j);
            if ((p->terms[j].p = jf_data_array(d, name, 1, (size_t)len)) == NULL) goto bad;
        }
    }
    jf_data_close(d);
    return JF_OK;
bad:
    jf_log(inst, 3, "disturbance.dat: preset table is malformed");
    jf_data_close(d);
    return JF_ERROR;
}

int model_instantiate(JfInstance *inst) {
    static const char *wrench[6] = {"Fx", "Fy", "Fz", "Mx", "My", "Mz"};
    Dist *m = (Dist *)jf_alloc(inst, 1, sizeof(Dist));
    int i, bad = 0;
    inst->model = m;
    if (m == NULL) return JF_ERROR;
    bad |= (m->preset = jf_vr(inst, "preset", JF_STRING)) < 0;
    bad |= (m->seed = jf_vr(inst, "seed", JF_INTEGER)) < 0;
    bad |= (m->use_speed = jf_vr(inst, "use_speed_input", JF_BOOLEAN)) < 0;
    bad |= (m->scale = jf_vr(inst, "scale", JF_REAL)) < 0;
    bad |= (m->start_time = jf_vr(inst, "start_time", JF_REAL)) < 0;
    bad |= (m->stop_time = jf_vr(inst, "stop_time", JF_REAL)) < 0;
    bad |= (m->wheel_speed = jf_vr(inst, "wheel_speed", JF_REAL)) < 0;
    bad |= (m->freq = jf_vr(inst, "frequency_scale", JF_REAL)) < 0;
    for (i = 0; i < 6; i++) bad |= (m->out[i] = jf_vr(inst, wrench[i], JF_REAL)) < 0;
    if (bad || read_presets(inst, m) != JF_OK) return JF_ERROR;
    inst->n_state = 3;
    inst->state = (double *)jf_alloc(inst, 3, sizeof(double));
    return inst->state ? JF_OK : JF_ERROR;
}

static void free_active(Dist *m) {
    size_t j;
    for (j = 0; j < m->n_active; j++) {
        free(m->active[j].p);
        free(m->active[j].rec);
        m->active[j].rec = NULL;
    }
    m->n_active = 0;
}

void model_free(JfInstance *inst) {
    Dist *m = DS;
    size_t i, j;
    if (m == NULL) return;
    free_active(m);
    for (i = 0; m->presets != NULL && i < m->n_presets; i++)
        for (j = 0; j < m->presets[i].n; j++) free(m->presets[i].terms[j].p);
    free(m->presets);
    free(m);
    inst->model = NULL;
}

/* Phases of a harmonic or wheel term, or the chopper's phase, from default_rng(seed). */
static void randomise_term(Term *t, uint32_t seed) {
    Pcg64 g;
    double *p = t->p;
    size_t i, n;
    pcg_seed(&g, seed);
    switch ((int)p[0]) {
    case HARMONIC: /* [1, f, kind, d(3), n, a(n), h(n), phi(n)] */
        n = (size_t)p[6];
        for (i = 0; i < n; i++) p[7 + 2 * n + i] = pcg_uniform(&g, 0.0, 2 * PI);
        break;
    case WHEEL: /* [6, n, h(n), C(n), D(n), A(n), phi(n), frame(9), speed] */
        n = (size_t)p[1];
        for (i = 0; i < n; i++) p[2 + 4 * n + i] = pcg_uniform(&g, 0.0, 2 * PI);
        break;
    case CHOPPER: /* [2, f, amp, kind, d(3), rise, duty, phase] */
        p[9] = pcg_uniform(&g, 0.0, 1.0);
        break;
    case RANDOM: /* [8, seed, ...]: the record is drawn from the seed itself */
        p[1] = (double)seed;
        break;
    default:
        break;
    }
}

/* numpy.interp(x, xp, fp, left, right), the same formula and branches (n >= 2). */
static double interp(double x, const double *xp, const double *fp, size_t n, double left,
                     double right) {
    size_t lo = 0, hi = n - 1;
    double slope, r;
    if (x != x) return x;
    if (x > xp[n - 1]) return right;
    if (x < xp[0]) return left;
    if (x == xp[n - 1]) return fp[n - 1];
    while (hi - lo > 1) { /* xp[lo] <= x < xp[hi] */
        size_t mid = lo + (hi - lo) / 2;
        if (xp[mid] <= x) lo = mid;
        else hi = mid;
    }
    if (xp[lo] == x) return fp[lo];
    slope = (fp[lo + 1] - fp[lo]) / (xp[lo + 1] - xp[lo]);
    r = slope * (x - xp[lo]) + fp[lo];
    if (r != r) {
        r = slope * (x - xp[lo + 1]) + fp[lo + 1];
        if (r != r && fp[lo] == fp[lo + 1]) r = fp[lo];
    }
    return r;
}

/* In-place inverse DFT, x_j = sum_k X_k exp(+2 pi i j k / n), n a power of two. */
static void inverse_fft(double *re, double *im, const double *wr, const double *wi, size_t n) {
    size_t i, j = 0, len, k, step;
    for (i = 1; i < n; i++) { /* bit-reversal permutation */
        size_t bit = n >> 1;
        for (; j & bit; bit >>= 1) j ^= bit;
        j ^= bit;
        if (i < j) {
            double t = re[i];
            re[i] = re[j];
            re[j] = t;
            t = im[i];
            im[i] = im[j];
            im[j] = t;
        }
    }
    for (len = 2; len <= n; len <<= 1) {
        step = n / len;
        for (i = 0; i < n; i += len)
            for (k = 0; k < len / 2; k++) {
                size_t a = i + k, b = a + len / 2;
                double c = wr[k * step], s = wi[k * step];
                double tr = re[b] * c - im[b] * s, ti = re[b] * s + im[b] * c;
                re[b] = re[a] - tr;
                im[b] = im[a] - ti;
                re[a] += tr;
                im[a] += ti;
            }
    }
}

/* BandLimitedRandom.record: [8, seed, fs, n, kind, d(3), m, f(m), S(m)]. */
static int random_record(JfInstance *inst, Term *t) {
    const double *p = t->p, *f = p + 9, *S = f + (size_t)p[8];
    size_t n = (size_t)p[3], half = n / 2, m = (size_t)p[8], k;
    double df = p[2] / (double)n;
    double *re = (double *)jf_alloc(inst, n, sizeof(double));
    double *im = (double *)jf_alloc(inst, n, sizeof(double));
    double *wr = (double *)jf_alloc(inst, half, sizeof(double));
    double *wi = (double *)jf_alloc(inst, half, sizeof(double));
    Pcg64 g;
    int ok = re && im && wr && wi;
    if (ok) {
        pcg_seed(&g, (uint32_t)p[1]);
        for (k = 0; k <= half; k++) { /* spectrum = 0.5 n amp exp(i phase) */
            double phase = pcg_uniform(&g, 0.0, 2 * PI);
            double amp = (k == 0 || k == half) ? 0.0
                         : sqrt(2.0 * interp((double)k * df, f, S, m, 0.0, 0.0) * df);
            double a = 0.5 * (double)n * amp;
            re[k] = a * jm_cos(phase);
            im[k] = a * jm_sin(phase);
            if (k > 0 && k < half) { /* Hermitian: irfft of the half spectrum */
                re[n - k] = re[k];
                im[n - k] = -im[k];
            }
        }
        im[0] = im[half] = 0.0;
        for (k = 0; k < half; k++) {
            wr[k] = jm_cos(2 * PI * (double)k / (double)n);
            wi[k] = jm_sin(2 * PI * (double)k / (double)n);
        }
        inverse_fft(re, im, wr, wi, n);
        for (k = 0; k < n; k++) re[k] = re[k] / (double)n;
        t->rec = re;
        re = NULL;
    }
    free(re);
    free(im);
    free(wr);
    free(wi);
    return ok ? JF_OK : JF_ERROR;
}

static const char *TERM_NAMES[] = {"", "Harmonic", "Chopper", "ScanMirror", "Slew", "Stepper",
                                   "WheelImbalance", "Table", "BandLimitedRandom"};

/* distfmu.presets.retimed on one term: its line and repetition frequencies times k (a scan
 * period and a slew interval divided), with the checks the Python source makes. */
static int retime_term(JfInstance *inst, Term *t, double k) {
    double *p = t->p;
    int type = (int)p[0];
    switch (type) {
    case HARMONIC: /* [1, f, ...] */
    case CHOPPER:  /* [2, f, ...] */
    case STEPPER:  /* [5, step_rate, ...] */
        p[1] = p[1] * k;
        return JF_OK;
    case WHEEL: /* [..., speed] */
        p[t->len - 1] = p[t->len - 1] * k;
        return JF_OK;
    case SCAN: { /* [3, inertia, period, amp, retrace, turnaround, ...] */
        double r = p[4], shortest;
        p[2] = p[2] / k;
        shortest = (r < 1 - r ? r : 1 - r) * p[2];
        if (!(p[5] < shortest)) {
            jf_log(inst, 3, "scan mirror source: turnaround must be shorter than the retrace "
                            "and the sweep (%g s), got %.17g s", shortest, p[5]);
            return JF_ERROR;
        }
        return JF_OK;
    }
    case SLEW: /* [4, angle, rate, accel, inertia, start, axis(3), has_repeat, repeat, alt] */
        if (p[9] != 0.0) {
            double r1 = p[2] / p[3], r2 = sqrt(fabs(p[1]) / p[3]);
            double ta = r1 < r2 ? r1 : r2, peak = p[3] * ta, rest = fabs(p[1]) - peak * ta;
            double duration = 2 * ta + (rest > 0.0 ? rest : 0.0) / peak;
            p[10] = p[10] / k;
            if (!(p[10] >= duration)) {
                jf_log(inst, 3, "slew source: repeat must be at least the slew duration %g s, "
                                "got %.17g", duration, p[10]);
                return JF_ERROR;
            }
            return JF_OK;
        }
        break; /* a single slew does not repeat */
    default:
        break;
    }
    jf_log(inst, 3, "a %s source does not repeat, so it has no frequency for frequency_scale "
                    "to scale; leave frequency_scale at 1 for this disturbance",
           type >= 1 && type <= 8 ? TERM_NAMES[type] : "?");
    return JF_ERROR;
}

/* The chosen preset with distfmu.presets.randomized(source, seed) applied. */
static int choose(JfInstance *inst) {
    Dist *m = DS;
    const char *name = inst->sv[m->preset];
    int seed = inst->iv[m->seed];
    double factor = inst->r[m->freq];
    size_t i, j;
    free_active(m);
    m->chosen = NULL;
    for (i = 0; i < m->n_presets; i++)
        if (strcmp(m->presets[i].name, name) == 0) m->chosen = &m->presets[i];
    if (m->chosen == NULL) {
        jf_log(inst, 3, "disturbance preset %s is unknown", name);
        return JF_ERROR;
    }
    if (seed < 0) {
        jf_log(inst, 3, "disturbance seed must be a non-negative integer, got %d", seed);
        return JF_ERROR;
    }
    for (j = 0; j < m->chosen->n; j++) {
        Term *t = &m->active[j];
        t->len = m->chosen->terms[j].len;
        t->p = (double *)jf_alloc(inst, t->len, sizeof(double));
        if (t->p == NULL) return JF_ERROR;
        memcpy(t->p, m->chosen->terms[j].p, t->len * sizeof(double));
        m->n_active = j + 1;
    }
    if (seed != 0) {
        if (m->chosen->is_sum) { /* SeedSequence(seed).spawn(n): entropy [seed,0,0,0,j] */
            for (j = 0; j < m->n_active; j++) {
                uint32_t entropy[5], pool[4], child;
                entropy[0] = (uint32_t)seed;
                entropy[1] = entropy[2] = entropy[3] = 0u;
                entropy[4] = (uint32_t)j;
                seed_pool(entropy, 5, pool);
                generate_state(pool, 1, &child);
                randomise_term(&m->active[j], child ? child : 1u);
            }
        } else if (m->n_active == 1) {
            randomise_term(&m->active[0], (uint32_t)seed);
        }
    }
    for (j = 0; j < m->n_active; j++)
        if ((int)m->active[j].p[0] == RANDOM && random_record(inst, &m->active[j]) != JF_OK)
            return JF_ERROR;
    m->input_driven = inst->bv[m->use_speed] && m->n_active == 1 && !m->chosen->is_sum &&
                      (int)m->active[0].p[0] == WHEEL;
    if (factor != 1.0) {
        if (!(isfinite(factor) && factor > 0.0)) {
            jf_log(inst, 3, "disturbance frequency_scale must be a positive finite number, "
                            "got %.17g", factor);
            return JF_ERROR;
        }
        if (inst->bv[m->use_speed]) {
            jf_log(inst, 3, "disturbance frequency_scale cannot scale a wheel driven from the "
                            "wheel_speed input (its speed is the input's); leave "
                            "frequency_scale at 1");
            return JF_ERROR;
        }
        /* no terms (no disturbance): nothing to scale */
        for (j = 0; j < m->n_active; j++)
            if (retime_term(inst, &m->active[j], factor) != JF_OK) return JF_ERROR;
    }
    return JF_OK;
}

/* ------------------------------------------------------------------ sources */

static double pymod(double a, double b) { /* numpy.mod: the sign of the divisor */
    double r = fmod(a, b);
    if (r != 0.0 && ((b < 0) != (r < 0))) r += b;
    return r;
}

static void along(double s, const double *dir, double kind, double w[6]) {
    int off = kind != 0.0 ? 3 : 0, k;
    for (k = 0; k < 3; k++) w[off + k] += s * dir[k];
}

static void harmonic(const double *p, double t, double w[6]) {
    size_t i, n = (size_t)p[6];
    const double *a = p + 7, *h = a + n, *phi = h + n;
    double s = 0.0, wf = 2 * PI * p[1];
    for (i = 0; i < n; i++) s += jm_sin(wf * (t * h[i]) + phi[i]) * a[i];
    along(s, p + 3, p[2], w);
}

static void chopper(const double *p, double t, double w[6]) {
    double f = p[1], amp = p[2], rise = p[7], duty = p[8], phase = p[9];
    double period = 1.0 / f, x = pymod(t / period - phase, 1.0) * period, high = duty * period;
    double s = x < high ? 1.0 : -1.0;
    if (rise > 0) {
        double half = 0.5 * rise;
        double x2 = period - x, d_rise = (x < x2 ? x : x2) * (x < period / 2 ? 1.0 : -1.0);
        double d_fall = x - high;
        if (fabs(d_rise) < half) s = d_rise / half;
        if (fabs(d_fall) < half) s = -d_fall / half;
    }
    along(amp * s, p + 4, p[3], w);
}

static void scan_mirror(const double *p, double t, double w[6]) {
    double inertia = p[1], period = p[2], amp = p[3], r = p[4], turn = p[5];
    double scan = 2 * amp / ((1 - r) * period), retrace = -2 * amp / (r * period);
    double x = pymod(t, period), t_sweep = (1 - r) * period, half = 0.5 * turn;
    double jump = (scan - retrace) / turn;
    int at_start = x < half || x >= period - half, at_end = fabs(x - t_sweep) < half;
    double acc = (at_start ? jump : 0.0) - (at_end ? jump : 0.0);
    along(-inertia * acc, p + 6, 1.0, w);
}

static void slew(const double *p, double t, double w[6]) {
    double angle = p[1], max_rate = p[2], max_accel = p[3], inertia = p[4], start = p[5];
    int has_repeat = p[9] != 0.0, alternate = p[11] != 0.0;
    double repeat = p[10], r1 = max_rate / max_accel, r2 = sqrt(fabs(angle) / max_accel);
    double ta = r1 < r2 ? r1 : r2, peak = max_accel * ta, rest = fabs(angle) - peak * ta;
    double tc = (rest > 0.0 ? rest : 0.0) / peak;
    double tau = t - start, sign = copysign(1.0, angle), acc;
    if (has_repeat) {
        double k = floor((tau > 0.0 ? tau : 0.0) / repeat);
        tau = tau >= 0 ? tau - k * repeat : tau;
        if (alternate) sign = sign * (pymod(k, 2) == 1 ? -1.0 : 1.0);
    }
    acc = (tau >= 0 && tau < ta) ? 1.0 : 0.0;
    acc -= (tau >= ta + tc && tau < 2 * ta + tc) ? 1.0 : 0.0;
    along(-inertia * (sign * max_accel * acc), p + 6, 1.0, w);
}

static void stepper(const double *p, double t, double w[6]) {
    double rate = p[1], peak = p[2], width = p[3], x = pymod(t, 1.0 / rate);
    double s = x < width ? jm_sin(PI * x / width) : 0.0;
    if (p[7] != 0.0) s -= (x >= width && x < 2 * width) ? jm_sin(PI * (x - width) / width) : 0.0;
    along(peak * s, p + 4, 1.0, w);
}

/* WheelImbalance.wrench_at(theta, omega). */
static void wheel_at(const double *p, double theta, double omega, double w[6]) {
    size_t i, n = (size_t)p[1];
    const double *h = p + 2, *C = h + n, *D = C + n, *A = D + n, *phi = A + n, *frame = phi + n;
    double sC = 0, cC = 0, sA = 0, sD = 0, cD = 0, w2 = omega * omega, lf[3], lm[3];
    int j;
    for (i = 0; i < n; i++) {
        double arg = theta * h[i] + phi[i], s = jm_sin(arg), c = jm_cos(arg);
        sC += s * C[i];
        cC += c * C[i];
        sA += s * A[i];
        sD += s * D[i];
        cD += c * D[i];
    }
    lf[0] = sC * w2;
    lf[1] = cC * w2;
    lf[2] = sA * w2;
    lm[0] = sD * w2;
    lm[1] = cD * w2;
    lm[2] = 0.0 * w2;
    for (j = 0; j < 3; j++) {
        w[j] += lf[0] * frame[j] + lf[1] * frame[3 + j] + lf[2] * frame[6 + j];
        w[3 + j] += lm[0] * frame[j] + lm[1] * frame[3 + j] + lm[2] * frame[6 + j];
    }
}

static void wheel(const double *p, double t, double w[6]) {
    size_t n = (size_t)p[1];
    double speed = p[2 + 5 * n + 9];
    wheel_at(p, speed * t, speed, w);
}

static void table(const double *p, double t, double w[6]) {
    size_t n = (size_t)p[2], k;
    const double *times = p + 3, *values = times + n; /* values: 6 columns of n */
    int hold = p[1] != 0.0;
    for (k = 0; k < 6; k++) {
        const double *col = values + k * n;
        w[k] += interp(t, times, col, n, hold ? col[0] : 0.0, hold ? col[n - 1] : 0.0);
    }
}

/* BandLimitedRandom.signal: the periodic record, linear between grid points. */
static void band_random(const Term *term, double t, double w[6]) {
    const double *p = term->p, *rec = term->rec;
    size_t n = (size_t)p[3], i;
    double x = pymod(t * p[2], (double)n), fi = floor(x), frac = x - fi;
    i = (size_t)fi % n;
    along((1 - frac) * rec[i] + frac * rec[(i + 1) % n], p + 5, p[4], w);
}

static void term_wrench(const Term *term, double t, double w[6]) {
    switch ((int)term->p[0]) {
    case HARMONIC: harmonic(term->p, t, w); break;
    case CHOPPER: chopper(term->p, t, w); break;
    case SCAN: scan_mirror(term->p, t, w); break;
    case SLEW: slew(term->p, t, w); break;
    case STEPPER: stepper(term->p, t, w); break;
    case WHEEL: wheel(term->p, t, w); break;
    case TABLE: table(term->p, t, w); break;
    case RANDOM: band_random(term, t, w); break;
    default: break;
    }
}

/* disturbance_output: the gated, scaled wrench at the state's time, the window's edges met
 * within JF_TIME_RTOL of the step h that ended there (0 on initialisation). */
static void write_outputs(JfInstance *inst, double h) {
    Dist *m = DS;
    const double *x = inst->state;
    double t = x[0], total[6] = {0, 0, 0, 0, 0, 0}, start = inst->r[m->start_time];
    double stop = inst->r[m->stop_time] > start ? inst->r[m->stop_time] : HUGE_VAL;
    size_t j;
    int k;
    if (m->input_driven) {
        wheel_at(m->active[0].p, x[1], x[2], total);
    } else {
        for (j = 0; j < m->n_active; j++) {
            double w[6] = {0, 0, 0, 0, 0, 0};
            term_wrench(&m->active[j], t, w);
            for (k = 0; k < 6; k++) total[k] = total[k] + w[k];
        }
    }
    for (k = 0; k < 6; k++)
        inst->r[m->out[k]] = (jf_reached(t, start, h) && !jf_reached(t, stop, h))
                                 ? inst->r[m->scale] * total[k]
                                 : 0.0;
}

/* ------------------------------------------------------------------ FMI hooks */

int model_exit_initialization(JfInstance *inst) {
    if (choose(inst) != JF_OK) return JF_ERROR;
    inst->state[0] = inst->start_time;
    inst->state[1] = 0.0;
    inst->state[2] = 0.0;
    write_outputs(inst, 0.0);
    return JF_OK;
}

int model_inputs_changed(JfInstance *inst) {
    (void)inst;
    return JF_OK;
}

int model_state_restored(JfInstance *inst) {
    if (inst->phase == JF_STEPPING && DS->chosen == NULL) return choose(inst);
    return JF_OK;
}

int model_do_step(JfInstance *inst, double t, double h) {
    Dist *m = DS;
    double *x = inst->state;
    if (m->input_driven) {
        double omega = inst->r[m->wheel_speed];
        x[1] = x[1] + omega * h;
        x[2] = omega;
    }
    x[0] = jf_end_time(t, h, x[0]); /* the host's communication point, never drifting */
    write_outputs(inst, h);
    return JF_OK;
}
