/* Piezo kernel: stack + amplifier + Bouc-Wen + stroke limit + strain gauge.
 *
 * A line-by-line port of piezofmu.actuator / amplifier / hysteresis (same sub-stepping
 * rule, same order of the limits, same Taylor-series exponential for the second-order
 * amplifier, same SplitMix64 + Box-Muller gauge noise keyed by (seed, tick)), so that
 * the native and the Python FMU give the same numbers to round-off.
 * State: [v, dv/dt, sat_voltage, sat_slew, h_bw, tick, z] as ActuatorState.to_array.
 * With servo_bandwidth > 0 the stack's servo loop is closed on the elongation input: the
 * amplifier follows an integrator z, dz/dt = k_i (d0/V0 v_cmd - elongation), moved every
 * sub-step and clipped to the rails (piezofmu.amplifier.servo_path).
 * With coupling = 1 the force output is the trapezoidal mean of the force over the coming
 * step of hold_step with v_cmd held (piezofmu.actuator.step_mean), recomputed after every
 * set of an input and after every step; the step itself is the same computation.
 * Stack constants (c h, capacitance, d0/V0, V0) come from resources/piezo.dat.
 */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "jfmu.h"

#define PI 3.141592653589793
#define MULTIPLE_RTOL 1e-9

/* Parameters of one step, checked. */
typedef struct {
    double v_min, v_max, i_max, w, zeta, h_int, alpha, beta, gamma, stroke_limit, length,
        noise_std, resolution;
    int order, hyst;
    uint64_t seed;
    int coupling;
    double hold_step;
    int servo;
    double servo_ki;
} Params;

/* The sub-steps of an advance over dt and their map (amplifier._coefficients). */
typedef struct {
    long n;
    double hsub, a, a11, a12, a21, a22, b1, b2;
} Coef;

typedef struct {
    double ch, capacitance, stroke_per_volt, rated_voltage;
    long v_min, v_max, i_max, bandwidth, amp_order, damping, internal_step, hysteresis,
        bw_alpha, bw_beta_v0, bw_gamma_v0, stroke_limit, gauge_length, noise_std, resolution,
        seed, v_cmd, elongation, force, voltage, current, free_stroke, strain, sat_voltage,
        sat_slew, sat_stroke, coupling, hold_step, servo_bandwidth, servo_plant_gain;
    int ready;
    /* the coming step as write_force computed it: reused by the step when the state,
     * the command and the parameters are still those it started from */
    int ahead_ok;
    long ahead_n;
    Params ahead_q;
    double ahead_u, ahead_e, ahead_x0[7], ahead_x1[7];
    /* the sub-step map of the last advance, kept for the same (dt, h_int, w, zeta,
     * order): the same numbers give the same coefficients, so they are computed once */
    int coef_ok, coef_order;
    double coef_key[4];
    Coef coef;
} Piezo;



#define P ((Piezo *)inst->model)

int model_instantiate(JfInstance *inst) {
    Piezo *p;
    JfData *d = jf_data_open(inst, "piezo.dat");
    int bad;
    if (d == NULL) return JF_ERROR;
    p = (Piezo *)jf_alloc(inst, 1, sizeof(Piezo));
    inst->model = p;
    bad = p == NULL || jf_data_scalar(d, "ch", &p->ch) ||
          jf_data_scalar(d, "capacitance", &p->capacitance) ||
          jf_data_scalar(d, "stroke_per_volt", &p->stroke_per_volt) ||
          jf_data_scalar(d, "rated_voltage", &p->rated_voltage);
    jf_data_close(d);
    if (bad) return JF_ERROR;
#define R(name) (p->name = jf_vr(inst, #name, JF_REAL)) < 0
#define I(name, type) (p->name = jf_vr(inst, #name, type)) < 0
    if (R(v_min) || R(v_max) || R(i_max) || R(bandwidth) || I(amp_order, JF_INTEGER) ||
        R(damping) || R(internal_step) || I(hysteresis, JF_BOOLEAN) || R(bw_alpha) ||
        R(bw_beta_v0) || R(bw_gamma_v0) || R(stroke_limit) || R(gauge_length) ||
        R(noise_std) || R(resolution) || I(seed, JF_INTEGER) || R(v_cmd) || R(elongation) ||
        R(force) || R(voltage) || R(current) || R(free_stroke) || R(strain) ||
        R(sat_voltage) || R(sat_slew) || R(sat_stroke) || I(coupling, JF_INTEGER) ||
        R(hold_step) || R(servo_bandwidth) || R(servo_plant_gain))
        return JF_ERROR;
#undef R
#undef I
    inst->n_state = 7;
    inst->state = (double *)jf_alloc(inst, 7, sizeof(double));
    return inst->state ? JF_OK : JF_ERROR;
}

void model_free(JfInstance *inst) {
    free(inst->model);
    inst->model = NULL;
}

static int params(JfInstance *inst, Params *q) {
    Piezo *p = P;
    const double *r = inst->r;
    memset(q, 0, sizeof *q); /* padding too: parameter sets are compared with memcmp */
    q->v_min = r[p->v_min];
    q->v_max = r[p->v_max];
    q->i_max = r[p->i_max];
    q->w = 2.0 * PI * r[p->bandwidth];
    q->order = inst->iv[p->amp_order];
    q->zeta = r[p->damping];
    q->h_int = r[p->internal_step];
    q->hyst = inst->bv[p->hysteresis];
    q->alpha = r[p->bw_alpha];
    q->beta = r[p->bw_beta_v0] / p->rated_voltage;
    q->gamma = r[p->bw_gamma_v0] / p->rated_voltage;
    q->stroke_limit = r[p->stroke_limit] > 0 ? r[p->stroke_limit] : HUGE_VAL;
    q->length = r[p->gauge_length];
    q->noise_std = r[p->noise_std];
    q->resolution = r[p->resolution];
    q->seed = (uint64_t)(inst->iv[p->seed] < 0 ? 0 : inst->iv[p->seed]);
    q->coupling = inst->iv[p->coupling];
    q->hold_step = r[p->hold_step];
    if (!(r[p->servo_bandwidth] >= 0 && isfinite(r[p->servo_bandwidth])) ||
        !(r[p->servo_plant_gain] >= 0 && isfinite(r[p->servo_plant_gain]))) {
        jf_log(inst, 3, "parameters servo_bandwidth and servo_plant_gain of %s are %g and "
               "%g; expected >= 0 and finite (0 for no servo, 0 for d0/V0)",
               inst->instance_name, r[p->servo_bandwidth], r[p->servo_plant_gain]);
        return JF_ERROR;
    }
    q->servo = r[p->servo_bandwidth] > 0;
    if (q->servo) {
        /* as PiezoActuator.servo_gain */
        double g = r[p->servo_plant_gain] > 0 ? r[p->servo_plant_gain] : p->stroke_per_volt;
        q->servo_ki = 2.0 * PI * r[p->servo_bandwidth] / g;
    }
    if (q->coupling != 0 && q->coupling != 1) {
        jf_log(inst, 3, "parameter coupling of %s is %d; expected 1 (mean force over the "
               "step) or 0 (force at the end of the last step)", inst->instance_name,
               q->coupling);
        return JF_ERROR;
    }
    if (q->coupling == 1 && !(q->hold_step > 0 && isfinite(q->hold_step))) {
        jf_log(inst, 3, "parameter hold_step of %s is %g; expected the FMU's communication "
               "step (s)", inst->instance_name, q->hold_step);
        return JF_ERROR;
    }
    if (r[p->stroke_limit] < 0) {
        jf_log(inst, 3, "parameter stroke_limit of %s is %g; expected >= 0 (0 for no limit)",
               inst->instance_name, r[p->stroke_limit]);
        return JF_ERROR;
    }
    if (q->order != 1 && q->order != 2) {
        jf_log(inst, 3, "amplifier order must be 1 or 2, got %d", q->order);
        return JF_ERROR;
    }
    if (!(r[p->bandwidth] > 0 && isfinite(r[p->bandwidth])) || !(q->zeta > 0 && isfinite(q->zeta))
        || !(q->h_int > 0 && isfinite(q->h_int)) || !(q->i_max > 0) || !(q->v_min < q->v_max)) {
        jf_log(inst, 3, "amplifier parameters of %s are out of range: bandwidth, damping, "
               "internal_step and i_max must be positive, v_min below v_max",
               inst->instance_name);
        return JF_ERROR;
    }
    if (q->hyst && !(q->alpha > 0 && isfinite(q->alpha) && isfinite(q->beta) &&
                     isfinite(q->gamma) && q->beta > fabs(q->gamma))) {
        jf_log(inst, 3, "Bouc-Wen parameters need alpha > 0 and beta > |gamma|");
        return JF_ERROR;
    }
    if (!(q->length > 0 && isfinite(q->length)) || !(q->noise_std >= 0 && isfinite(q->noise_std))
        || !(q->resolution >= 0 && isfinite(q->resolution)) || inst->iv[p->seed] < 0) {
        jf_log(inst, 3, "strain gauge parameters of %s are out of range: gauge_length > 0, "
               "noise_std >= 0, resolution >= 0, seed >= 0", inst->instance_name);
        return JF_ERROR;
    }
    return JF_OK;
}

/* ------------------------------------------------------------------ amplifier */

static void substeps(double dt, double h, long *n, double *size) {
    double ratio = dt / h, k = nearbyint(ratio); /* round half to even, as Python */
    if (k >= 1 && fabs(ratio - k) <= MULTIPLE_RTOL * ratio) {
        *n = (long)k;
        *size = h;
        return;
    }
    k = ceil(ratio);
    *n = (long)k;
    *size = dt / k;
}

static void mat3(const double *a, const double *b, double *out) {
    int i, j, k;
    for (i = 0; i < 3; i++)
        for (j = 0; j < 3; j++) {
            double s = 0.0;
            for (k = 0; k < 3; k++) s += a[3 * i + k] * b[3 * k + j];
            out[3 * i + j] = s;
        }
}

/* piezofmu.amplifier._expm: scaling and squaring of a Taylor series. */
static void expm3(const double *a, double *out) {
    double norm = 0.0, x[9], term[9], t2[9];
    int i, k, squarings = 0;
    for (i = 0; i < 3; i++) {
        double row = fabs(a[3 * i]) + fabs(a[3 * i + 1]) + fabs(a[3 * i + 2]);
        if (row > norm) norm = row;
    }
    if (norm > 0.25) squarings = jm_ceil_log2(norm / 0.25);
    if (squarings < 0) squarings = 0;
    for (i = 0; i < 9; i++) {
        x[i] = a[i] / ldexp(1.0, squarings);
        term[i] = (i % 4 == 0) ? 1.0 : 0.0;
        out[i] = term[i];
    }
    for (k = 1; k < 19; k++) {
        mat3(term, x, t2);
        for (i = 0; i < 9; i++) {
            term[i] = t2[i] / k;
            out[i] = out[i] + term[i];
        }
    }
    for (k = 0; k < squarings; k++) {
        mat3(out, out, t2);
        for (i = 0; i < 9; i++) out[i] = t2[i];
    }
}

/* Bouc-Wen: exact advance over a monotone voltage increment (hysteresis.increment). */
static double segment(const Params *q, double h, double s, double w, double sigma) {
    double k = q->beta + s * sigma * q->gamma;
    double h_inf = s * q->alpha / k;
    return h_inf + (h - h_inf) * jm_exp(-k * w);
}

static double bw_increment(const Params *q, double h, double dv) {
    double s, w;
    if (dv == 0.0) return h;
    s = dv > 0 ? 1.0 : -1.0;
    w = fabs(dv);
    if (h * s < 0.0) {
        double sigma = -s, k = q->beta + s * sigma * q->gamma;
        double h_inf = s * q->alpha / k, w0 = jm_log1p(-h / h_inf) / k;
        if (w0 >= w) return segment(q, h, s, w, sigma);
        h = 0.0;
        w = w - w0;
    }
    return segment(q, h, s, w, s);
}

/* Force of an effective voltage after the stroke limit (actuator._force). */
static double stack_force(const Piezo *p, const Params *q, double v_eff) {
    double limit = q->stroke_limit / p->stroke_per_volt;
    if (v_eff > limit) v_eff = limit;
    if (v_eff < -limit) v_eff = -limit;
    return p->ch * v_eff;
}

static Coef coefficients(const Params *q, double dt) {
    Coef c = {0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    substeps(dt, q->h_int, &c.n, &c.hsub);
    if (q->order == 1) {
        c.a = jm_exp(-q->w * c.hsub);
    } else {
        /* as piezofmu.amplifier._coefficients: the scaled state (v, r / w) */
        double m[9], e[9], wh = q->w * c.hsub;
        m[0] = wh * 0.0;
        m[1] = wh * 1.0;
        m[2] = wh * 0.0;
        m[3] = wh * -1.0;
        m[4] = wh * (-2.0 * q->zeta);
        m[5] = wh * 1.0;
        m[6] = m[7] = m[8] = wh * 0.0;
        expm3(m, e);
        c.a11 = e[0];
        c.a12 = e[1] / q->w;
        c.a21 = e[3] * q->w;
        c.a22 = e[4];
        c.b1 = e[2];
        c.b2 = e[5] * q->w;
    }
    return c;
}

/* amplifier._advance on the state x, with the Bouc-Wen state driven along the sub-step
 * path; with mean != NULL also the trapezoidal mean force (actuator.step_mean).  With
 * the servo on, the command of each sub-step is the mean of the servo integrator x[6]
 * over it, the integrator driven by the expansion error (d0/V0 u - e).
 * Returns the number of sub-steps. */
static long advance(JfInstance *inst, const Params *q, double *x, double u, double e,
                    double dt, double *mean) {
    double v = x[0], r = x[1], h_bw = x[4], z = x[6], dz = 0.0, hsub, a = 0.0, f_prev = 0.0,
           total = 0.0;
    double a11 = 0, a12 = 0, a21 = 0, a22 = 0, b1 = 0, b2 = 0, s_max, dv_max;
    int sat_v = 0, sat_s = 0, any_v = 0, any_s = 0, first = q->order == 1;
    long n, i;
    Piezo *p = P;
    if (!(p->coef_ok && p->coef_order == q->order && p->coef_key[0] == dt &&
          p->coef_key[1] == q->h_int && p->coef_key[2] == q->w && p->coef_key[3] == q->zeta)) {
        p->coef = coefficients(q, dt);
        p->coef_ok = 1;
        p->coef_order = q->order;
        p->coef_key[0] = dt;
        p->coef_key[1] = q->h_int;
        p->coef_key[2] = q->w;
        p->coef_key[3] = q->zeta;
    }
    n = p->coef.n;
    hsub = p->coef.hsub;
    a = p->coef.a;
    a11 = p->coef.a11;
    a12 = p->coef.a12;
    a21 = p->coef.a21;
    a22 = p->coef.a22;
    b1 = p->coef.b1;
    b2 = p->coef.b2;
    s_max = q->i_max / P->capacitance;
    dv_max = s_max * hsub;
    if (q->servo) dz = hsub * (q->servo_ki * (P->stroke_per_volt * u - e));
    if (mean != NULL) f_prev = stack_force(P, q, v - h_bw);
    for (i = 0; i < n; i++) {
        double v_new, r_new = 0.0, dv;
        if (q->servo) {
            double z_new = z + dz;
            if (z_new < q->v_min) z_new = q->v_min;   /* anti-windup: held at the rails */
            if (z_new > q->v_max) z_new = q->v_max;
            u = 0.5 * (z + z_new);
            z = z_new;
        }
        if (first) {
            v_new = u + (v - u) * a;
        } else {
            v_new = a11 * v + a12 * r + b1 * u;
            r_new = a21 * v + a22 * r + b2 * u;
        }
        dv = v_new - v;
        sat_s = 0;
        if (dv > dv_max) {
            v_new = v + dv_max;
            sat_s = 1;
        } else if (dv < -dv_max) {
            v_new = v - dv_max;
            sat_s = 1;
        }
        if (first) r_new = q->w * (u - v_new);
        if (r_new > s_max) {
            r_new = s_max;
            sat_s = sat_s || !first;
        } else if (r_new < -s_max) {
            r_new = -s_max;
            sat_s = sat_s || !first;
        }
        sat_v = 0;
        if (v_new > q->v_max) {
            v_new = q->v_max;
            sat_v = 1;
            if (r_new > 0.0) r_new = 0.0;
        } else if (v_new < q->v_min) {
            v_new = q->v_min;
            sat_v = 1;
            if (r_new < 0.0) r_new = 0.0;
        } else if (first && ((v_new == q->v_max && r_new > 0) ||
                             (v_new == q->v_min && r_new < 0))) {
            r_new = 0.0;
            sat_v = 1;
        }
        any_v = any_v || sat_v;   /* a limit at any sub-step flags the step */
        any_s = any_s || sat_s;
        if (q->hyst) h_bw = bw_increment(q, h_bw, v_new - v);
        v = v_new;
        r = r_new;
        if (mean != NULL) {
            double f = stack_force(P, q, v - h_bw);
            total += 0.5 * (f_prev + f);
            f_prev = f;
        }
    }
    if (mean != NULL) *mean = total / (double)n;
    x[0] = v;
    x[1] = r;
    x[2] = any_v;
    x[3] = any_s;
    x[4] = h_bw;
    x[6] = z;
    return n;
}

/* ------------------------------------------------------------------ gauge */

static uint64_t splitmix64(uint64_t x) {
    uint64_t z = x + 0x9E3779B97F4A7C15u;
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9u;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBu;
    return z ^ (z >> 31);
}

/* piezofmu.actuator.gaussian: N(0, 1) as a pure function of (seed, counter). */
static double gaussian(uint64_t seed, uint64_t counter) {
    uint64_t h1 = splitmix64(splitmix64(seed) ^ counter), h2 = splitmix64(h1);
    double u1 = (double)((h1 >> 11) + 1) * ldexp(1.0, -53);
    double u2 = (double)(h2 >> 11) * ldexp(1.0, -53);
    return sqrt(-2.0 * jm_log(u1)) * jm_cos(2.0 * PI * u2);
}

/* Python's round(): half to even. */
static double round_even(double x) {
    double f = floor(x), d = x - f;
    if (d > 0.5) return f + 1.0;
    if (d < 0.5) return f;
    return fmod(f, 2.0) == 0.0 ? f : f + 1.0;
}

static void write_strain(JfInstance *inst, const Params *q) {
    Piezo *p = P;
    double eps = inst->r[p->elongation] / q->length;
    if (q->noise_std > 0.0) eps += q->noise_std * gaussian(q->seed, (uint64_t)inst->state[5]);
    if (q->resolution > 0.0) eps = q->resolution * round_even(eps / q->resolution);
    inst->r[p->strain] = eps;
}

static void write_outputs(JfInstance *inst, const Params *q) {
    Piezo *p = P;
    const double *x = inst->state;
    double v_eff = x[0] - x[4], stroke = p->stroke_per_volt * v_eff;
    int sat_stroke = fabs(stroke) > q->stroke_limit;
    if (sat_stroke) {
        stroke = copysign(q->stroke_limit, stroke);
        v_eff = stroke / p->stroke_per_volt;
    }
    inst->r[p->force] = p->ch * v_eff;
    inst->r[p->voltage] = x[0];
    inst->r[p->current] = p->capacitance * x[1];
    inst->r[p->free_stroke] = stroke;
    inst->r[p->sat_voltage] = x[2] != 0.0 ? 1.0 : 0.0;
    inst->r[p->sat_slew] = x[3] != 0.0 ? 1.0 : 0.0;
    inst->r[p->sat_stroke] = sat_stroke ? 1.0 : 0.0;
}

/* The force held over the coming step: its mean with v_cmd held (coupling 1), else the
 * state's force (already written by write_outputs). */
static void write_force(JfInstance *inst, const Params *q) {
    Piezo *p = P;
    double mean;
    if (q->coupling != 1) return;
    memcpy(p->ahead_x0, inst->state, sizeof p->ahead_x0);
    memcpy(p->ahead_x1, inst->state, sizeof p->ahead_x1);
    p->ahead_u = inst->r[p->v_cmd];
    p->ahead_e = inst->r[p->elongation];
    p->ahead_q = *q;
    p->ahead_n = advance(inst, q, p->ahead_x1, p->ahead_u, p->ahead_e, q->hold_step, &mean);
    p->ahead_ok = 1;
    inst->r[p->force] = mean;
}

/* ------------------------------------------------------------------ FMI hooks */

int model_exit_initialization(JfInstance *inst) {
    Params q;
    double v;
    if (params(inst, &q) != JF_OK) return JF_ERROR;
    v = 0.0 < q.v_min ? q.v_min : 0.0; /* at rest at 0 V, clipped to the rails */
    if (v > q.v_max) v = q.v_max;
    inst->state[0] = v;
    inst->state[1] = 0.0;
    inst->state[2] = v != 0.0;
    inst->state[3] = 0.0;
    inst->state[4] = 0.0;
    inst->state[5] = 0.0;
    inst->state[6] = q.servo ? v : 0.0;
    write_outputs(inst, &q);
    P->ready = 1;
    write_strain(inst, &q);
    write_force(inst, &q);
    return JF_OK;
}

int model_inputs_changed(JfInstance *inst) {
    Params q;
    if (!P->ready) return JF_OK;
    if (params(inst, &q) != JF_OK) return JF_ERROR;
    write_strain(inst, &q);
    if (!isfinite(inst->r[P->v_cmd])) return JF_OK;   /* refused at the step */
    if (q.servo && !isfinite(inst->r[P->elongation])) return JF_OK;
    write_force(inst, &q);
    return JF_OK;
}

int model_state_restored(JfInstance *inst) {
    const double *x = inst->state;   /* finite: checked with the state bytes */
    if (x[5] < 0 || x[5] != floor(x[5]) || (x[2] != 0 && x[2] != 1) ||
        (x[3] != 0 && x[3] != 1)) {
        jf_log(inst, 3, "FMU state rejected: actuator state is not a valid state");
        return JF_ERROR;
    }
    P->ready = inst->phase == JF_STEPPING;
    P->ahead_ok = 0;
    return JF_OK;
}

int model_do_step(JfInstance *inst, double t, double h) {
    Params q;
    double u = inst->r[P->v_cmd], e = inst->r[P->elongation];
    (void)t;
    if (params(inst, &q) != JF_OK) return JF_ERROR;
    if (!isfinite(u)) {
        jf_log(inst, 3, "amplifier command v_cmd must be finite, got %g", u);
        return JF_ERROR;
    }
    if (q.servo && !isfinite(e)) {
        jf_log(inst, 3, "elongation must be finite with the servo on, got %g", e);
        return JF_ERROR;
    }
    if (q.coupling == 1) {
        if (!jf_same_step(h, q.hold_step, t + h)) { /* the host's rounding of the step */
            jf_log(inst, 3, "%s was stepped by %.17g s, but its force is the mean over "
                   "hold_step = %.17g s; set hold_step to the communication step (or "
                   "coupling = 0)", inst->instance_name, h, q.hold_step);
            return JF_ERROR;
        }
        h = q.hold_step;
    }
    if (q.coupling == 1 && P->ahead_ok && u == P->ahead_u && (!q.servo || e == P->ahead_e) &&
        memcmp(P->ahead_x0, inst->state, sizeof P->ahead_x0) == 0 &&
        memcmp(&P->ahead_q, &q, sizeof q) == 0) {
        memcpy(inst->state, P->ahead_x1, sizeof P->ahead_x1);  /* the same computation */
        inst->state[5] += (double)P->ahead_n;
    } else {
        inst->state[5] += (double)advance(inst, &q, inst->state, u, e, h, NULL);
    }
    write_outputs(inst, &q);
    write_strain(inst, &q);
    write_force(inst, &q);
    return JF_OK;
}
