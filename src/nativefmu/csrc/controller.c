/* Controller kernel: the discrete law of Eq. (11) (ctrlfmu.law and ctrlfmu.slave).
 *
 *   v = C x + D y,  u = clip(v, u_min, u_max),  x+ = A x + B y + L (u - v)
 *
 * gain scales C and D (L divided by it), t_on and enable gate the law (zero command and
 * state while inactive), r is added to the command after the limits.  The law samples
 * on its own clock t_k = t_start + k dt, instants matched within JF_TIME_RTOL of dt and
 * t + h taken with jf_end_time (a host's rounding or drift never slips a sample).  Matrices come from resources/controller.dat.
 * State: [x (n), u (n_out), u_prev (n_out), k, t0, tau, ready].
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "jfmu.h"

#define TOL 1e-9 /* t_on / dt, as ctrlfmu.law.first_active_sample */
#define NO_LIMIT 1e30

typedef struct {
    size_t n, n_in, n_out;
    double *A, *B, *C, *D, *L, *Cg, *Dg, *Lg, *y, *v, *u, *x;
    double dt;
    int delayed;
    long k_first; /* first active sample */
    long gain, u_min, u_max, t_on, enable;
    long *y_vr, *r_vr, *u_vr;
} Law;

#define LAW ((Law *)inst->model)

static double *load(JfData *d, const char *name, size_t rows, size_t cols, int *ok) {
    double *p = jf_data_array(d, name, rows, cols);
    if (p == NULL) *ok = 0;
    return p;
}

static long *names(JfInstance *inst, const char *prefix, size_t n, int *ok) {
    long *out = (long *)jf_alloc(inst, n, sizeof(long));
    char name[32];
    size_t i;
    if (out == NULL) {
        *ok = 0;
        return NULL;
    }
    for (i = 0; i < n; i++) {
        sprintf(name, "%s%lu", prefix, (unsigned long)(i + 1));
        if ((out[i] = jf_vr(inst, name, JF_REAL)) < 0) *ok = 0;
    }
    return out;
}

int model_instantiate(JfInstance *inst) {
    Law *m;
    JfData *d = jf_data_open(inst, "controller.dat");
    double s[5];
    int ok = 1;
    if (d == NULL) return JF_ERROR;
    m = (Law *)jf_alloc(inst, 1, sizeof(Law));
    inst->model = m;
    if (m == NULL || jf_data_scalar(d, "n", &s[0]) || jf_data_scalar(d, "n_in", &s[1]) ||
        jf_data_scalar(d, "n_out", &s[2]) || jf_data_scalar(d, "dt", &s[3]) ||
        jf_data_scalar(d, "delayed", &s[4])) {
        jf_data_close(d);
        return JF_ERROR;
    }
    m->n = (size_t)s[0];
    m->n_in = (size_t)s[1];
    m->n_out = (size_t)s[2];
    m->dt = s[3];
    m->delayed = s[4] != 0.0;
    m->A = load(d, "A", m->n, m->n, &ok);
    m->B = load(d, "B", m->n, m->n_in, &ok);
    m->C = load(d, "C", m->n_out, m->n, &ok);
    m->D = load(d, "D", m->n_out, m->n_in, &ok);
    m->L = load(d, "aw_gain", m->n, m->n_out, &ok);
    jf_data_close(d);
    m->Cg = (double *)jf_alloc(inst, m->n_out * m->n, sizeof(double));
    m->Dg = (double *)jf_alloc(inst, m->n_out * m->n_in, sizeof(double));
    m->Lg = (double *)jf_alloc(inst, m->n * m->n_out, sizeof(double));
    m->y = (double *)jf_alloc(inst, m->n_in, sizeof(double));
    m->v = (double *)jf_alloc(inst, m->n_out, sizeof(double));
    m->u = (double *)jf_alloc(inst, m->n_out, sizeof(double));
    m->x = (double *)jf_alloc(inst, m->n, sizeof(double));
    m->y_vr = names(inst, "y", m->n_in, &ok);
    m->r_vr = names(inst, "r", m->n_out, &ok);
    m->u_vr = names(inst, "u", m->n_out, &ok);
    if ((m->gain = jf_vr(inst, "gain", JF_REAL)) < 0 ||
        (m->u_min = jf_vr(inst, "u_min", JF_REAL)) < 0 ||
        (m->u_max = jf_vr(inst, "u_max", JF_REAL)) < 0 ||
        (m->t_on = jf_vr(inst, "t_on", JF_REAL)) < 0 ||
        (m->enable = jf_vr(inst, "enable", JF_BOOLEAN)) < 0)
        ok = 0;
    if (!ok || !m->Cg || !m->Dg || !m->Lg || !m->y || !m->v || !m->u || !m->x) return JF_ERROR;
    inst->n_state = m->n + 2 * m->n_out + 4;
    inst->state = (double *)jf_alloc(inst, inst->n_state, sizeof(double));
    return inst->state ? JF_OK : JF_ERROR;
}

void model_free(JfInstance *inst) {
    Law *m = LAW;
    if (m == NULL) return;
    free(m->A);
    free(m->B);
    free(m->C);
    free(m->D);
    free(m->L);
    free(m->Cg);
    free(m->Dg);
    free(m->Lg);
    free(m->y);
    free(m->v);
    free(m->u);
    free(m->x);
    free(m->y_vr);
    free(m->r_vr);
    free(m->u_vr);
    free(m);
    inst->model = NULL;
}

/* State views. */
#define SX(inst) ((inst)->state)
#define SU(inst) ((inst)->state + LAW->n)
#define SUP(inst) ((inst)->state + LAW->n + LAW->n_out)
#define SK(inst) ((inst)->state[LAW->n + 2 * LAW->n_out])
#define ST0(inst) ((inst)->state[LAW->n + 2 * LAW->n_out + 1])
#define STAU(inst) ((inst)->state[LAW->n + 2 * LAW->n_out + 2])
#define SREADY(inst) ((inst)->state[LAW->n + 2 * LAW->n_out + 3])

/* ControllerSlave._apply_parameters: gain, limits and t_on relative to the start. */
static int apply_parameters(JfInstance *inst) {
    Law *m = LAW;
    double g = inst->r[m->gain], lo = inst->r[m->u_min], hi = inst->r[m->u_max];
    double t_on = inst->r[m->t_on], rel;
    size_t i;
    if (!(isfinite(g) && lo <= hi)) {
        jf_log(inst, 3, "controller %s has gain %g and limits [%g, %g] V; expected a finite "
               "gain and u_min <= u_max", inst->instance_name, g, lo, hi);
        return JF_ERROR;
    }
    if (!(isfinite(t_on) && t_on >= 0)) {
        jf_log(inst, 3, "parameter t_on of %s is %g; expected >= 0 s", inst->instance_name,
               t_on);
        return JF_ERROR;
    }
    for (i = 0; i < m->n_out * m->n; i++) m->Cg[i] = g * m->C[i];
    for (i = 0; i < m->n_out * m->n_in; i++) m->Dg[i] = g * m->D[i];
    for (i = 0; i < m->n * m->n_out; i++) m->Lg[i] = g != 0 ? m->L[i] / g : m->L[i];
    rel = t_on - ST0(inst);
    if (rel < 0.0) rel = 0.0;
    m->k_first = (long)ceil(rel / m->dt - TOL);
    if (m->k_first < 0) m->k_first = 0;
    return JF_OK;
}

static double clip(JfInstance *inst, double v) {
    double lo = inst->r[LAW->u_min], hi = inst->r[LAW->u_max];
    return v < lo ? lo : (v > hi ? hi : v);
}

/* Row i of (m v) summed left to right, as ctrlfmu.law._mv for short rows. */
static double mv_row(const double *m, const double *v, size_t i, size_t cols) {
    double s = 0.0;
    size_t j;
    for (j = 0; j < cols; j++) s += m[i * cols + j] * v[j];
    return s;
}

static void read_y(JfInstance *inst) {
    size_t j;
    for (j = 0; j < LAW->n_in; j++) LAW->y[j] = inst->r[LAW->y_vr[j]];
}

static int active(JfInstance *inst, double k) {
    return inst->bv[LAW->enable] && k >= (double)LAW->k_first;
}

/* ctrlfmu.law.output of the non-delayed form into m->u. */
static void law_output(JfInstance *inst) {
    Law *m = LAW;
    size_t i;
    read_y(inst);
    for (i = 0; i < m->n_out; i++)
        m->u[i] = active(inst, SK(inst))
                      ? clip(inst, mv_row(m->Cg, SX(inst), i, m->n) + mv_row(m->Dg, m->y, i,
                                                                             m->n_in))
                      : 0.0;
}

static void write_outputs(JfInstance *inst) {
    Law *m = LAW;
    double tau = STAU(inst), k = SK(inst);
    const double *u;
    size_t i;
    if (fabs((tau - ST0(inst)) / m->dt - k) <= JF_TIME_RTOL) {
        if (m->delayed) {
            u = SU(inst);
        } else {
            law_output(inst);
            u = m->u;
        }
    } else {
        u = m->delayed ? SUP(inst) : SU(inst);
    }
    for (i = 0; i < m->n_out; i++) inst->r[m->u_vr[i]] = u[i] + inst->r[m->r_vr[i]];
}

int model_exit_initialization(JfInstance *inst) {
    ST0(inst) = inst->start_time;
    STAU(inst) = inst->start_time;
    if (apply_parameters(inst) != JF_OK) return JF_ERROR;
    SREADY(inst) = 1.0;
    write_outputs(inst);
    return JF_OK;
}

int model_inputs_changed(JfInstance *inst) {
    if (SREADY(inst) != 0.0) write_outputs(inst);
    return JF_OK;
}

int model_state_restored(JfInstance *inst) {
    /* finite: checked with the state bytes */
    if (SK(inst) < 0 || SK(inst) != floor(SK(inst)) ||
        (SREADY(inst) != 0.0 && SREADY(inst) != 1.0)) {
        jf_log(inst, 3, "FMU state rejected: controller state is not a valid state");
        return JF_ERROR;
    }
    if (SREADY(inst) != 0.0) return apply_parameters(inst);
    return JF_OK;
}

/* One sample of ctrlfmu.law.step. */
static void sample(JfInstance *inst) {
    Law *m = LAW;
    double *x = SX(inst), *u = SU(inst);
    size_t i;
    if (!active(inst, SK(inst))) {
        for (i = 0; i < m->n; i++) x[i] = 0.0;
        for (i = 0; i < m->n_out; i++) u[i] = 0.0;
    } else {
        for (i = 0; i < m->n_out; i++) {
            m->v[i] = mv_row(m->Cg, x, i, m->n) + mv_row(m->Dg, m->y, i, m->n_in);
            m->u[i] = clip(inst, m->v[i]);
            m->v[i] = m->u[i] - m->v[i]; /* u - v */
        }
        for (i = 0; i < m->n; i++)
            m->x[i] = mv_row(m->A, x, i, m->n) + mv_row(m->B, m->y, i, m->n_in) +
                      mv_row(m->Lg, m->v, i, m->n_out);
        for (i = 0; i < m->n; i++) x[i] = m->x[i];
        for (i = 0; i < m->n_out; i++) u[i] = m->u[i];
    }
    SK(inst) += 1.0;
}

int model_do_step(JfInstance *inst, double t, double h) {
    Law *m = LAW;
    double tau = jf_end_time(t, h, STAU(inst));
    double k_end = ceil((tau - ST0(inst)) / m->dt - JF_TIME_RTOL);
    size_t i;
    if (k_end < 0) k_end = 0;
    if (SK(inst) < k_end) {
        read_y(inst);
        while (SK(inst) < k_end) {
            for (i = 0; i < m->n_out; i++) SUP(inst)[i] = SU(inst)[i];
            sample(inst);
        }
    }
    STAU(inst) = tau;
    write_outputs(inst);
    return JF_OK;
}
