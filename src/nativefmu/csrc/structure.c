/* Structure kernel: a reduced model stepped with its exact ZOH discretisation.
 *
 * Same equations and state layout as structfmu.discrete.ZohStepper:
 *   x = [q_e (n_m), v_e (n_m), q_o (n_r), v_o (n_r), x_f (n_f)]
 * Each mode q'' + c q' + w^2 q = B_e u is advanced with closed-form 2x2 blocks
 * (underdamped with w h >= 1e-2, or rigid), otherwise with the exponential of its 3x3
 * augmented matrix; the Ritz block with the exponential of its augmented matrix; the
 * accelerometer low-pass rows x_f+ = F_x x + F_u u with one exponential of the whole
 * first-order model (given in this layout in the data file as A_full, B_full).
 * Discretisations for the declared step sizes (data arrays steps, a11_<j>, ...) are
 * computed by structfmu.discrete.discretize at build time.  A step within JF_STEP_RTOL of
 * a declared or an already discretised step is that step (the host's rounding: FMPy's
 * (k+1)h - kh, a host counting nanoseconds); any other step is discretised here, at its
 * first step, and kept in a cache of CACHE steps (the oldest replaced first).  The Ritz
 * block and the filter rows are stiff (kHz stack modes: an augmented matrix of norm
 * ~1e6 for 1 ms), so both are exponentiated after an exact power-of-two balancing
 * (jf_expm_balanced), which keeps scipy.linalg.expm's accuracy (about 1e-14 of peak
 * against the Python FMU, where the unbalanced exponential was 5e-8 off).
 * Outputs: y = C_x x + D u (D non-zero only for unfiltered accelerations).
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "jfmu.h"

#define CACHE 8

/* The columns of a row-major matrix that four consecutive rows read: panel p (rows 4p to
 * 4p + 3) reads columns cols[start[p]] ... cols[start[p + 1] - 1], increasing. */
typedef struct {
    size_t *start, *cols;
} Panels;

typedef struct {
    double h;
    double *a11, *G1, *G2, *Phi_o, *G_o, *F_x, *F_u; /* a11 holds a11, a12, a21, a22 */
    Panels f_cols;        /* of F_x, built on first use */
} Zoh;

typedef struct {
    size_t n_steps;
    double *steps;
    Zoh *pre;
    Zoh cache[CACHE];     /* steps discretised here */
    size_t n_cached, next_slot;
    const Zoh *cur;       /* the discretisation in use */
    size_t n_m, n_r, n_in, n_out, n_f, ns, n;
    double *omega, *cdamp, *B_e, *K_oo, *D_oo, *B_o, *C_x, *D, *A_full, *B_full;
    size_t *u_vr, *y_vr;
    int has_ft;
    /* views of the discretisation in use (cur) */
    double *a11, *a12, *a21, *a22, *G1, *G2, *Phi_o, *G_o, *F_x, *F_u;
    const Panels *f_cols;
    Panels c_cols;        /* of C_x */
    size_t *all_o;        /* 0 ... 2 n_r - 1: every column of Phi_o */
    size_t *u_on, n_on;   /* the inputs that are not zero this step */
    /* work */
    double *u, *y_state, *tq, *tv, *to, *tf, *gq, *gv, *rs;
} Structure;

#define M ((Structure *)inst->model)

/* out[i] = sum_k A[i * lda + cols[k]] x[cols[k]] for rows i < nrows (at most four),
 * k increasing: each row's terms are added in the order of the dense sum over all
 * columns, less the columns left out.  The rows are interleaved so that four
 * independent sums share each load of x (one sum at a time waits on its own adds). */
static void dot4(const double *A, size_t lda, size_t nrows, const size_t *cols, size_t nc,
                 const double *x, double *out) {
    size_t k;
    if (nrows == 4) {
        const double *a0 = A, *a1 = A + lda, *a2 = A + 2 * lda, *a3 = A + 3 * lda;
        double s0 = 0.0, s1 = 0.0, s2 = 0.0, s3 = 0.0;
        for (k = 0; k < nc; k++) {
            size_t j = cols[k];
            double xj = x[j];
            s0 += a0[j] * xj;
            s1 += a1[j] * xj;
            s2 += a2[j] * xj;
            s3 += a3[j] * xj;
        }
        out[0] = s0;
        out[1] = s1;
        out[2] = s2;
        out[3] = s3;
        return;
    }
    for (; nrows > 0; nrows--, A += lda, out++) {
        double s0 = 0.0;
        for (k = 0; k < nc; k++) s0 += A[cols[k]] * x[cols[k]];
        *out = s0;
    }
}

/* out = A x over the columns cols (all rows), four rows at a time. */
static void rows_dot(const double *A, size_t lda, size_t nrows, const size_t *cols, size_t nc,
                     const double *x, double *out) {
    size_t i;
    for (i = 0; i < nrows; i += 4)
        dot4(A + i * lda, lda, nrows - i < 4 ? nrows - i : 4, cols, nc, x, out + i);
}

/* out = A x over the columns each panel of four rows reads. */
static void panel_dot(const double *A, size_t lda, size_t nrows, const Panels *p,
                      const double *x, double *out) {
    size_t i, q;
    for (i = 0, q = 0; i < nrows; i += 4, q++)
        dot4(A + i * lda, lda, nrows - i < 4 ? nrows - i : 4, p->cols + p->start[q],
             p->start[q + 1] - p->start[q], x, out + i);
}

/* The columns of A (nrows x ncols) that each panel of four rows reads: a column whose four
 * coefficients are zero adds only zeros to their sums and is left out.  Skipping a zero
 * term keeps every sum's bits: a sum started at +0 is never -0, and s + (+-0) is s. */
static int panels_build(JfInstance *inst, const double *A, size_t nrows, size_t ncols,
                        Panels *p) {
    size_t np = (nrows + 3) / 4, q, i, j, n = 0;
    p->start = (size_t *)jf_alloc(inst, np + 1, sizeof(size_t));
    p->cols = (size_t *)jf_alloc(inst, np * ncols + 1, sizeof(size_t));
    if (p->start == NULL || p->cols == NULL) return JF_ERROR;
    for (q = 0; q < np; q++) {
        p->start[q] = n;
        for (j = 0; j < ncols; j++)
            for (i = 4 * q; i < nrows && i < 4 * q + 4; i++)
                if (A[i * ncols + j] != 0.0) {
                    p->cols[n++] = j;
                    break;
                }
    }
    p->start[np] = n;
    return JF_OK;
}

static void panels_free(Panels *p) {
    free(p->start);
    free(p->cols);
    p->start = p->cols = NULL;
}

static double *load(JfData *d, const char *name, size_t rows, size_t cols, int *ok) {
    double *p = jf_data_array(d, name, rows, cols);
    if (p == NULL) *ok = 0;
    return p;
}

static size_t *load_vrs(JfInstance *inst, JfData *d, const char *name, size_t n, int *ok) {
    double *v = load(d, name, 1, n, ok);
    size_t *out = (size_t *)jf_alloc(inst, n, sizeof(size_t)), i;
    if (v == NULL || out == NULL) {
        free(v);
        free(out);
        *ok = 0;
        return NULL;
    }
    for (i = 0; i < n; i++) out[i] = (size_t)v[i];
    free(v);
    return out;
}

int model_instantiate(JfInstance *inst) {
    Structure *m;
    JfData *d = jf_data_open(inst, "structure.dat");
    double v[5];
    int ok = 1;
    size_t i;
    if (d == NULL) return JF_ERROR;
    m = (Structure *)jf_alloc(inst, 1, sizeof(Structure));
    inst->model = m;
    if (m == NULL || jf_data_scalar(d, "n_m", &v[0]) || jf_data_scalar(d, "n_r", &v[1]) ||
        jf_data_scalar(d, "n_in", &v[2]) || jf_data_scalar(d, "n_out", &v[3]) ||
        jf_data_scalar(d, "n_f", &v[4])) {
        jf_data_close(d);
        return JF_ERROR;
    }
    m->n_m = (size_t)v[0];
    m->n_r = (size_t)v[1];
    m->n_in = (size_t)v[2];
    m->n_out = (size_t)v[3];
    m->n_f = (size_t)v[4];
    m->ns = 2 * (m->n_m + m->n_r);
    m->n = m->ns + m->n_f;
    m->omega = load(d, "omega", 1, m->n_m, &ok);
    m->cdamp = load(d, "modal_damping", 1, m->n_m, &ok);
    m->B_e = load(d, "B_e", m->n_m, m->n_in, &ok);
    m->K_oo = load(d, "K_oo", m->n_r, m->n_r, &ok);
    m->D_oo = load(d, "D_oo", m->n_r, m->n_r, &ok);
    m->B_o = load(d, "B_o", m->n_r, m->n_in, &ok);
    m->C_x = load(d, "C_x", m->n_out, m->n, &ok);
    m->D = load(d, "D", m->n_out, m->n_in, &ok);
    if (m->n_f) {
        m->A_full = load(d, "A_full", m->n, m->n, &ok);
        m->B_full = load(d, "B_full", m->n, m->n_in, &ok);
    }
    if (jf_data_scalar(d, "n_steps", &v[0]) == JF_OK) {
        size_t j;
        m->n_steps = (size_t)v[0];
        m->steps = load(d, "steps", 1, m->n_steps, &ok);
        m->pre = (Zoh *)jf_alloc(inst, m->n_steps, sizeof(Zoh));
        if (m->pre == NULL) ok = 0;
        for (j = 0; ok && j < m->n_steps; j++) {
            char name[32];
            Zoh *z = &m->pre[j];
            double *a[4];
            z->h = m->steps[j];
            const char *abcd[4] = {"a11", "a12", "a21", "a22"};
            for (i = 0; i < 4; i++) {
                sprintf(name, "%s_%lu", abcd[i], (unsigned long)j);
                a[i] = load(d, name, 1, m->n_m, &ok);
            }
            z->a11 = (double *)jf_alloc(inst, 4 * m->n_m, sizeof(double));
            if (ok && z->a11 != NULL)
                for (i = 0; i < 4; i++) memcpy(z->a11 + i * m->n_m, a[i], m->n_m * sizeof(double));
            else
                ok = 0;
            for (i = 0; i < 4; i++) free(a[i]);
#define PRE(field, rows, cols)                                     \
    sprintf(name, #field "_%lu", (unsigned long)j);                \
    z->field = load(d, name, rows, cols, &ok);
            PRE(G1, m->n_m, m->n_in)
            PRE(G2, m->n_m, m->n_in)
            PRE(Phi_o, 2 * m->n_r, 2 * m->n_r)
            PRE(G_o, 2 * m->n_r, m->n_in)
            if (m->n_f) {
                PRE(F_x, m->n_f, m->n)
                PRE(F_u, m->n_f, m->n_in)
            }
#undef PRE
        }
    }
    m->u_vr = load_vrs(inst, d, "u_vr", m->n_in, &ok);
    m->y_vr = load_vrs(inst, d, "y_vr", m->n_out, &ok);
    jf_data_close(d);
    if (!ok) return JF_ERROR;
    for (i = 0; i < m->n_out * m->n_in; i++)
        if (m->D[i] != 0.0) m->has_ft = 1;
    m->u = (double *)jf_alloc(inst, m->n_in, sizeof(double));
    m->y_state = (double *)jf_alloc(inst, m->n_out, sizeof(double));
    m->tq = (double *)jf_alloc(inst, 2 * m->n_m, sizeof(double));
    m->to = (double *)jf_alloc(inst, 2 * m->n_r, sizeof(double));
    m->tf = (double *)jf_alloc(inst, m->n_f, sizeof(double));
    m->gq = (double *)jf_alloc(inst, 2 * m->n_m + 1, sizeof(double));
    m->rs = (double *)jf_alloc(inst, m->n_out + 2 * m->n_r + m->n_f + 1, sizeof(double));
    m->u_on = (size_t *)jf_alloc(inst, m->n_in + 1, sizeof(size_t));
    m->all_o = (size_t *)jf_alloc(inst, 2 * m->n_r + 1, sizeof(size_t));
    inst->n_state = m->n;
    inst->state = (double *)jf_alloc(inst, m->n, sizeof(double));
    if (!m->u || !m->y_state || !m->tq || !m->to || !m->tf || !m->gq || !m->rs || !m->u_on ||
        !m->all_o || !inst->state)
        return JF_ERROR;
    m->gv = m->gq + m->n_m;
    for (i = 0; i < 2 * m->n_r; i++) m->all_o[i] = i;
    if (panels_build(inst, m->C_x, m->n_out, m->n, &m->c_cols) != JF_OK) return JF_ERROR;
    m->tv = m->tq + m->n_m;
    m->cur = NULL;
    return JF_OK;
}

static void zoh_free(Zoh *z) {
    free(z->a11);
    free(z->G1);
    free(z->G2);
    free(z->Phi_o);
    free(z->G_o);
    free(z->F_x);
    free(z->F_u);
    panels_free(&z->f_cols);
    memset(z, 0, sizeof *z);
}

void model_free(JfInstance *inst) {
    Structure *m = M;
    size_t j;
    if (m == NULL) return;
    for (j = 0; m->pre != NULL && j < m->n_steps; j++) zoh_free(&m->pre[j]);
    for (j = 0; j < CACHE; j++) zoh_free(&m->cache[j]);
    free(m->pre);
    free(m->steps);
    free(m->omega);
    free(m->cdamp);
    free(m->B_e);
    free(m->K_oo);
    free(m->D_oo);
    free(m->B_o);
    free(m->C_x);
    free(m->D);
    free(m->A_full);
    free(m->B_full);
    free(m->u_vr);
    free(m->y_vr);
    free(m->u);
    free(m->y_state);
    free(m->tq);
    free(m->to);
    free(m->tf);
    free(m->gq);
    free(m->rs);
    free(m->u_on);
    free(m->all_o);
    panels_free(&m->c_cols);
    free(m);
    inst->model = NULL;
}

/* Exact ZOH of every mode, of the Ritz block and of the filter rows for step h, into the
 * views m->a11 ... (the buffers of a cache slot). */
static int discretize(JfInstance *inst, double h) {
    Structure *m = M;
    size_t i, j, k, nr = m->n_r, n3 = 3 * nr, nin = m->n_in;
    double g1, g2, E[9], Aug[9];
    for (i = 0; i < m->n_m; i++) {
        double w = m->omega[i], cc = m->cdamp[i];
        if (w == 0.0) {
            double x = cc * h, em, gg;
            em = cc > 0 ? -jm_expm1(-x) / cc : h;
            gg = cc > 0 ? (h - em) / cc : h * h / 2;
            m->a11[i] = 1.0;
            m->a12[i] = em;
            m->a21[i] = 0.0;
            m->a22[i] = jm_exp(-x);
            g1 = gg;
            g2 = em;
        } else if (cc < 2 * w && w * h >= 1e-2) {
            double s = cc / 2, wd = sqrt(w * w - s * s), e = jm_exp(-s * h);
            double co = jm_cos(wd * h), si = jm_sin(wd * h);
            m->a11[i] = e * (co + s / wd * si);
            m->a12[i] = e * si / wd;
            m->a21[i] = -(w * w) * e * si / wd;
            m->a22[i] = e * (co - s / wd * si);
            g1 = (1.0 - m->a11[i]) / (w * w);
            g2 = m->a12[i];
        } else {
            memset(Aug, 0, sizeof Aug);
            Aug[1] = h;
            Aug[3] = -(w * w) * h;
            Aug[4] = -cc * h;
            Aug[5] = h;
            if (jf_expm(Aug, 3, E) != JF_OK) return JF_ERROR;
            m->a11[i] = E[0];
            m->a12[i] = E[1];
            m->a21[i] = E[3];
            m->a22[i] = E[4];
            g1 = E[2];
            g2 = E[5];
        }
        for (j = 0; j < nin; j++) {
            m->G1[i * nin + j] = g1 * m->B_e[i * nin + j];
            m->G2[i * nin + j] = g2 * m->B_e[i * nin + j];
        }
    }
    if (nr) {
        double *A = (double *)calloc(2 * n3 * n3, sizeof(double)), *X;
        if (A == NULL) return JF_ERROR;
        X = A + n3 * n3;
        for (i = 0; i < nr; i++) {
            A[i * n3 + nr + i] = h;
            A[(nr + i) * n3 + 2 * nr + i] = h;
            for (j = 0; j < nr; j++) {
                A[(nr + i) * n3 + j] = -m->K_oo[i * nr + j] * h;
                A[(nr + i) * n3 + nr + j] = -m->D_oo[i * nr + j] * h;
            }
        }
        if (jf_expm_balanced(A, n3, X) != JF_OK) {
            free(A);
            return JF_ERROR;
        }
        for (i = 0; i < 2 * nr; i++) {
            for (j = 0; j < 2 * nr; j++) m->Phi_o[i * 2 * nr + j] = X[i * n3 + j];
            for (j = 0; j < nin; j++) {
                double s = 0.0;
                for (k = 0; k < nr; k++) s += X[i * n3 + 2 * nr + k] * m->B_o[k * nin + j];
                m->G_o[i * nin + j] = s;
            }
        }
        free(A);
    }
    if (m->n_f) {
        size_t n = m->n, na = n + nin;
        double *A = (double *)calloc(2 * na * na, sizeof(double)), *X;
        if (A == NULL) return JF_ERROR;
        X = A + na * na;
        for (i = 0; i < n; i++) {
            for (j = 0; j < n; j++) A[i * na + j] = m->A_full[i * n + j] * h;
            for (j = 0; j < nin; j++) A[i * na + n + j] = m->B_full[i * nin + j] * h;
        }
        if (jf_expm_balanced(A, na, X) != JF_OK) {
            free(A);
            return JF_ERROR;
        }
        for (i = 0; i < m->n_f; i++) {
            for (j = 0; j < n; j++) m->F_x[i * n + j] = X[(m->ns + i) * na + j];
            for (j = 0; j < nin; j++) m->F_u[i * nin + j] = X[(m->ns + i) * na + n + j];
        }
        free(A);
    }
    return JF_OK;
}

static void use(Structure *m, const Zoh *z) {
    m->cur = z;
    m->a11 = z->a11;
    m->a12 = z->a11 + m->n_m;
    m->a21 = z->a11 + 2 * m->n_m;
    m->a22 = z->a11 + 3 * m->n_m;
    m->G1 = z->G1;
    m->G2 = z->G2;
    m->Phi_o = z->Phi_o;
    m->G_o = z->G_o;
    m->F_x = z->F_x;
    m->F_u = z->F_u;
    m->f_cols = &z->f_cols;
}

/* Use the discretisation z, its filter panels built on its first use. */
static int ready(JfInstance *inst, Zoh *z) {
    Structure *m = M;
    if (m->n_f && z->f_cols.start == NULL &&
        panels_build(inst, z->F_x, m->n_f, m->n, &z->f_cols) != JF_OK)
        return JF_ERROR;
    use(m, z);
    return JF_OK;
}

/* Make the discretisation for step h the one in use: a declared or cached step that h is
 * up to rounding (jf_same_step), else a new one in the next cache slot. */
static int select_step(JfInstance *inst, double h) {
    Structure *m = M;
    Zoh *z;
    size_t j, nm = m->n_m, nr = m->n_r, nin = m->n_in;
    for (j = 0; j < m->n_steps; j++)
        if (jf_same_step(h, m->pre[j].h, 0.0)) return ready(inst, &m->pre[j]);
    for (j = 0; j < m->n_cached; j++)
        if (jf_same_step(h, m->cache[j].h, 0.0)) return ready(inst, &m->cache[j]);
    z = &m->cache[m->next_slot];
    zoh_free(z);
    z->a11 = (double *)jf_alloc(inst, 4 * nm + 1, sizeof(double));
    z->G1 = (double *)jf_alloc(inst, nm * nin + 1, sizeof(double));
    z->G2 = (double *)jf_alloc(inst, nm * nin + 1, sizeof(double));
    z->Phi_o = (double *)jf_alloc(inst, 4 * nr * nr + 1, sizeof(double));
    z->G_o = (double *)jf_alloc(inst, 2 * nr * nin + 1, sizeof(double));
    z->F_x = (double *)jf_alloc(inst, m->n_f * m->n + 1, sizeof(double));
    z->F_u = (double *)jf_alloc(inst, m->n_f * nin + 1, sizeof(double));
    if (!z->a11 || !z->G1 || !z->G2 || !z->Phi_o || !z->G_o || !z->F_x || !z->F_u) {
        zoh_free(z);
        m->cur = NULL;
        return JF_ERROR;
    }
    z->h = h;
    use(m, z);
    if (discretize(inst, h) != JF_OK) {
        zoh_free(z);
        m->cur = NULL;
        return JF_ERROR;
    }
    if (m->next_slot == m->n_cached) m->n_cached++;
    m->next_slot = (m->next_slot + 1) % CACHE;
    return ready(inst, z);
}



/* The inputs, and which of them are not zero: a zero input adds only zeros to the input
 * products (see panels_build), which read the others alone. */
static void read_inputs(JfInstance *inst) {
    Structure *m = M;
    size_t j;
    m->n_on = 0;
    for (j = 0; j < m->n_in; j++) {
        m->u[j] = inst->r[m->u_vr[j]];
        if (m->u[j] != 0.0) m->u_on[m->n_on++] = j;
    }
}

static void update_state_outputs(JfInstance *inst) {
    Structure *m = M;
    panel_dot(m->C_x, m->n, m->n_out, &m->c_cols, inst->state, m->y_state);
}

static void write_outputs(JfInstance *inst) {
    Structure *m = M;
    size_t i;
    read_inputs(inst);
    if (m->has_ft) rows_dot(m->D, m->n_in, m->n_out, m->u_on, m->n_on, m->u, m->rs);
    for (i = 0; i < m->n_out; i++) {
        double s = m->y_state[i];
        if (m->has_ft) s = m->rs[i] + s;
        inst->r[m->y_vr[i]] = s;
    }
}

int model_exit_initialization(JfInstance *inst) {
    update_state_outputs(inst);
    write_outputs(inst);
    return JF_OK;
}

int model_inputs_changed(JfInstance *inst) {
    if (M->has_ft) write_outputs(inst);
    return JF_OK;
}

int model_state_restored(JfInstance *inst) {
    update_state_outputs(inst);
    return JF_OK;
}

int model_do_step(JfInstance *inst, double t, double h) {
    Structure *m = M;
    size_t i, nm = m->n_m, nr = m->n_r, nin = m->n_in;
    double *x = inst->state, *q = x, *v = x + nm, *xo = x + 2 * nm;
    (void)t;
    if ((m->cur == NULL || h != m->cur->h) && select_step(inst, h) != JF_OK) {
        jf_log(inst, 3, "cannot discretise the structure for step %g s", h);
        return JF_ERROR;
    }
    read_inputs(inst);
    if (m->n_f) { /* the filter reads the state before the step */
        double *f = m->rs;
        panel_dot(m->F_x, m->n, m->n_f, m->f_cols, x, m->tf);
        rows_dot(m->F_u, nin, m->n_f, m->u_on, m->n_on, m->u, f);
        for (i = 0; i < m->n_f; i++) m->tf[i] = m->tf[i] + f[i];
    }
    rows_dot(m->G1, nin, nm, m->u_on, m->n_on, m->u, m->gq);
    rows_dot(m->G2, nin, nm, m->u_on, m->n_on, m->u, m->gv);
    for (i = 0; i < nm; i++) {
        m->tq[i] = m->gq[i] + m->a11[i] * q[i] + m->a12[i] * v[i];
        m->tv[i] = m->gv[i] + m->a21[i] * q[i] + m->a22[i] * v[i];
    }
    if (nr) {
        double *f = m->rs;
        rows_dot(m->Phi_o, 2 * nr, 2 * nr, m->all_o, 2 * nr, xo, m->to);
        rows_dot(m->G_o, nin, 2 * nr, m->u_on, m->n_on, m->u, f);
        for (i = 0; i < 2 * nr; i++) m->to[i] = m->to[i] + f[i];
    }
    memcpy(q, m->tq, 2 * nm * sizeof(double)); /* q and v are contiguous */
    memcpy(xo, m->to, 2 * nr * sizeof(double));
    memcpy(x + m->ns, m->tf, m->n_f * sizeof(double));
    update_state_outputs(inst);
    write_outputs(inst);
    return JF_OK;
}
