/* The FMI-independent core of a jitterfmu native FMU (C99, libc and libm only).
 *
 * Shared by the FMI 2.0 layer (fmi2.c) and the FMI 3.0 layer (fmi3.c); see jfcore.h.
 * Variables live in arrays indexed by value reference; the model kernel steps them.
 * The FMU state is kept in its serialised form: one byte layout, the same under both
 * FMI versions, written by jf_state_save (fmi2GetFMUstate / fmi3GetFMUState, and the
 * serialisation) and checked field by field before jf_state_restore writes anything
 * (see state_check: checksum, sizes, GUID, phase, Booleans, and every Real value, the
 * start time and the kernel state finite).  The kernel then checks its own state
 * (model_state_restored); if it refuses it, the instance's previous state is written
 * back, so a refused state changes nothing:
 *
 *   offset  size        field
 *   0       8           magic "JFMUSTAT"
 *   8       4           layout version (uint32, 2)
 *   12      4           byte-order mark 0x01020304 (uint32, host order)
 *   16      64          GUID (FMI 3.0: instantiation token) of the model, zero padded
 *   80      4 x 4       n_vr, n_state, phase, 0 (uint32)
 *   96      8           start time (double)
 *   104     8 n_vr      Real (Float64) values by value reference (double)
 *   ...     4 n_vr      Integer (Int32) values (int32)
 *   ...     4 n_vr      Boolean values (int32, 0 or 1)
 *   ...     8 n_state   kernel state (double)
 *   ...     8           the communication point the next step starts from (double)
 *   end-8   8           FNV-1a 64 checksum of every byte before it
 *
 * String variables (fixed parameters) are not part of the state.
 */
#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "jfcore.h"
#include "jfstate.h"
#include "jfmu.h"
#include "model_config.h"

#define STATE_MAGIC "JFMUSTAT"
#define STATE_VERSION 2u
#define STATE_HEADER JF_STATE_HEADER

/* ------------------------------------------------------------------ logging, memory */

void jf_log(JfInstance *inst, int status, const char *fmt, ...) {
    char buf[1024];
    va_list ap;
    static const char *categories[] = {"logAll", "logStatusWarning", "logStatusDiscard",
                                       "logStatusError", "logStatusFatal"};
    if (inst == NULL) return;
    if (status < 3 && !inst->logging_on) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    if (status < 0 || status > 4) status = 3;
    jf_api_log(inst, status, categories[status], buf);
}

void *jf_alloc(JfInstance *inst, size_t n, size_t size) {
    void *p = calloc(n ? n : 1, size ? size : 1);
    if (p == NULL) jf_log(inst, 3, "out of memory (%lu x %lu bytes)", (unsigned long)n,
                          (unsigned long)size);
    return p;
}

/* The variable of value reference vr (< JF_N_VR), its first row as the table lists it. */
static const JfVar *var_of(unsigned int vr) {
    int i = JF_VAR_INDEX[vr];
    return i < 0 ? NULL : &JF_VARS[i];
}

long jf_vr(JfInstance *inst, const char *name, int type) {
    size_t i;
    for (i = 0; i < JF_N_VARS; i++)
        if (JF_VARS[i].type == type && strcmp(JF_VARS[i].name, name) == 0)
            return (long)JF_VARS[i].vr;
    jf_log(inst, 3, "model %s has no variable %s of type %d", JF_MODEL_IDENTIFIER, name, type);
    return -1;
}

static char *dup_string(const char *s) {
    size_t n = strlen(s);
    char *out = (char *)malloc(n + 1);
    if (out != NULL) memcpy(out, s, n + 1);
    return out;
}

/* ------------------------------------------------------------------ instance life */

static void set_start_values(JfInstance *inst) {
    size_t i;
    for (i = 0; i < JF_N_VARS; i++) {
        const JfVar *v = &JF_VARS[i];
        switch (v->type) {
        case JF_REAL: inst->r[v->vr] = v->start; break;
        case JF_INTEGER: inst->iv[v->vr] = (int)v->start; break;
        case JF_BOOLEAN: inst->bv[v->vr] = v->start != 0.0; break;
        default:
            free(inst->sv[v->vr]);
            inst->sv[v->vr] = dup_string(v->sstart ? v->sstart : "");
        }
    }
}

JfInstance *jf_instance_new(const char *name, int logging_on) {
    JfInstance *inst = (JfInstance *)calloc(1, sizeof(JfInstance));
    if (inst == NULL) return NULL;
    inst->logging_on = logging_on != 0;
    inst->instance_name = dup_string(name ? name : "");
    if (inst->instance_name == NULL) {
        free(inst);
        return NULL;
    }
    return inst;
}

int jf_instance_setup(JfInstance *inst, const char *token, char *resource_dir) {
    inst->resource_dir = resource_dir;
    if (token == NULL || strcmp(token, JF_GUID) != 0) {
        jf_log(inst, 3, "GUID %s does not match the model's %s", token ? token : "(null)",
               JF_GUID);
        return JF_ERROR;
    }
    inst->r = (double *)jf_alloc(inst, JF_N_VR, sizeof(double));
    inst->iv = (int *)jf_alloc(inst, JF_N_VR, sizeof(int));
    inst->bv = (int *)jf_alloc(inst, JF_N_VR, sizeof(int));
    inst->sv = (char **)jf_alloc(inst, JF_N_VR, sizeof(char *));
    if (inst->resource_dir == NULL || !inst->r || !inst->iv || !inst->bv || !inst->sv) {
        jf_log(inst, 3, "cannot instantiate %s: no resource location or no memory",
               JF_MODEL_IDENTIFIER);
        return JF_ERROR;
    }
    set_start_values(inst);
    inst->phase = JF_INSTANTIATED;
    return model_instantiate(inst) == JF_OK ? JF_OK : JF_ERROR;
}

void jf_instance_free(JfInstance *inst) {
    size_t i;
    if (inst == NULL) return;
    model_free(inst);
    if (inst->sv != NULL)
        for (i = 0; i < JF_N_VR; i++) free(inst->sv[i]);
    free(inst->sv);
    free(inst->r);
    free(inst->iv);
    free(inst->bv);
    free(inst->state);
    free(inst->resource_dir);
    free(inst->instance_name);
    free(inst);
}

int jf_kernel_status(JfInstance *inst, int status) {
    if (status == JF_OK) return JF_OK;
    inst->phase = JF_FAILED;
    return JF_ERROR;
}

int jf_instance_reset(JfInstance *inst) {
    size_t i;
    model_free(inst);
    free(inst->state);
    inst->state = NULL;
    inst->n_state = 0;
    inst->model = NULL;
    for (i = 0; i < JF_N_VR; i++) {
        inst->r[i] = 0.0;
        inst->iv[i] = 0;
        inst->bv[i] = 0;
    }
    set_start_values(inst);
    inst->start_time = 0.0;
    inst->phase = JF_INSTANTIATED;
    return jf_kernel_status(inst, model_instantiate(inst));
}

int jf_enter_initialization(JfInstance *inst, double start_time, const char *fn) {
    if (inst->phase != JF_INSTANTIATED) {
        jf_log(inst, 3, "%s: only allowed once, after instantiation", fn);
        return JF_ERROR;
    }
    if (!isfinite(start_time) || fabs(start_time) > JF_MAX_TIME) {
        jf_log(inst, 3, "%s: start time %.17g s is not a finite time within %g s", fn,
               start_time, JF_MAX_TIME);
        return JF_ERROR;
    }
    inst->start_time = start_time;
    inst->t_next = start_time;
    inst->phase = JF_INITIALIZATION;
    return JF_OK;
}

int jf_exit_initialization(JfInstance *inst, const char *fn) {
    if (inst->phase != JF_INITIALIZATION) {
        jf_log(inst, 3, "%s: not in initialization mode", fn);
        return JF_ERROR;
    }
    if (model_exit_initialization(inst) != JF_OK) return jf_kernel_status(inst, JF_ERROR);
    inst->phase = JF_STEPPING;
    return JF_OK;
}

int jf_do_step(JfInstance *inst, double t, double h, const char *fn) {
    if (inst->phase != JF_STEPPING) {
        jf_log(inst, 3, "%s: not in step mode (initialise first, and no step after an "
               "error or after terminating)", fn);
        return JF_ERROR;
    }
    if (!(h > 0.0) || !isfinite(h) || !isfinite(t)) {
        jf_log(inst, 3, "%s: communication step must be positive and finite", fn);
        return JF_ERROR;
    }
    if (h > JF_MAX_STEP || fabs(t) + h > JF_MAX_TIME) {
        jf_log(inst, 3, "%s: a step of %.17g s from t = %.17g s is longer than the %g s one "
               "step may take (or ends past %g s); step in pieces", fn, h, t, JF_MAX_STEP,
               JF_MAX_TIME);
        return JF_ERROR;
    }
    if (t < inst->t_next && inst->t_next - t <= 1e-9 * fabs(inst->t_next) &&
        fabs(t + h - inst->t_next) <= 4.0 * DBL_EPSILON * fabs(inst->t_next))
        return JF_OK;   /* a host's rounding remainder (t += h short of its stop time) */
    if (!jf_same_point(t, inst->t_next, h)) {
        jf_log(inst, 3, "%s: the step starts at t = %.17g s but the FMU is at t = %.17g s; "
               "step from where the last step ended (or restore a state saved there)", fn,
               t, inst->t_next);
        return JF_ERROR;
    }
    if (model_do_step(inst, t, h) != JF_OK) return jf_kernel_status(inst, JF_ERROR);
    inst->t_next = jf_end_time(t, h, inst->t_next);
    return JF_OK;
}

int jf_same_point(double t, double known, double h) {
    /* a host that accumulates t += h is off by up to about (t / h) ulps of t */
    double tol = JF_TIME_RTOL * h + 4.0 * DBL_EPSILON * fabs(known) * (1.0 + fabs(known) / h);
    return fabs(t - known) <= (tol < 0.5 * h ? tol : 0.5 * h);
}

int jf_check_reals(JfInstance *inst, const unsigned int *vr, size_t nvr, const double *v,
                   const char *fn) {
    size_t k;
    for (k = 0; k < nvr; k++) {
        const JfVar *var = var_of(vr[k]);
        if (!isfinite(v[k])) {
            jf_log(inst, 3, "%s: %s = %g is not a finite number; nothing was set", fn,
                   var->name, v[k]);
            return JF_ERROR;
        }
        if (v[k] < var->min || v[k] > var->max) {
            jf_log(inst, 3, "%s: %s = %.17g is outside its declared range [%.17g, %.17g]; "
                   "nothing was set", fn, var->name, v[k], var->min, var->max);
            return JF_ERROR;
        }
    }
    return JF_OK;
}

int jf_check_outputs(JfInstance *inst, const char *fn, int ranges) {
    size_t i;
    for (i = 0; i < JF_N_VARS; i++) {
        const JfVar *v = &JF_VARS[i];
        double x;
        if (v->type != JF_REAL || v->causality != JF_OUTPUT) continue;
        x = inst->r[v->vr];
        if (isfinite(x) && (!ranges || (x >= v->min && x <= v->max))) continue;
        jf_log(inst, 3, "%s: output %s = %g is %s; an input drove the model outside its "
               "validity (the instance stops here)", fn, v->name, x,
               isfinite(x) ? "outside its declared range" : "not a finite number");
        inst->phase = JF_FAILED;
        return JF_ERROR;
    }
    return JF_OK;
}

/* ------------------------------------------------------------------ variables */

int jf_check_refs(JfInstance *inst, const unsigned int *vr, size_t nvr, int type,
                  int setting) {
    size_t k;
    if (inst->phase == JF_FAILED) {
        jf_log(inst, 3, "instance %s failed before; no further calls allowed",
               inst->instance_name);
        return JF_ERROR;
    }
    for (k = 0; k < nvr; k++) {
        const JfVar *v = vr[k] < JF_N_VR ? var_of(vr[k]) : NULL;
        if (v == NULL || v->type != type) {
            jf_log(inst, 3, "value reference %u is not a variable of this type (%d)",
                   (unsigned)vr[k], type);
            return JF_ERROR;
        }
        if (setting) {
            if (v->causality == JF_OUTPUT || v->causality == JF_LOCAL) {
                jf_log(inst, 3, "variable %s is an output or local and cannot be set", v->name);
                return JF_ERROR;
            }
            if (v->causality == JF_PARAMETER && !v->tunable && inst->phase >= JF_STEPPING) {
                jf_log(inst, 3, "fixed parameter %s cannot be set after initialization",
                       v->name);
                return JF_ERROR;
            }
        }
    }
    return JF_OK;
}

/* Kernels refresh direct-feedthrough outputs here, in any phase (as the Python slaves'
 * set_real does); those that need initialised parameters check their own flag. */
int jf_after_set(JfInstance *inst, size_t nvr) {
    if (nvr == 0) return JF_OK;
    return jf_kernel_status(inst, model_inputs_changed(inst));
}

int jf_set_string(JfInstance *inst, unsigned int vr, const char *s) {
    char *copy = dup_string(s ? s : "");
    if (copy == NULL) {
        jf_log(inst, 3, "setting a String: out of memory");
        return JF_ERROR;
    }
    free(inst->sv[vr]);
    inst->sv[vr] = copy;
    return JF_OK;
}

/* ------------------------------------------------------------------ FMU state */

static size_t state_size(const JfInstance *inst) {
    return STATE_HEADER + JF_N_VR * (8u + 4u + 4u) + inst->n_state * 8u + 8u + 8u;
}

JfState *jf_state_save(JfInstance *inst) {
    size_t n = state_size(inst), i;
    uint32_t head[6];
    int32_t word;
    unsigned char *p;
    uint64_t sum;
    JfState *blob = (JfState *)jf_alloc(inst, 1, sizeof(JfState) + n);
    if (blob == NULL) return NULL;
    blob->size = n;
    p = blob->bytes;
    jf_state_head_write(p, STATE_MAGIC, STATE_VERSION, JF_GUID);
    head[2] = (uint32_t)JF_N_VR;
    head[3] = (uint32_t)inst->n_state;
    head[4] = (uint32_t)inst->phase;
    head[5] = 0;
    memcpy(p + 80, head + 2, 16);
    memcpy(p + 96, &inst->start_time, 8);
    p += STATE_HEADER;
    memcpy(p, inst->r, JF_N_VR * 8u);
    p += JF_N_VR * 8u;
    for (i = 0; i < JF_N_VR; i++, p += 4) {
        word = (int32_t)inst->iv[i];
        memcpy(p, &word, 4);
    }
    for (i = 0; i < JF_N_VR; i++, p += 4) {
        word = (int32_t)(inst->bv[i] != 0);
        memcpy(p, &word, 4);
    }
    if (inst->n_state) memcpy(p, inst->state, inst->n_state * 8u);
    p += inst->n_state * 8u;
    memcpy(p, &inst->t_next, 8);
    p += 8;
    sum = jf_state_sum(blob->bytes, n - 8u);
    memcpy(p, &sum, 8);
    return blob;
}

/* Check every field of a serialised state before anything is written; 0 if valid. */
static int state_check(JfInstance *inst, const unsigned char *p, size_t n) {
    const unsigned char *start = p;
    uint32_t head[6];
    uint64_t sum;
    char why[160];
    int32_t word;
    size_t i;
    if (jf_state_head_check(p, n, STATE_MAGIC, STATE_VERSION, JF_GUID, "native", why,
                            sizeof why)) {
        jf_log(inst, 3, "FMU state rejected: %s", why);
        return 1;
    }
    memcpy(head + 2, p + 80, 16);
    if (head[2] != JF_N_VR || head[3] != inst->n_state || n != state_size(inst)) {
        jf_log(inst, 3, "FMU state rejected: %u variables and %u state values in %lu bytes; "
               "expected %u, %u and %lu", (unsigned)head[2], (unsigned)head[3],
               (unsigned long)n, (unsigned)JF_N_VR, (unsigned)inst->n_state,
               (unsigned long)state_size(inst));
        return 1;
    }
    memcpy(&sum, p + n - 8u, 8);
    if (sum != jf_state_sum(p, n - 8u)) {
        jf_log(inst, 3, "FMU state rejected: checksum mismatch (corrupted bytes)");
        return 1;
    }
    if (head[4] > JF_TERMINATED) {
        jf_log(inst, 3, "FMU state rejected: phase %u is not a valid phase", (unsigned)head[4]);
        return 1;
    }
    p += STATE_HEADER + JF_N_VR * 12u;
    for (i = 0; i < JF_N_VR; i++, p += 4) {
        memcpy(&word, p, 4);
        if (word != 0 && word != 1) {
            jf_log(inst, 3, "FMU state rejected: Boolean value %ld is not 0 or 1", (long)word);
            return 1;
        }
    }
    for (i = 0; i < inst->n_state; i++, p += 8) {   /* every kernel's state is finite */
        double x;
        memcpy(&x, p, 8);
        if (!isfinite(x)) {
            jf_log(inst, 3, "FMU state rejected: state value %lu is not finite",
                   (unsigned long)i);
            return 1;
        }
    }
    {
        double t;
        memcpy(&t, p, 8);
        if (!isfinite(t) || fabs(t) > JF_MAX_TIME) {
            jf_log(inst, 3, "FMU state rejected: its time %g s is not a finite time within "
                   "%g s", t, JF_MAX_TIME);
            return 1;
        }
    }
    p = start + 96;
    for (i = 0; i <= JF_N_VR; i++, p += 8) {   /* the start time, then every Real value */
        double x;
        memcpy(&x, p, 8);
        if (!isfinite(x) && i == 0) {
            jf_log(inst, 3, "FMU state rejected: its start time is not finite");
            return 1;
        }
        if (!isfinite(x)) {
            jf_log(inst, 3, "FMU state rejected: Real value reference %lu is not finite",
                   (unsigned long)(i - 1));
            return 1;
        }
    }
    return 0;
}

/* Write a checked state into the instance (no kernel hook). */
static void state_apply(JfInstance *inst, const unsigned char *p) {
    uint32_t phase;
    int32_t word;
    size_t i;
    memcpy(&phase, p + 88, 4);
    inst->phase = (int)phase;
    memcpy(&inst->start_time, p + 96, 8);
    p += STATE_HEADER;
    memcpy(inst->r, p, JF_N_VR * 8u);
    p += JF_N_VR * 8u;
    for (i = 0; i < JF_N_VR; i++, p += 4) {
        memcpy(&word, p, 4);
        inst->iv[i] = (int)word;
    }
    for (i = 0; i < JF_N_VR; i++, p += 4) {
        memcpy(&word, p, 4);
        inst->bv[i] = (int)word;
    }
    if (inst->n_state) memcpy(inst->state, p, inst->n_state * 8u);
    memcpy(&inst->t_next, p + inst->n_state * 8u, 8);
}

/* Restore a state all or nothing: checked bytes, then the kernel's own check; a state the
 * kernel refuses is replaced by the instance's previous one. */
int jf_state_restore(JfInstance *inst, const unsigned char *p, size_t n) {
    JfState *before;
    if (state_check(inst, p, n) != 0) return JF_ERROR;
    before = jf_state_save(inst);
    if (before == NULL) return JF_ERROR;
    state_apply(inst, p);
    if (model_state_restored(inst) != JF_OK) {
        state_apply(inst, before->bytes);
        (void)model_state_restored(inst);
        free(before);
        jf_log(inst, 3, "FMU state rejected by %s; its previous state is kept",
               inst->instance_name);
        return JF_ERROR;
    }
    free(before);
    return JF_OK;
}

JfState *jf_state_copy(JfInstance *inst, const unsigned char *p, size_t n) {
    JfState *blob;
    if (state_check(inst, p, n) != 0) return NULL;
    blob = (JfState *)jf_alloc(inst, 1, sizeof(JfState) + n);
    if (blob == NULL) return NULL;
    blob->size = n;
    memcpy(blob->bytes, p, n);
    return blob;
}

/* ------------------------------------------------------------------ time */

double jf_end_time(double t, double h, double last) {
    double te, g;
    if (fabs(t - last) <= JF_TIME_RTOL * fabs(h)) t = last;
    te = t + h;
    if (!(fabs(te) < 9.0e3)) return te; /* ps counts exact below 2^53 ps */
    g = nearbyint(te * 1.0e12) / 1.0e12;
    if (fabs(g - te) <= 4.0 * DBL_EPSILON * fabs(te)) return g;
    /* a host whose clock drifts: a time within JF_TIME_RTOL of a step of a microsecond
     * is that microsecond (as fmukit.timing.end_time) */
    g = nearbyint(te * 1.0e6) / 1.0e6;
    return fabs(g - te) <= JF_TIME_RTOL * fabs(h) ? g : te;
}

int jf_reached(double t, double event, double period) {
    return t >= event - JF_TIME_RTOL * fabs(period);
}

int jf_same_step(double h, double known, double t) {
    double k = fabs(known), tol = 4.0 * DBL_EPSILON * fabs(t) * (1.0 + fabs(t) / k);
    if (tol < JF_STEP_RTOL * k) tol = JF_STEP_RTOL * k;
    return fabs(h - known) <= (tol < 0.25 * k ? tol : 0.25 * k);
}
