/* ACS kernel: three-axis PID attitude control with reaction wheels (acsfmu.pid).
 *
 * Gains from acsfmu.design.pid_gains_for (closed form: crossover at `bandwidth`,
 * phase margin plus 1.5 w_c T of sampling lag, integral zero a factor 5 below
 * crossover).  Samples at n T whatever the communication step; a torque computed at a
 * sample is applied one sample later; wheel momentum integrated exactly; torque and
 * momentum limits; conditional-integration anti-windup.
 * State (AcsState.as_array): [integral (3), torque_active (3), torque_pending (3),
 * momentum (3), next_sample, activated, time].
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "jfmu.h"

#define PI 3.141592653589793
#define INTEGRAL_RATIO 5.0

typedef struct {
    long inertia[3], bandwidth, phase_margin, sample_time, torque_limit, momentum_limit,
        wheel_inertia, momentum0[3], anti_windup, attitude[3], rate[3], torque[3], speed[3];
    double kp[3], ki[3], kd[3], T, tl, hmax, jw;
    int aw;
} Acs;

#define A_ ((Acs *)inst->model)

int model_instantiate(JfInstance *inst) {
    static const char *axes[3] = {"x", "y", "z"}, *att[3] = {"roll", "pitch", "yaw"},
                      *tq[3] = {"Tx", "Ty", "Tz"};
    char name[40];
    Acs *a = (Acs *)jf_alloc(inst, 1, sizeof(Acs));
    int i, bad = 0;
    inst->model = a;
    if (a == NULL) return JF_ERROR;
    for (i = 0; i < 3; i++) {
        sprintf(name, "inertia_%s", axes[i]);
        bad |= (a->inertia[i] = jf_vr(inst, name, JF_REAL)) < 0;
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
    if (bad) return JF_ERROR;
    inst->n_state = 15;
    inst->state = (double *)jf_alloc(inst, 15, sizeof(double));
    return inst->state ? JF_OK : JF_ERROR;
}

void model_free(JfInstance *inst) {
    free(inst->model);
    inst->model = NULL;
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
    wc = 2 * PI * bw;
    deg = r[a->phase_margin] * (180.0 / PI); /* math.degrees, then math.radians */
    phi = deg * (PI / 180.0) + 1.5 * wc * T;
    for (i = 0; i < 3; i++) {
        double j = r[a->inertia[i]], ti, td;
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
        a->kp[i] = j * (wc * wc) * cos(phi);
        ti = INTEGRAL_RATIO / wc;
        td = (tan(phi) + 1.0 / INTEGRAL_RATIO) / wc;
        a->ki[i] = a->kp[i] / ti;
        a->kd[i] = a->kp[i] * td;
    }
    return JF_OK;
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
    for (i = 0; i < 15; i++) x[i] = 0.0;
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

/* acsfmu.pid.pid_command for one axis; returns the torque, updates *z. */
static double pid_axis(const Acs *a, int i, double *z, double e, double rate, double h_next) {
    double v = -(a->kp[i] * e + a->kd[i] * rate + a->ki[i] * *z);
    double lo = (h_next - a->hmax) / a->T, hi = (h_next + a->hmax) / a->T, u, dv;
    u = v > lo ? v : lo;
    u = u < hi ? u : hi;
    u = u > -a->tl ? u : -a->tl;
    u = u < a->tl ? u : a->tl;
    dv = -a->ki[i] * a->T * e;
    if (!(u != v && sign(dv) == sign(v - u) && a->aw)) *z = *z + a->T * e;
    return u;
}

/* acsfmu.pid.acs_advance from t to t + h with the inputs held. */
int model_do_step(JfInstance *inst, double t, double h) {
    Acs *a = A_;
    double *x = inst->state, *z = x, *u_act = x + 3, *u_pend = x + 6, *hw = x + 9;
    double T = a->T, tol = 1e-6 * T, t_end = t + h, cur = t, n = x[12], activated = x[13];
    double att[3], rate[3];
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
        for (i = 0; i < 3; i++)
            u_pend[i] = pid_axis(a, i, &z[i], att[i] - 0.0, rate[i], hw[i] - u_act[i] * T);
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
