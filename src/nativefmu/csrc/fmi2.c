/* FMI 2.0 co-simulation API of a jitterfmu native FMU (C99, libc and libm only).
 *
 * A thin layer over jfcore.c, which holds the variables, the phases and the FMU state
 * (its byte layout is documented at the top of jfcore.c); fmi3.c is the FMI 3.0 twin
 * of this file over the same core.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "jfcore.h"
#include "jfmu.h"
#include "model_config.h"

void jf_api_log(JfInstance *inst, int status, const char *category, const char *message) {
    const fmi2CallbackFunctions *cb = (const fmi2CallbackFunctions *)inst->callbacks;
    if (cb == NULL || cb->logger == NULL) return;
    cb->logger(cb->componentEnvironment, inst->instance_name, (fmi2Status)status, category,
               "%s", message);
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

#define INST ((JfInstance *)c)
#define STATUS(x) ((x) == JF_OK ? fmi2OK : fmi2Error)

static fmi2Status fail(JfInstance *inst, const char *fmt, const char *what) {
    jf_log(inst, 3, fmt, what);
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
    inst = jf_instance_new(instanceName, loggingOn != 0);
    if (inst == NULL) return NULL;
    inst->callbacks = functions;
    if (fmuType != fmi2CoSimulation) {
        jf_log(inst, 3, "%s supports co-simulation only", JF_MODEL_IDENTIFIER);
        jf_instance_free(inst);
        return NULL;
    }
    if (jf_instance_setup(inst, fmuGUID, uri_to_path(fmuResourceLocation)) != JF_OK) {
        jf_instance_free(inst);
        return NULL;
    }
    return inst;
}

void fmi2FreeInstance(fmi2Component c) { jf_instance_free(INST); }

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
    return STATUS(jf_enter_initialization(INST, INST->start_time,
                                          "fmi2EnterInitializationMode"));
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    return STATUS(jf_exit_initialization(INST, "fmi2ExitInitializationMode"));
}

fmi2Status fmi2Terminate(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    INST->phase = JF_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    return STATUS(jf_instance_reset(INST));
}

/* ------------------------------------------------------------------ getters and setters */

#define CHECK(type, setting) \
    if (c == NULL || jf_check_refs(INST, vr, nvr, type, setting) != JF_OK) return fmi2Error

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    size_t k;
    CHECK(JF_REAL, 0);
    for (k = 0; k < nvr; k++) value[k] = INST->r[vr[k]];
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    size_t k;
    CHECK(JF_INTEGER, 0);
    for (k = 0; k < nvr; k++) value[k] = INST->iv[vr[k]];
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    size_t k;
    CHECK(JF_BOOLEAN, 0);
    for (k = 0; k < nvr; k++) value[k] = INST->bv[vr[k]] ? fmi2True : fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    size_t k;
    CHECK(JF_STRING, 0);
    for (k = 0; k < nvr; k++) value[k] = INST->sv[vr[k]];
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    size_t k;
    CHECK(JF_REAL, 1);
    if (jf_check_reals(INST, vr, nvr, value, "fmi2SetReal") != JF_OK) return fmi2Error;
    for (k = 0; k < nvr; k++) INST->r[vr[k]] = value[k];
    return STATUS(jf_after_set(INST, nvr));
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    size_t k;
    CHECK(JF_INTEGER, 1);
    for (k = 0; k < nvr; k++) INST->iv[vr[k]] = value[k];
    return STATUS(jf_after_set(INST, nvr));
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    size_t k;
    CHECK(JF_BOOLEAN, 1);
    for (k = 0; k < nvr; k++) INST->bv[vr[k]] = value[k] != fmi2False;
    return STATUS(jf_after_set(INST, nvr));
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    size_t k;
    CHECK(JF_STRING, 1);
    for (k = 0; k < nvr; k++)
        if (jf_set_string(INST, vr[k], value[k]) != JF_OK) return fmi2Error;
    return STATUS(jf_after_set(INST, nvr));
}

/* ------------------------------------------------------------------ FMU state */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    JfState *blob;
    if (c == NULL || FMUstate == NULL) return fmi2Error;
    blob = jf_state_save(INST);
    if (blob == NULL) return fmi2Error;
    free(*FMUstate);
    *FMUstate = blob;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    const JfState *blob = (const JfState *)FMUstate;
    if (c == NULL || blob == NULL) return fmi2Error;
    return STATUS(jf_state_restore(INST, blob->bytes, blob->size));
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    (void)c;
    if (FMUstate == NULL) return fmi2OK;
    free(*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    const JfState *blob = (const JfState *)FMUstate;
    if (c == NULL || blob == NULL || size == NULL) return fmi2Error;
    *size = blob->size;
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate,
                                 fmi2Byte serializedState[], size_t size) {
    const JfState *blob = (const JfState *)FMUstate;
    if (c == NULL || blob == NULL || serializedState == NULL) return fmi2Error;
    if (size != blob->size)
        return fail(INST, "fmi2SerializeFMUstate: %s", "size differs from "
                    "fmi2SerializedFMUstateSize");
    memcpy(serializedState, blob->bytes, size);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    JfState *blob;
    if (c == NULL || serializedState == NULL || FMUstate == NULL) return fmi2Error;
    blob = jf_state_copy(INST, (const unsigned char *)serializedState, size);
    if (blob == NULL) return fmi2Error;
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
    int st;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c == NULL) return fmi2Error;
    st = jf_do_step(INST, currentCommunicationPoint, communicationStepSize, "fmi2DoStep");
    /* never NaN or inf with OK; the declared ranges the master checks itself, naming the
     * diverging loop */
    if (st == JF_OK) st = jf_check_outputs(INST, "fmi2DoStep", 0);
    return STATUS(st);
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
