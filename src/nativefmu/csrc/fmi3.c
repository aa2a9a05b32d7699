/* FMI 3.0 co-simulation API of a jitterfmu native FMU (C99, libc and libm only).
 *
 * The FMI 3.0 twin of fmi2.c: a thin layer over jfcore.c, which holds the variables, the
 * phases and the FMU state (its byte layout, the same as under FMI 2.0, is documented
 * at the top of jfcore.c), over the same model kernels.  FMI 2.0 Real, Integer, Boolean
 * and String variables are Float64, Int32, Boolean and String variables here, with the
 * same value references.  Co-simulation only, without event mode, intermediate updates,
 * early return or clocks; the functions of the other interface types and of the other
 * variable types are present (an FMI 3.0 binary exports every function) and answer
 * fmi3Error with a logged reason: fmi3_refusals.h, shared with container_fmi3.c.
 */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "jfcore.h"
#include "jfmu.h"
#include "model_config.h"

void jf_api_log(JfInstance *inst, int status, const char *category, const char *message) {
    fmi3LogMessageCallback log = (fmi3LogMessageCallback)inst->log_message;
    if (log == NULL) return;
    log((fmi3InstanceEnvironment)inst->environment, (fmi3Status)status, category, message);
}

#define INST ((JfInstance *)instance)
#define STATUS(x) ((x) == JF_OK ? fmi3OK : fmi3Error)

static fmi3Status fail(fmi3Instance instance, const char *fn, const char *why) {
    if (instance != NULL) jf_log(INST, 3, "%s: %s", fn, why);
    return fmi3Error;
}

/* resourcePath (a native path, ideally with a trailing separator) as the core keeps it. */
static char *resource_dir(fmi3String path) {
    size_t n;
    char *out;
    if (path == NULL) return NULL;
    n = strlen(path);
    out = (char *)malloc(n + 2);
    if (out == NULL) return NULL;
    memcpy(out, path, n + 1);
    if (n == 0 || (out[n - 1] != '/' && out[n - 1] != '\\')) {
        out[n] = '/';
        out[n + 1] = '\0';
    }
    return out;
}

/* ------------------------------------------------------------------ common functions */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                               size_t nCategories, const fmi3String categories[]) {
    (void)nCategories;
    (void)categories;
    if (instance == NULL) return fmi3Error;
    INST->logging_on = loggingOn != 0;
    return fmi3OK;
}

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    JfInstance *inst;
    (void)visible;
    (void)eventModeUsed;       /* hasEventMode is false: no event is ever signalled */
    (void)earlyReturnAllowed;  /* never returns early */
    (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;  /* providesIntermediateUpdate is false */
    inst = jf_instance_new(instanceName, loggingOn != 0);
    if (inst == NULL) return NULL;
    inst->environment = instanceEnvironment;
    inst->log_message = (void (*)(void))logMessage;
    if (jf_instance_setup(inst, instantiationToken, resource_dir(resourcePath)) != JF_OK) {
        jf_instance_free(inst);
        return NULL;
    }
    return inst;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName,
                                          fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    if (logMessage != NULL)
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   JF_MODEL_IDENTIFIER " supports co-simulation only");
    return NULL;
}

fmi3Instance fmi3InstantiateScheduledExecution(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
    fmi3LockPreemptionCallback lockPreemption, fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)clockUpdate;
    (void)lockPreemption;
    (void)unlockPreemption;
    return fmi3InstantiateModelExchange(instanceName, instantiationToken, resourcePath,
                                        visible, loggingOn, instanceEnvironment, logMessage);
}

void fmi3FreeInstance(fmi3Instance instance) { jf_instance_free(INST); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (instance == NULL) return fmi3Error;
    return STATUS(jf_enter_initialization(INST, startTime, "fmi3EnterInitializationMode"));
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    return STATUS(jf_exit_initialization(INST, "fmi3ExitInitializationMode"));
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    INST->phase = JF_TERMINATED;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    return STATUS(jf_instance_reset(INST));
}

/* ------------------------------------------------------------------ getters and setters */

/* Scalars only: one value per value reference. */
#define CHECK(type, setting, fn)                                                         \
    if (instance == NULL) return fmi3Error;                                               \
    if (nValues != nValueReferences)                                                      \
        return fail(instance, fn, "nValues differs from nValueReferences (every variable " \
                    "is a scalar)");                                                      \
    if (jf_check_refs(INST, valueReferences, nValueReferences, type, setting) != JF_OK)  \
        return fmi3Error

/* The independent variable `time` takes the value reference after every other one
 * (nativefmu.fmi3xml); its value is the current time, as FMI 3.0 says. */
#define TIME_VR ((fmi3ValueReference)JF_N_VR)

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    size_t k;
    if (instance == NULL) return fmi3Error;
    if (nValues != nValueReferences)
        return fail(instance, "fmi3GetFloat64", "nValues differs from nValueReferences "
                    "(every variable is a scalar)");
    for (k = 0; k < nValueReferences; k++) {
        if (valueReferences[k] == TIME_VR && INST->phase != JF_FAILED) {
            values[k] = INST->phase >= JF_INITIALIZATION ? INST->t_next : 0.0;
            continue;
        }
        if (jf_check_refs(INST, valueReferences + k, 1, JF_REAL, 0) != JF_OK) return fmi3Error;
        values[k] = INST->r[valueReferences[k]];
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Int32 values[], size_t nValues) {
    size_t k;
    CHECK(JF_INTEGER, 0, "fmi3GetInt32");
    for (k = 0; k < nValueReferences; k++) values[k] = (fmi3Int32)INST->iv[valueReferences[k]];
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    size_t k;
    CHECK(JF_BOOLEAN, 0, "fmi3GetBoolean");
    for (k = 0; k < nValueReferences; k++)
        values[k] = INST->bv[valueReferences[k]] ? fmi3True : fmi3False;
    return fmi3OK;
}

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, fmi3String values[], size_t nValues) {
    size_t k;
    CHECK(JF_STRING, 0, "fmi3GetString");
    for (k = 0; k < nValueReferences; k++) values[k] = INST->sv[valueReferences[k]];
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[],
                          size_t nValues) {
    size_t k;
    if (instance != NULL)
        for (k = 0; k < nValueReferences; k++)
            if (valueReferences[k] == TIME_VR)
                return fail(instance, "fmi3SetFloat64", "time is the independent variable "
                            "and cannot be set");
    CHECK(JF_REAL, 1, "fmi3SetFloat64");
    if (jf_check_reals(INST, valueReferences, nValueReferences, values, "fmi3SetFloat64") !=
        JF_OK)
        return fmi3Error;
    for (k = 0; k < nValueReferences; k++) INST->r[valueReferences[k]] = values[k];
    return STATUS(jf_after_set(INST, nValueReferences));
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Int32 values[], size_t nValues) {
    size_t k;
    CHECK(JF_INTEGER, 1, "fmi3SetInt32");
    for (k = 0; k < nValueReferences; k++) INST->iv[valueReferences[k]] = (int)values[k];
    return STATUS(jf_after_set(INST, nValueReferences));
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Boolean values[],
                          size_t nValues) {
    size_t k;
    CHECK(JF_BOOLEAN, 1, "fmi3SetBoolean");
    for (k = 0; k < nValueReferences; k++) INST->bv[valueReferences[k]] = values[k] != 0;
    return STATUS(jf_after_set(INST, nValueReferences));
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const fmi3String values[], size_t nValues) {
    size_t k;
    CHECK(JF_STRING, 1, "fmi3SetString");
    for (k = 0; k < nValueReferences; k++)
        if (jf_set_string(INST, valueReferences[k], values[k]) != JF_OK) return fmi3Error;
    return STATUS(jf_after_set(INST, nValueReferences));
}

/* Types this model has no variable of. */
static fmi3Status no_such_type(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               const char *type) {
    if (instance == NULL) return fmi3Error;
    if (nvr == 0) return fmi3OK;
    jf_log(INST, 3, "value reference %u is not a variable of type %s (this model has none)",
           (unsigned)vr[0], type);
    return fmi3Error;
}

/* ------------------------------------------------------------------ FMU state */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    JfState *blob;
    if (instance == NULL || FMUState == NULL) return fmi3Error;
    blob = jf_state_save(INST);
    if (blob == NULL) return fmi3Error;
    free(*FMUState);
    *FMUState = blob;
    return fmi3OK;
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    const JfState *blob = (const JfState *)FMUState;
    if (instance == NULL || blob == NULL) return fmi3Error;
    return STATUS(jf_state_restore(INST, blob->bytes, blob->size));
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    (void)instance;
    if (FMUState == NULL) return fmi3OK;
    free(*FMUState);
    *FMUState = NULL;
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                      size_t *size) {
    const JfState *blob = (const JfState *)FMUState;
    if (instance == NULL || blob == NULL || size == NULL) return fmi3Error;
    *size = blob->size;
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size) {
    const JfState *blob = (const JfState *)FMUState;
    if (instance == NULL || blob == NULL || serializedState == NULL) return fmi3Error;
    if (size != blob->size)
        return fail(instance, "fmi3SerializeFMUState", "size differs from "
                    "fmi3SerializedFMUStateSize");
    memcpy(serializedState, blob->bytes, size);
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState) {
    JfState *blob;
    if (instance == NULL || serializedState == NULL || FMUState == NULL) return fmi3Error;
    blob = jf_state_copy(INST, (const unsigned char *)serializedState, size);
    if (blob == NULL) return fmi3Error;
    free(*FMUState);
    *FMUState = blob;
    return fmi3OK;
}

/* ------------------------------------------------------------------ refused functions */

#define JF3_SUBJECT "the model"
#define JF3_REFUSE(fn, why) return fail(instance, fn, why)
#include "fmi3_refusals.h"

/* ------------------------------------------------------------------ co-simulation */

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    int st;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (instance == NULL) return fmi3Error;
    if (eventHandlingNeeded != NULL) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation != NULL) *terminateSimulation = fmi3False;
    if (earlyReturn != NULL) *earlyReturn = fmi3False;
    st = jf_do_step(INST, currentCommunicationPoint, communicationStepSize, "fmi3DoStep");
    /* FMI 3.0: an output the model cannot vouch for is an error, never NaN with OK (the
     * FMI 2.0 build leaves that check to its master, which names the diverging loop) */
    if (st == JF_OK) st = jf_check_outputs(INST, "fmi3DoStep", 1);
    if (lastSuccessfulTime != NULL)
        *lastSuccessfulTime = st == JF_OK ? currentCommunicationPoint + communicationStepSize
                                          : currentCommunicationPoint;
    return STATUS(st);
}
