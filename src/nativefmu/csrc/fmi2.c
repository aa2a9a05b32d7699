/* FMI 2.0 co-simulation API of a jitterfmu native FMU (C99, libc and libm only).
 *
 * Variables live in arrays indexed by value reference; the model kernel steps them.
 * The FMU state is kept in its serialised form: one byte layout, written by
 * fmi2GetFMUstate / fmi2SerializeFMUstate and checked field by field before
 * fmi2SetFMUstate / fmi2DeSerializeFMUstate write anything (see state_check: checksum,
 * sizes, GUID, phase, Booleans, and every Real value, the start time and the kernel state
 * finite).  The kernel then checks its own state (model_state_restored); if it refuses
 * it, the instance's previous state is written back, so a refused state changes nothing:
 *
 *   offset  size        field
 *   0       8           magic "JFMUSTAT"
 *   8       4           layout version (uint32, 1)
 *   12      4           byte-order mark 0x01020304 (uint32, host order)
 *   16      64          GUID of the model description, zero padded
 *   80      4 x 4       n_vr, n_state, phase, 0 (uint32)
 *   96      8           start time (double)
 *   104     8 n_vr      Real values by value reference (double)
 *   ...     4 n_vr      Integer values (int32)
 *   ...     4 n_vr      Boolean values (int32, 0 or 1)
 *   ...     8 n_state   kernel state (double)
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

#include "fmi2Functions.h"
#include "jfmu.h"
#include "model_config.h"

#define STATE_MAGIC "JFMUSTAT"
#define STATE_VERSION 1u
#define STATE_BOM 0x01020304u
#define STATE_HEADER 104u

static const fmi2CallbackFunctions *cbs(const JfInstance *inst) {
    return (const fmi2CallbackFunctions *)inst->callbacks;
}

void jf_log(JfInstance *inst, int status, const char *fmt, ...) {
    char buf[1024];
    va_list ap;
    const fmi2CallbackFunctions *cb;
    static const char *categories[] = {"logAll", "logStatusWarning", "logStatusDiscard",
                                       "logStatusError", "logStatusFatal"};
    if (inst == NULL) return;
    cb = cbs(inst);
    if (cb == NULL || cb->logger == NULL) return;
    if (status < 3 && !inst->logging_on) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    if (status < 0 || status > 4) status = 3;
    cb->logger(cb->componentEnvironment, inst->instance_name, (fmi2Status)status,
               categories[status], "%s", buf);
}

void *jf_alloc(JfInstance *inst, size_t n, size_t size) {
    void *p = calloc(n ? n : 1, size ? size : 1);
    if (p == NULL) jf_log(inst, 3, "out of memory (%lu x %lu bytes)", (unsigned long)n,
                          (unsigned long)size);
    return p;
}

static const JfVar *var_of(unsigned int vr) {
    size_t i;
    for (i = 0; i < JF_N_VARS; i++)
        if (JF_VARS[i].vr == vr) return &JF_VARS[i];
    return NULL;
}

long jf_vr(JfInstance *inst, const char *name, int type) {
    size_t i;
    for (i = 0; i < JF_N_VARS; i++)
        if (JF_VARS[i].type == type && strcmp(JF_VARS[i].name, name) == 0)
            return (long)JF_VARS[i].vr;
    jf_log(inst, 3, "model %s has no variable %s of type %d", JF_MODEL_IDENTIFIER, name, type);
    return -1;
}

/* ------------------------------------------------------------------ helpers */

static char *dup_string(const char *s) {
    size_t n = strlen(s);
    char *out = (char *)malloc(n + 1);
    if (out != NULL) memcpy(out, s, n + 1);
    return out;
}

static int hexval(char c) {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
}

/* Local path (with a trailing '/') of a file:// URI, percent-decoded. */
static char *uri_to_path(const char *uri) {
    const char *p = uri;
    char *out, *q;
    size_t n;
    if (uri == NULL) return NULL;
    if (strncmp(p, "file://", 7) == 0) {
        p += 7;
        if (strncmp(p, "localhost/", 10) == 0) p += 9;
    } else if (strncmp(p, "file:", 5) == 0) {
        p += 5;
    }
#ifdef _WIN32
    if (p[0] == '/' && p[1] != '\0' && p[2] == ':') p += 1; /* /C:/... */
#endif
    n = strlen(p);
    out = (char *)malloc(n + 2);
    if (out == NULL) return NULL;
    q = out;
    while (*p) {
        if (p[0] == '%' && hexval(p[1]) >= 0 && hexval(p[2]) >= 0) {
            *q++ = (char)(hexval(p[1]) * 16 + hexval(p[2]));
            p += 3;
        } else {
            *q++ = *p++;
        }
    }
    if (q == out || (q[-1] != '/' && q[-1] != '\\')) *q++ = '/';
    *q = '\0';
    return out;
}

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

static void free_instance(JfInstance *inst) {
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

#define INST ((JfInstance *)c)

static fmi2Status fail(JfInstance *inst, const char *fmt, const char *what) {
    jf_log(inst, 3, fmt, what);
    return fmi2Error;
}

static fmi2Status kernel_status(JfInstance *inst, int status) {
    if (status == JF_OK) return fmi2OK;
    inst->phase = JF_FAILED;
    return fmi2Error;
}

/* ------------------------------------------------------------------ common functions */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    (void)nCategories;
    (void)categories;
    if (c == NULL) return fmi2Error;
    INST->logging_on = loggingOn != 0;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    JfInstance *inst;
    (void)visible;
    inst = (JfInstance *)calloc(1, sizeof(JfInstance));
    if (inst == NULL) return NULL;
    inst->callbacks = functions;
    inst->logging_on = loggingOn != 0;
    inst->instance_name = dup_string(instanceName ? instanceName : "");
    if (inst->instance_name == NULL) {
        free(inst);
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        jf_log(inst, 3, "%s supports co-simulation only", JF_MODEL_IDENTIFIER);
        free_instance(inst);
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, JF_GUID) != 0) {
        jf_log(inst, 3, "GUID %s does not match the model's %s", fmuGUID ? fmuGUID : "(null)",
               JF_GUID);
        free_instance(inst);
        return NULL;
    }
    inst->resource_dir = uri_to_path(fmuResourceLocation);
    inst->r = (double *)jf_alloc(inst, JF_N_VR, sizeof(double));
    inst->iv = (int *)jf_alloc(inst, JF_N_VR, sizeof(int));
    inst->bv = (int *)jf_alloc(inst, JF_N_VR, sizeof(int));
    inst->sv = (char **)jf_alloc(inst, JF_N_VR, sizeof(char *));
    if (inst->resource_dir == NULL || !inst->r || !inst->iv || !inst->bv || !inst->sv) {
        jf_log(inst, 3, "cannot instantiate %s: no resource location or no memory",
               JF_MODEL_IDENTIFIER);
        free_instance(inst);
        return NULL;
    }
    set_start_values(inst);
    inst->phase = JF_INSTANTIATED;
    if (model_instantiate(inst) != JF_OK) {
        free_instance(inst);
        return NULL;
    }
    return inst;
}

void fmi2FreeInstance(fmi2Component c) { free_instance(INST); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (c == NULL) return fmi2Error;
    if (INST->phase != JF_INSTANTIATED)
        return fail(INST, "fmi2SetupExperiment: %s", "only allowed after fmi2Instantiate");
    INST->start_time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    if (INST->phase != JF_INSTANTIATED)
        return fail(INST, "fmi2EnterInitializationMode: %s", "only allowed once, after "
                    "fmi2Instantiate");
    INST->phase = JF_INITIALIZATION;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    if (INST->phase != JF_INITIALIZATION)
        return fail(INST, "fmi2ExitInitializationMode: %s", "not in initialization mode");
    if (model_exit_initialization(INST) != JF_OK) return kernel_status(INST, JF_ERROR);
    INST->phase = JF_STEPPING;
    return fmi2OK;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    INST->phase = JF_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    size_t i;
    if (c == NULL) return fmi2Error;
    model_free(INST);
    free(INST->state);
    INST->state = NULL;
    INST->n_state = 0;
    INST->model = NULL;
    for (i = 0; i < JF_N_VR; i++) {
        INST->r[i] = 0.0;
        INST->iv[i] = 0;
        INST->bv[i] = 0;
    }
    set_start_values(INST);
    INST->start_time = 0.0;
    INST->phase = JF_INSTANTIATED;
    return kernel_status(INST, model_instantiate(INST));
}

/* ------------------------------------------------------------------ getters and setters */

static fmi2Status check_refs(JfInstance *inst, const fmi2ValueReference vr[], size_t nvr,
                             int type, int setting) {
    size_t k;
    if (inst->phase == JF_FAILED) {
        jf_log(inst, 3, "instance %s failed before; no further calls allowed",
               inst->instance_name);
        return fmi2Error;
    }
    for (k = 0; k < nvr; k++) {
        const JfVar *v = vr[k] < JF_N_VR ? var_of(vr[k]) : NULL;
        if (v == NULL || v->type != type) {
            jf_log(inst, 3, "value reference %u is not a variable of this type (%d)",
                   (unsigned)vr[k], type);
            return fmi2Error;
        }
        if (setting) {
            if (v->causality == JF_OUTPUT || v->causality == JF_LOCAL) {
                jf_log(inst, 3, "variable %s is an output or local and cannot be set", v->name);
                return fmi2Error;
            }
            if (v->causality == JF_PARAMETER && !v->tunable && inst->phase >= JF_STEPPING) {
                jf_log(inst, 3, "fixed parameter %s cannot be set after initialization",
                       v->name);
                return fmi2Error;
            }
        }
    }
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    size_t k;
    if (c == NULL || check_refs(INST, vr, nvr, JF_REAL, 0) != fmi2OK) return fmi2Error;
    for (k = 0; k < nvr; k++) value[k] = INST->r[vr[k]];
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    size_t k;
    if (c == NULL || check_refs(INST, vr, nvr, JF_INTEGER, 0) != fmi2OK) return fmi2Error;
    for (k = 0; k < nvr; k++) value[k] = INST->iv[vr[k]];
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    size_t k;
    if (c == NULL || check_refs(INST, vr, nvr, JF_BOOLEAN, 0) != fmi2OK) return fmi2Error;
    for (k = 0; k < nvr; k++) value[k] = INST->bv[vr[k]] ? fmi2True : fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    size_t k;
    if (c == NULL || check_refs(INST, vr, nvr, JF_STRING, 0) != fmi2OK) return fmi2Error;
    for (k = 0; k < nvr; k++) value[k] = INST->sv[vr[k]];
    return fmi2OK;
}

/* Kernels refresh direct-feedthrough outputs here, in any phase (as the Python slaves'
 * set_real does); those that need initialised parameters check their own flag. */
static fmi2Status after_set(JfInstance *inst, size_t nvr) {
    if (nvr == 0) return fmi2OK;
    return kernel_status(inst, model_inputs_changed(inst));
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    size_t k;
    if (c == NULL || check_refs(INST, vr, nvr, JF_REAL, 1) != fmi2OK) return fmi2Error;
    for (k = 0; k < nvr; k++) INST->r[vr[k]] = value[k];
    return after_set(INST, nvr);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    size_t k;
    if (c == NULL || check_refs(INST, vr, nvr, JF_INTEGER, 1) != fmi2OK) return fmi2Error;
    for (k = 0; k < nvr; k++) INST->iv[vr[k]] = value[k];
    return after_set(INST, nvr);
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    size_t k;
    if (c == NULL || check_refs(INST, vr, nvr, JF_BOOLEAN, 1) != fmi2OK) return fmi2Error;
    for (k = 0; k < nvr; k++) INST->bv[vr[k]] = value[k] != fmi2False;
    return after_set(INST, nvr);
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    size_t k;
    if (c == NULL || check_refs(INST, vr, nvr, JF_STRING, 1) != fmi2OK) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        char *s = dup_string(value[k] ? value[k] : "");
        if (s == NULL) return fail(INST, "fmi2SetString: %s", "out of memory");
        free(INST->sv[vr[k]]);
        INST->sv[vr[k]] = s;
    }
    return after_set(INST, nvr);
}

/* ------------------------------------------------------------------ FMU state */

static uint64_t fnv1a(const unsigned char *p, size_t n) {
    uint64_t h = 0xcbf29ce484222325u;
    size_t i;
    for (i = 0; i < n; i++) {
        h ^= p[i];
        h *= 0x100000001b3u;
    }
    return h;
}

static size_t state_size(const JfInstance *inst) {
    return STATE_HEADER + JF_N_VR * (8u + 4u + 4u) + inst->n_state * 8u + 8u;
}

typedef struct {
    size_t size;
    unsigned char bytes[1];
} StateBlob;

static StateBlob *state_write(JfInstance *inst) {
    size_t n = state_size(inst), i;
    uint32_t head[6];
    int32_t word;
    unsigned char *p;
    uint64_t sum;
    char guid[64];
    StateBlob *blob = (StateBlob *)jf_alloc(inst, 1, sizeof(StateBlob) + n);
    if (blob == NULL) return NULL;
    blob->size = n;
    p = blob->bytes;
    memcpy(p, STATE_MAGIC, 8);
    head[0] = STATE_VERSION;
    head[1] = STATE_BOM;
    memcpy(p + 8, head, 8);
    memset(guid, 0, sizeof guid);
    strncpy(guid, JF_GUID, sizeof guid - 1);
    memcpy(p + 16, guid, 64);
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
    sum = fnv1a(blob->bytes, n - 8u);
    memcpy(p, &sum, 8);
    return blob;
}

/* Check every field of a serialised state before anything is written; 0 if valid. */
static int state_check(JfInstance *inst, const unsigned char *p, size_t n) {
    const unsigned char *start = p;
    uint32_t head[6];
    uint64_t sum;
    char guid[64];
    int32_t word;
    size_t i;
    if (n < STATE_HEADER + 8u || memcmp(p, STATE_MAGIC, 8) != 0) {
        jf_log(inst, 3, "FMU state rejected: not a jitterfmu native state (%lu bytes)",
               (unsigned long)n);
        return 1;
    }
    memcpy(head, p + 8, 8);
    if (head[1] != STATE_BOM) {
        jf_log(inst, 3, "FMU state rejected: saved on a machine of another byte order");
        return 1;
    }
    if (head[0] != STATE_VERSION) {
        jf_log(inst, 3, "FMU state rejected: layout version %u; expected %u", (unsigned)head[0],
               STATE_VERSION);
        return 1;
    }
    memset(guid, 0, sizeof guid);
    strncpy(guid, JF_GUID, sizeof guid - 1);
    if (memcmp(p + 16, guid, 64) != 0) {
        jf_log(inst, 3, "FMU state rejected: saved by another model (GUID differs from %s)",
               JF_GUID);
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
    if (sum != fnv1a(p, n - 8u)) {
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
}

/* Restore a state all or nothing: checked bytes, then the kernel's own check; a state the
 * kernel refuses is replaced by the instance's previous one. */
static fmi2Status state_read(JfInstance *inst, const unsigned char *p, size_t n) {
    StateBlob *before;
    if (state_check(inst, p, n) != 0) return fmi2Error;
    before = state_write(inst);
    if (before == NULL) return fmi2Error;
    state_apply(inst, p);
    if (model_state_restored(inst) != JF_OK) {
        state_apply(inst, before->bytes);
        (void)model_state_restored(inst);
        free(before);
        jf_log(inst, 3, "FMU state rejected by %s; its previous state is kept",
               inst->instance_name);
        return fmi2Error;
    }
    free(before);
    return fmi2OK;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    StateBlob *blob;
    if (c == NULL || FMUstate == NULL) return fmi2Error;
    blob = state_write(INST);
    if (blob == NULL) return fmi2Error;
    free(*FMUstate);
    *FMUstate = blob;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    const StateBlob *blob = (const StateBlob *)FMUstate;
    if (c == NULL || blob == NULL) return fmi2Error;
    return state_read(INST, blob->bytes, blob->size);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    (void)c;
    if (FMUstate == NULL) return fmi2OK;
    free(*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    const StateBlob *blob = (const StateBlob *)FMUstate;
    if (c == NULL || blob == NULL || size == NULL) return fmi2Error;
    *size = blob->size;
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size) {
    const StateBlob *blob = (const StateBlob *)FMUstate;
    if (c == NULL || blob == NULL || serializedState == NULL) return fmi2Error;
    if (size != blob->size)
        return fail(INST, "fmi2SerializeFMUstate: %s", "size differs from "
                    "fmi2SerializedFMUstateSize");
    memcpy(serializedState, blob->bytes, size);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    StateBlob *blob;
    if (c == NULL || serializedState == NULL || FMUstate == NULL) return fmi2Error;
    if (state_check(INST, (const unsigned char *)serializedState, size) != 0)
        return fmi2Error;
    blob = (StateBlob *)jf_alloc(INST, 1, sizeof(StateBlob) + size);
    if (blob == NULL) return fmi2Error;
    blob->size = size;
    memcpy(blob->bytes, serializedState, size);
    free(*FMUstate);
    *FMUstate = blob;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[],
                                        size_t nKnown, const fmi2Real dvKnown[],
                                        fmi2Real dvUnknown[]) {
    (void)vUnknown_ref;
    (void)nUnknown;
    (void)vKnown_ref;
    (void)nKnown;
    (void)dvKnown;
    (void)dvUnknown;
    if (c == NULL) return fmi2Error;
    return fail(INST, "fmi2GetDirectionalDerivative: %s", "not provided "
                "(providesDirectionalDerivative is false)");
}

/* ------------------------------------------------------------------ co-simulation */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    if (c == NULL) return fmi2Error;
    return fail(INST, "fmi2SetRealInputDerivatives: %s", "canInterpolateInputs is false");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    if (c == NULL) return fmi2Error;
    return fail(INST, "fmi2GetRealOutputDerivatives: %s", "maxOutputDerivativeOrder is 0");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c == NULL) return fmi2Error;
    if (INST->phase != JF_STEPPING)
        return fail(INST, "fmi2DoStep: %s", "not in step mode (initialise first, "
                    "and no step after an error or fmi2Terminate)");
    if (!(communicationStepSize > 0.0) || !isfinite(communicationStepSize) ||
        !isfinite(currentCommunicationPoint))
        return fail(INST, "fmi2DoStep: %s", "communication step must be positive and finite");
    return kernel_status(INST, model_do_step(INST, currentCommunicationPoint,
                                             communicationStepSize));
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    return fail(INST, "fmi2CancelStep: %s", "fmi2DoStep never returns fmi2Pending");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s;
    (void)value;
    if (c == NULL) return fmi2Error;
    return fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    (void)s;
    (void)value;
    if (c == NULL) return fmi2Error;
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s;
    (void)value;
    if (c == NULL) return fmi2Error;
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    if (c == NULL || value == NULL) return fmi2Error;
    if (s == fmi2Terminated) {
        *value = fmi2False;
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s;
    (void)value;
    if (c == NULL) return fmi2Error;
    return fmi2Discard;
}

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

int jf_same_step(double h, double known) {
    return fabs(h - known) <= JF_STEP_RTOL * fabs(known);
}
