/* ACS kernel: three-axis PID attitude control with reaction wheels (acsfmu.pid).
 *
 * Gains from acsfmu.design.pid_gains_for (closed form: crossover at `bandwidth`,
 * phase margin plus 1.5 w_c T of sampling lag, integral zero a factor 5 below
 * crossover).  Samples at n T whatever the communication step; a torque computed at a
 * sample is applied one sample later; wheel momentum integrated exactly; torque and
 * momentum limits; conditional-integration anti-windup.
 * Filters (acsfmu.filters): per axis a notch then a low-pass on the commanded torque,
 * and an anti-alias low-pass on the six inputs; biquads by Tustin prewarped at their
 * corner (same formulas, same order as the Python twin), direct form II transposed,
 * frequency 0 = off (the signal passes unchanged, the states stay 0).
 * State (AcsState.as_array): [integral (3), torque_active (3), torque_pending (3),
 * momentum (3), next_sample, activated, time, antialias (6 x 2), notch (3 x 2),
 * lowpass (3 x 2)].
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "jfmu.h"

#define PI 3.141592653589793
#define INTEGRAL_RATIO 5.0
#define N_STATE 39
#define S_AA 15    /* offsets of the filter states in the state vector */
#define S_NOTCH 27
#define S_LOW 33

/* Per-axis filter parameters, in the order they are checked (as acsfmu.filters). */
static const char *const FILTER_NAMES[5] = {"notch_hz", "notch_zeta_num", "notch_zeta_den",
                                            "lowpass_hz", "lowpass_zeta"};

typedef struct {
    long inertia[3], bandwidth, bandwidth_axis[3], phase_margin, sample_time, torque_limit,
        momentum_limit, wheel_inertia, momentum0[3], anti_windup, attitude[3], rate[3],
        torque[3], speed[3], filter[5][3], antialias_hz, antialias_zeta;
    double kp[3], ki[3], kd[3], T, tl, hmax, jw;
    double notch[3][5], low[3][5], aa[5]; /* [b0, b1, b2, a1, a2] */
    int aw, notch_on[3], low_on[3], aa_on;
} Acs;

#define A_ ((Acs *)inst->model)

int model_instantiate(JfInstance *inst) {
    static const char *axes[3] = {"x", "y", "z"}, *att[3] = {"roll", "pitch", "yaw"},
                      *tq[3] = {"Tx", "Ty", "Tz"};
    char name[40];
    Acs *a = (Acs *)jf_alloc(inst, 1, sizeof(Acs));
    int i, k, bad = 0;
    inst->model = a;
    if (a == NULL) return JF_ERROR;
    for (i = 0; i < 3; i++) {
        sprintf(name, "inertia_%s", axes[i]);
        bad |= (a->inertia[i] = jf_vr(inst, name, JF_REAL)) < 0;
        sprintf(name, "bandwidth_%s", axes[i]);
        bad |= (a->bandwidth_axis[i] = jf_vr(inst, name, JF_REAL)) < 0;
        for (k = 0; k < 5; k++) {
            sprintf(name, "%s_%s", FILTER_NAMES[k], axes[i]);
            bad |= (a->filter[k][i] = jf_vr(inst, name, JF_REAL)) < 0;
        }
        sprintf(name, "momentum0_%s", axes[i]);
        bad |= (a->momentum0[i] = jf_vr(inst, name, JF_REAL)) < 0;
        bad |= (a->attitude[i] = jf_vr(inst, att[i], JF_REAL)) < 0;
        sprintf(name, "rate_%s", axes[i]);
        bad |= (a->rate[i] = jf_vr(inst, name, JF_REAL)) < 0;
        bad |= (a->torque[i] = jf_vr(inst, tq[i], JF_REAL)) < 0;
        sprintf(name, "wheel_speed_%s", axes[i]);
        bad |= (a->speed[i] = jf_vr(inst, name, JF_REAL)) < 0;
    }
    bad |= (a->bandwidth = jf_vr(inst, "bandwidth", JF_REAL)) < 0;
    bad |= (a->phase_margin = jf_vr(inst, "phase_margin", JF_REAL)) < 0;
    bad |= (a->sample_time = jf_vr(inst, "sample_time", JF_REAL)) < 0;
    bad |= (a->torque_limit = jf_vr(inst, "torque_limit", JF_REAL)) < 0;
    bad |= (a->momentum_limit = jf_vr(inst, "momentum_limit", JF_REAL)) < 0;
    bad |= (a->wheel_inertia = jf_vr(inst, "wheel_inertia", JF_REAL)) < 0;
    bad |= (a->anti_windup = jf_vr(inst, "anti_windup", JF_BOOLEAN)) < 0;
    bad |= (a->antialias_hz = jf_vr(inst, "antialias_hz", JF_REAL)) < 0;
    bad |= (a->antialias_zeta = jf_vr(inst, "antialias_zeta", JF_REAL)) < 0;
    if (bad) return JF_ERROR;
    inst->n_state = N_STATE;
    inst->state = (double *)jf_alloc(inst, N_STATE, sizeof(double));
    return inst->state ? JF_OK : JF_ERROR;
}

void model_free(JfInstance *inst) {
    free(inst->model);
    inst->model = NULL;
}

/* acsfmu.filters.prewarped_biquad: num = (n2, n1, n0), den = (d2, d1, d0) in s / w. */
static void prewarped_biquad(const double num[3], const double den[3], double f, double T,
                             double c_out[5]) {
    double w = 2.0 * PI * f, c = 1.0 / jm_tan(0.5 * w * T), c2 = c * c;
    double a0 = den[0] * c2 + den[1] * c + den[2];
    c_out[0] = (num[0] * c2 + num[1] * c + num[2]) / a0;
    c_out[1] = 2.0 * (num[2] - num[0] * c2) / a0;
    c_out[2] = (num[0] * c2 - num[1] * c + num[2]) / a0;
    c_out[3] = 2.0 * (den[2] - den[0] * c2) / a0;
    c_out[4] = (den[0] * c2 - den[1] * c + den[2]) / a0;
}

static void lowpass_biquad(double f, double zeta, double T, double c_out[5]) {
    const double num[3] = {0.0, 0.0, 1.0};
    double den[3];
    den[0] = 1.0;
    den[1] = 2.0 * zeta;
    den[2] = 1.0;
    prewarped_biquad(num, den, f, T, c_out);
}

/* The refusals of acsfmu.filters, same sentences: 0 if the value is fine. */
static int bad_corner(JfInstance *inst, const char *name, double f, double T) {
    double nyq = 0.5 / T;
    if (isfinite(f) && 0.0 <= f && f < nyq) return 0;
    if (f < 0)
        jf_log(inst, 3, "ACS instance '%s': ACS filters: %s = %g Hz is negative; expected 0 "
               "(off) or a corner below the Nyquist frequency %g Hz", inst->instance_name,
               name, f, nyq);
    else if (isnan(f))
        jf_log(inst, 3, "ACS instance '%s': ACS filters: %s = %g Hz is not a frequency; "
               "expected one below the Nyquist frequency %g Hz", inst->instance_name, name,
               f, nyq);
    else
        jf_log(inst, 3, "ACS instance '%s': ACS filters: %s = %g Hz is at or above the "
               "Nyquist frequency %g Hz of sample time %g s", inst->instance_name, name, f,
               nyq, T);
    return 1;
}

static int bad_damping(JfInstance *inst, const char *name, double zeta, double T) {
    if (isfinite(zeta) && zeta > 0) return 0;
    jf_log(inst, 3, "ACS instance '%s': ACS filters: %s = %g is not a positive damping ratio "
           "(filters sampled below the Nyquist frequency %g Hz)", inst->instance_name, name,
           zeta, 0.5 / T);
    return 1;
}

/* acsfmu.filters.AcsFilters: checks in its order, then the coefficients. */
static int configure_filters(JfInstance *inst) {
    static const char *axes[3] = {"x", "y", "z"};
    static const double identity[5] = {1.0, 0.0, 0.0, 0.0, 0.0};
    Acs *a = A_;
    const double *r = inst->r;
    double T = a->T, v[5];
    char name[40];
    int i, k;
    for (i = 0; i < 3; i++) {
        for (k = 0; k < 5; k++) {
            v[k] = r[a->filter[k][i]];
            sprintf(name, "%s_%s", FILTER_NAMES[k], axes[i]);
            if (k == 0 || k == 3 ? bad_corner(inst, name, v[k], T)
                                 : bad_damping(inst, name, v[k], T))
                return JF_ERROR;
        }
    }
    if (bad_corner(inst, "antialias_hz", r[a->antialias_hz], T) ||
        bad_damping(inst, "antialias_zeta", r[a->antialias_zeta], T))
        return JF_ERROR;
    for (i = 0; i < 3; i++) {
        double hz = r[a->filter[0][i]], zn = r[a->filter[1][i]], zd = r[a->filter[2][i]];
        double lp = r[a->filter[3][i]], zl = r[a->filter[4][i]];
        a->notch_on[i] = hz > 0;
        a->low_on[i] = lp > 0;
        if (a->notch_on[i]) {
            double num[3], den[3];
            num[0] = 1.0;
            num[1] = 2.0 * zn;
            num[2] = 1.0;
            den[0] = 1.0;
            den[1] = 2.0 * zd;
            den[2] = 1.0;
            prewarped_biquad(num, den, hz, T, a->notch[i]);
        } else {
            for (k = 0; k < 5; k++) a->notch[i][k] = identity[k];
        }
        if (a->low_on[i])
            lowpass_biquad(lp, zl, T, a->low[i]);
        else
            for (k = 0; k < 5; k++) a->low[i][k] = identity[k];
    }
    a->aa_on = r[a->antialias_hz] > 0;
    if (a->aa_on)
        lowpass_biquad(r[a->antialias_hz], r[a->antialias_zeta], T, a->aa);
    else
        for (k = 0; k < 5; k++) a->aa[k] = identity[k];
    return JF_OK;
}

/* acsfmu.filters.biquad_step for one filter: direct form II transposed. */
static double biquad(const double c[5], int on, double x, double *s) {
    double y;
    if (!on) return x;
    y = c[0] * x + s[0];
    s[0] = c[1] * x - c[3] * y + s[1];
    s[1] = c[2] * x - c[4] * y;
    return y;
}

/* acsfmu.design.pid_gains_for and the AcsConfig checks. */
static int configure(JfInstance *inst) {
    Acs *a = A_;
    const double *r = inst->r;
    double bw = r[a->bandwidth], T = r[a->sample_time], wc, phi, deg;
    int i;
    a->T = T;
    a->tl = r[a->torque_limit];
    a->hmax = r[a->momentum_limit];
    a->jw = r[a->wheel_inertia];
    a->aw = inst->bv[a->anti_windup] != 0;
    if (!(isfinite(T) && T > 0) || !(isfinite(a->tl) && a->tl > 0) ||
        !(isfinite(a->hmax) && a->hmax > 0) || !(isfinite(a->jw) && a->jw > 0)) {
        jf_log(inst, 3, "ACS instance %s: sample_time, torque_limit, momentum_limit and "
               "wheel_inertia must be positive", inst->instance_name);
        return JF_ERROR;
    }
    deg = r[a->phase_margin] * (180.0 / PI); /* math.degrees, then math.radians */
    for (i = 0; i < 3; i++) {
        double j = r[a->inertia[i]], ti, td;
        bw = r[a->bandwidth_axis[i]] != 0 ? r[a->bandwidth_axis[i]] : r[a->bandwidth];
        wc = 2 * PI * bw;
        phi = deg * (PI / 180.0) + 1.5 * wc * T;
        if (!(isfinite(j) && j > 0) || !(isfinite(bw) && bw > 0)) {
            jf_log(inst, 3, "ACS instance %s: PID design: inertia and bandwidth must be "
                   "positive", inst->instance_name);
            return JF_ERROR;
        }
        if (wc * T > 0.5) {
            jf_log(inst, 3, "ACS instance %s: PID design: bandwidth %g Hz is too high for "
                   "sample time %g s; expected w_c T <= 0.5", inst->instance_name, bw, T);
            return JF_ERROR;
        }
        if (!(0 < phi && phi < 85.0 * (PI / 180.0))) {
            jf_log(inst, 3, "ACS instance %s: PID design: phase margin plus the sampling lag "
                   "must be within (0, 85) deg", inst->instance_name);
            return JF_ERROR;
        }
        a->kp[i] = j * (wc * wc) * jm_cos(phi);
        ti = INTEGRAL_RATIO / wc;
        td = (jm_tan(phi) + 1.0 / INTEGRAL_RATIO) / wc;
        a->ki[i] = a->kp[i] / ti;
        a->kd[i] = a->kp[i] * td;
    }
    return configure_filters(inst);
}

static void write_outputs(JfInstance *inst) {
    Acs *a = A_;
    int i;
    for (i = 0; i < 3; i++) {
        inst->r[a->torque[i]] = inst->state[3 + i];
        inst->r[a->speed[i]] = inst->state[9 + i] / a->jw;
    }
}

int model_exit_initialization(JfInstance *inst) {
    Acs *a = A_;
    double n0, *x = inst->state;
    int i;
    if (configure(inst) != JF_OK) return JF_ERROR;
    n0 = ceil(inst->start_time / a->T - 1e-6);
    for (i = 0; i < N_STATE; i++) x[i] = 0.0;
    for (i = 0; i < 3; i++) x[9 + i] = inst->r[a->momentum0[i]];
    x[12] = n0;
    x[13] = n0 - 1;
    x[14] = inst->start_time;
    write_outputs(inst);
    return JF_OK;
}

int model_inputs_changed(JfInstance *inst) {
    (void)inst;
    return JF_OK;
}

int model_state_restored(JfInstance *inst) {
    if (inst->phase == JF_STEPPING) return configure(inst);
    return JF_OK;
}

static double sign(double x) { return x > 0 ? 1.0 : (x < 0 ? -1.0 : 0.0); }

/* acsfmu.pid.pid_command for one axis, inputs already filtered: returns the torque,
 * updates *z and the axis's notch and low-pass states. */
static double pid_axis(const Acs *a, int i, double *z, double e, double rate, double h_next,
                       double *s_notch, double *s_low) {
    double v = -(a->kp[i] * e + a->kd[i] * rate + a->ki[i] * *z);
    double lo = (h_next - a->hmax) / a->T, hi = (h_next + a->hmax) / a->T, u, dv, w;
    w = biquad(a->low[i], a->low_on[i], biquad(a->notch[i], a->notch_on[i], v, s_notch),
               s_low);
    u = w > lo ? w : lo;
    u = u < hi ? u : hi;
    u = u > -a->tl ? u : -a->tl;
    u = u < a->tl ? u : a->tl;
    dv = -a->ki[i] * a->T * e;
    if (!(u != w && sign(dv) == sign(w - u) && a->aw)) *z = *z + a->T * e;
    return u;
}

/* acsfmu.pid.acs_advance from t to t + h with the inputs held. */
int model_do_step(JfInstance *inst, double t, double h) {
    Acs *a = A_;
    double *x = inst->state, *z = x, *u_act = x + 3, *u_pend = x + 6, *hw = x + 9;
    double T = a->T, tol = 1e-6 * T, t_end = t + h, cur = t, n = x[12], activated = x[13];
    double att[3], rate[3], att_f[3], rate_f[3];
    int i;
    for (i = 0; i < 3; i++) {
        att[i] = inst->r[a->attitude[i]];
        rate[i] = inst->r[a->rate[i]];
    }
    if (n * T < t - tol) n = ceil(t / T - 1e-6); /* a step started after a missed sample */
    while (n * T < t_end - tol) {
        double tau = n * T > cur ? n * T : cur;
        for (i = 0; i < 3; i++) hw[i] -= u_act[i] * (tau - cur);
        cur = tau;
        if (activated < n) {
            for (i = 0; i < 3; i++) u_act[i] = u_pend[i];
            activated = n;
        }
        for (i = 0; i < 3; i++) { /* the six samples through the anti-alias filters */
            att_f[i] = biquad(a->aa, a->aa_on, att[i], x + S_AA + 2 * i);
            rate_f[i] = biquad(a->aa, a->aa_on, rate[i], x + S_AA + 2 * (3 + i));
        }
        for (i = 0; i < 3; i++)
            u_pend[i] = pid_axis(a, i, &z[i], att_f[i] - 0.0, rate_f[i],
                                 hw[i] - u_act[i] * T, x + S_NOTCH + 2 * i, x + S_LOW + 2 * i);
        n += 1;
    }
    for (i = 0; i < 3; i++) hw[i] -= u_act[i] * (t_end - cur);
    if (fabs(t_end - n * T) <= tol && activated < n) {
        for (i = 0; i < 3; i++) u_act[i] = u_pend[i];
        activated = n;
    }
    x[12] = n;
    x[13] = activated;
    x[14] = t_end;
    write_outputs(inst);
    return JF_OK;
}
