/* FMI 3.0 co-simulation API of a container FMU (C99, libc and libm only).
 *
 * The FMI 3.0 twin of container.c's API, and a thin layer over it the way fmi3.c is over
 * jfcore.c: container.c, compiled with its FMI 2.0 functions renamed ct2_fmi2... in an
 * FMI 3.0 container (container_fmi2.h), keeps the inner FMI 2.0 units, the schedule, the
 * tick count and the FMU state; this file maps each FMI 3.0 call onto those functions.
 * Float64, Int32, Boolean and String variables are the container's Real, Integer,
 * Boolean and String ones with the same value references; `time` (the independent
 * variable, after every other value reference) reads the tick's exact time.
 * The host's logMessage receives everything container.c and the inner units log,
 * through an FMI 2.0 logger kept in the instance.  Co-simulation only, without event
 * mode, intermediate updates, early return or clocks; the functions of the other
 * interface types and variable types are present and answer fmi3Error with a logged
 * reason (fmi3_refusals.h, shared with fmi3.c).
 */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "fmi3Functions.h"
#include "container_fmi2.h"

typedef struct {
    fmi2CallbackFunctions cb;    /* what container.c and the inner units log through */
    fmi3InstanceEnvironment env;
    fmi3LogMessageCallback log;
    char *name;
    fmi2Component c;             /* container.c's instance */
} Ct3;

#define W ((Ct3 *)instance)

/* The FMI 3.0 status of an FMI 2.0 one (container.c answers OK, Warning, Discard or
 * Error; anything above Warning is an error here). */
static fmi3Status STATUS(fmi2Status st) {
    return st == fmi2OK ? fmi3OK : st == fmi2Warning ? fmi3Warning : fmi3Error;
}

static void say(const Ct3 *w, fmi3Status status, const char *message) {
    static const char *categories[] = {"logAll", "logStatusWarning", "logStatusDiscard",
                                       "logStatusError", "logStatusFatal"};
    if (w != NULL && w->log != NULL)
        w->log(w->env, status, categories[status > fmi3Fatal ? fmi3Fatal : status], message);
}

/* The FMI 2.0 logger of container.c and the inner units: formatted, prefixed with the
 * inner instance's name when it is not the container's, and handed to logMessage. */
static void fmi2_logger(fmi2ComponentEnvironment env, fmi2String name, fmi2Status status,
                 fmi2String category, fmi2String message, ...) {
    const Ct3 *w = (const Ct3 *)env;
    char text[2048];
    int n = 0;
    va_list ap;
    if (w == NULL || w->log == NULL || message == NULL) return;
    if (name != NULL && w->name != NULL && strcmp(name, w->name) != 0)
        n = snprintf(text, sizeof text, "%s: ", name);
    if (n < 0 || (size_t)n >= sizeof text) n = 0;
    va_start(ap, message);
    vsnprintf(text + n, sizeof text - (size_t)n, message, ap);
    va_end(ap);
    w->log(w->env, status > fmi2Fatal ? fmi3Error : (fmi3Status)status,
           category != NULL ? category : "logAll", text);
}

static fmi3Status fail(fmi3Instance instance, const char *fn, const char *why) {
    char text[1024];
    if (instance == NULL) return fmi3Error;
    snprintf(text, sizeof text, "%s: %s", fn, why);
    say(W, fmi3Error, text);
    return fmi3Error;
}

/* resourcePath (a native path) as the file URI container.c hands on to the inner units
 * (which percent-decode it): unreserved characters kept, '\\' as '/', the rest %XX. */
static char *resource_uri(fmi3String path) {
    static const char hex[] = "0123456789ABCDEF";
    size_t n, i;
    char *out, *q;
    if (path == NULL) return NULL;
    n = strlen(path);
    out = (char *)malloc(3 * n + 10);
    if (out == NULL) return NULL;
    q = out;
    memcpy(q, "file://", 7);
    q += 7;
    if (path[0] != '/' && path[0] != '\\') *q++ = '/';   /* C:\... -> file:///C:/... */
    for (i = 0; i < n; i++) {
        unsigned char ch = (unsigned char)path[i];
        if ((ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') ||
            strchr("/-._~:", ch) != NULL) {
            *q++ = (char)ch;
        } else if (ch == '\\') {
            *q++ = '/';
        } else {
            *q++ = '%';
            *q++ = hex[ch >> 4];
            *q++ = hex[ch & 15];
        }
    }
    *q = '\0';
    return out;
}

/* ------------------------------------------------------------------ common functions */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn,
                               size_t nCategories, const fmi3String categories[]) {
    if (instance == NULL) return fmi3Error;
    return STATUS(fmi2SetDebugLogging(W->c, loggingOn ? fmi2True : fmi2False, nCategories,
                                      categories));
}

fmi3Instance fmi3InstantiateCoSimulation(
    fmi3String instanceName, fmi3String instantiationToken, fmi3String resourcePath,
    fmi3Boolean visible, fmi3Boolean loggingOn, fmi3Boolean eventModeUsed,
    fmi3Boolean earlyReturnAllowed, const fmi3ValueReference requiredIntermediateVariables[],
    size_t nRequiredIntermediateVariables, fmi3InstanceEnvironment instanceEnvironment,
    fmi3LogMessageCallback logMessage, fmi3IntermediateUpdateCallback intermediateUpdate) {
    Ct3 *w;
    char *uri;
    const char *name = instanceName != NULL ? instanceName : "";
    (void)eventModeUsed;       /* hasEventMode is false: no event is ever signalled */
    (void)earlyReturnAllowed;  /* never returns early */
    (void)requiredIntermediateVariables;
    (void)nRequiredIntermediateVariables;
    (void)intermediateUpdate;  /* providesIntermediateUpdate is false */
    w = (Ct3 *)calloc(1, sizeof(Ct3));
    if (w == NULL) return NULL;
    {
        fmi2CallbackFunctions cb = {fmi2_logger, calloc, free, NULL, NULL};
        cb.componentEnvironment = w;
        memcpy(&w->cb, &cb, sizeof cb);
    }
    w->env = instanceEnvironment;
    w->log = logMessage;
    w->name = (char *)malloc(strlen(name) + 1);
    if (w->name != NULL) memcpy(w->name, name, strlen(name) + 1);
    uri = resource_uri(resourcePath);
    if (resourcePath == NULL) {
        char text[256];
        snprintf(text, sizeof text, "%s needs its resourcePath (the unzipped FMU's "
                 "resources/ folder)", ct2_model_identifier);
        say(w, fmi3Error, text);
    }
    if (w->name != NULL && uri != NULL)
        w->c = fmi2Instantiate(name, fmi2CoSimulation, instantiationToken, uri, &w->cb,
                               visible ? fmi2True : fmi2False,
                               loggingOn ? fmi2True : fmi2False);
    free(uri);
    if (w->c == NULL) {
        free(w->name);
        free(w);
        return NULL;
    }
    return w;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName,
                                          fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible,
                                          fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    char text[256];
    (void)instanceName;
    (void)instantiationToken;
    (void)resourcePath;
    (void)visible;
    (void)loggingOn;
    snprintf(text, sizeof text, "%s supports co-simulation only", ct2_model_identifier);
    if (logMessage != NULL) logMessage(instanceEnvironment, fmi3Error, "logStatusError", text);
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

void fmi3FreeInstance(fmi3Instance instance) {
    if (instance == NULL) return;
    fmi2FreeInstance(W->c);
    free(W->name);
    free(W);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined,
                                       fmi3Float64 tolerance, fmi3Float64 startTime,
                                       fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    fmi2Status st;
    if (instance == NULL) return fmi3Error;
    st = fmi2SetupExperiment(W->c, toleranceDefined ? fmi2True : fmi2False, tolerance,
                             startTime, stopTimeDefined ? fmi2True : fmi2False, stopTime);
    if (st > fmi2Warning) return fmi3Error;
    return STATUS(fmi2EnterInitializationMode(W->c));
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    return STATUS(fmi2ExitInitializationMode(W->c));
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    return STATUS(fmi2Terminate(W->c));
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    if (instance == NULL) return fmi3Error;
    return STATUS(fmi2Reset(W->c));
}

/* ------------------------------------------------------------------ getters and setters */

/* Scalars only: one value per value reference. */
#define CHECK(fn)                                                                         \
    if (instance == NULL) return fmi3Error;                                               \
    if (nValues != nValueReferences)                                                      \
        return fail(instance, fn, "nValues differs from nValueReferences (every variable " \
                    "is a scalar)")

static int has_time(const fmi3ValueReference vr[], size_t n) {
    size_t k;
    for (k = 0; k < n; k++)
        if (vr[k] == ct2_time_vr) return 1;
    return 0;
}

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Float64 values[], size_t nValues) {
    size_t k;
    CHECK("fmi3GetFloat64");
    if (!has_time(valueReferences, nValueReferences))
        return STATUS(fmi2GetReal(W->c, valueReferences, nValueReferences, values));
    for (k = 0; k < nValueReferences; k++) {
        fmi2Status st = valueReferences[k] == ct2_time_vr
            ? fmi2GetRealStatus(W->c, fmi2LastSuccessfulTime, &values[k])
            : fmi2GetReal(W->c, &valueReferences[k], 1, &values[k]);
        if (st > fmi2Warning) return fmi3Error;
    }
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, fmi3Int32 values[], size_t nValues) {
    size_t k;
    CHECK("fmi3GetInt32");
    for (k = 0; k < nValueReferences; k++) {
        fmi2Integer x = 0;
        if (fmi2GetInteger(W->c, &valueReferences[k], 1, &x) > fmi2Warning) return fmi3Error;
        values[k] = (fmi3Int32)x;
    }
    return fmi3OK;
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, fmi3Boolean values[], size_t nValues) {
    size_t k;
    CHECK("fmi3GetBoolean");
    for (k = 0; k < nValueReferences; k++) {
        fmi2Boolean x = fmi2False;
        if (fmi2GetBoolean(W->c, &valueReferences[k], 1, &x) > fmi2Warning) return fmi3Error;
        values[k] = x ? fmi3True : fmi3False;
    }
    return fmi3OK;
}

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, fmi3String values[], size_t nValues) {
    CHECK("fmi3GetString");
    return STATUS(fmi2GetString(W->c, valueReferences, nValueReferences, values));
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Float64 values[],
                          size_t nValues) {
    CHECK("fmi3SetFloat64");
    if (has_time(valueReferences, nValueReferences))
        return fail(instance, "fmi3SetFloat64", "time is the independent variable and cannot "
                    "be set");
    return STATUS(fmi2SetReal(W->c, valueReferences, nValueReferences, values));
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                        size_t nValueReferences, const fmi3Int32 values[], size_t nValues) {
    size_t k;
    CHECK("fmi3SetInt32");
    for (k = 0; k < nValueReferences; k++) {
        fmi2Integer x = (fmi2Integer)values[k];
        if (fmi2SetInteger(W->c, &valueReferences[k], 1, &x) > fmi2Warning) return fmi3Error;
    }
    return fmi3OK;
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                          size_t nValueReferences, const fmi3Boolean values[],
                          size_t nValues) {
    size_t k;
    CHECK("fmi3SetBoolean");
    for (k = 0; k < nValueReferences; k++) {
        fmi2Boolean x = values[k] ? fmi2True : fmi2False;
        if (fmi2SetBoolean(W->c, &valueReferences[k], 1, &x) > fmi2Warning) return fmi3Error;
    }
    return fmi3OK;
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference valueReferences[],
                         size_t nValueReferences, const fmi3String values[], size_t nValues) {
    CHECK("fmi3SetString");
    return STATUS(fmi2SetString(W->c, valueReferences, nValueReferences, values));
}

/* Types the container has no variable of. */
static fmi3Status no_such_type(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               const char *type) {
    char text[160];
    if (instance == NULL) return fmi3Error;
    if (nvr == 0) return fmi3OK;
    snprintf(text, sizeof text, "value reference %u is not a variable of type %s (this "
             "container has none)", (unsigned)vr[0], type);
    say(W, fmi3Error, text);
    return fmi3Error;
}

/* ------------------------------------------------------------------ FMU state */

/* container.c's state (its layout is documented there), under the FMI 3.0 names. */
fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    if (instance == NULL) return fmi3Error;
    return STATUS(fmi2GetFMUstate(W->c, FMUState));
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    if (instance == NULL) return fmi3Error;
    return STATUS(fmi2SetFMUstate(W->c, FMUState));
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    return STATUS(fmi2FreeFMUstate(instance == NULL ? NULL : W->c, FMUState));
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState,
                                      size_t *size) {
    if (instance == NULL) return fmi3Error;
    return STATUS(fmi2SerializedFMUstateSize(W->c, FMUState, size));
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState,
                                 fmi3Byte serializedState[], size_t size) {
    if (instance == NULL) return fmi3Error;
    return STATUS(fmi2SerializeFMUstate(W->c, FMUState, (fmi2Byte *)serializedState, size));
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[],
                                   size_t size, fmi3FMUState *FMUState) {
    if (instance == NULL) return fmi3Error;
    return STATUS(fmi2DeSerializeFMUstate(W->c, (const fmi2Byte *)serializedState, size,
                                          FMUState));
}

/* ------------------------------------------------------------------ refused functions */

#define JF3_SUBJECT "the container"
#define JF3_REFUSE(fn, why) return fail(instance, fn, why)
#include "fmi3_refusals.h"

/* ------------------------------------------------------------------ co-simulation */

/* A step of m base ticks (container.c refuses any other, naming the allowed steps). */
fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize,
                      fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation,
                      fmi3Boolean *earlyReturn, fmi3Float64 *lastSuccessfulTime) {
    fmi2Status st;
    if (instance == NULL) return fmi3Error;
    if (eventHandlingNeeded != NULL) *eventHandlingNeeded = fmi3False;
    if (terminateSimulation != NULL) *terminateSimulation = fmi3False;
    if (earlyReturn != NULL) *earlyReturn = fmi3False;
    st = fmi2DoStep(W->c, currentCommunicationPoint, communicationStepSize,
                    noSetFMUStatePriorToCurrentPoint ? fmi2True : fmi2False);
    if (lastSuccessfulTime != NULL)
        *lastSuccessfulTime = st <= fmi2Warning
            ? currentCommunicationPoint + communicationStepSize : currentCommunicationPoint;
    return STATUS(st);
}
