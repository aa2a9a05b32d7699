/* A small FMI 2.0 co-simulation FMU modelled on the Reference FMU "Stair".
 *
 * counter = floor(t) + 1 at the end of each step.  When it reaches `limit` (vr 2,
 * default 10, i.e. at t = 9 s) fmi2DoStep returns fmi2Discard and
 * fmi2GetBooleanStatus(fmi2Terminated) reports true: the FMU asks the master to end
 * the simulation, having advanced to the end of that step (fmi2LastSuccessfulTime and
 * counter there, as the Reference FMU Stair does).  With `terminate` (vr 3) false it returns fmi2Discard without
 * asking to terminate (a step it could not complete).  Written for the tests; no FMI
 * headers are needed.
 */
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef void *fmi2Component;
typedef void *fmi2ComponentEnvironment;
typedef void *fmi2FMUstate;
typedef unsigned int fmi2ValueReference;
typedef double fmi2Real;
typedef int fmi2Integer;
typedef int fmi2Boolean;
typedef char fmi2Char;
typedef const fmi2Char *fmi2String;
typedef char fmi2Byte;
typedef enum { fmi2OK, fmi2Warning, fmi2Discard, fmi2Error, fmi2Fatal, fmi2Pending } fmi2Status;
typedef enum { fmi2ModelExchange, fmi2CoSimulation } fmi2Type;
typedef enum { fmi2DoStepStatus, fmi2PendingStatus, fmi2LastSuccessfulTime,
               fmi2Terminated } fmi2StatusKind;
typedef void (*fmi2CallbackLogger)(fmi2ComponentEnvironment, fmi2String, fmi2Status,
                                   fmi2String, fmi2String, ...);
typedef struct {
    fmi2CallbackLogger logger;
    void *(*allocateMemory)(size_t, size_t);
    void (*freeMemory)(void *);
    void (*stepFinished)(fmi2ComponentEnvironment, fmi2Status);
    fmi2ComponentEnvironment componentEnvironment;
} fmi2CallbackFunctions;

#define EXPORT __attribute__((visibility("default")))

typedef struct {
    double time;
    int counter;
    int limit;
    int terminate;
    int terminated;
    fmi2CallbackFunctions cb;
    char name[64];
} Stair;

EXPORT const char *fmi2GetTypesPlatform(void) { return "default"; }
EXPORT const char *fmi2GetVersion(void) { return "2.0"; }

EXPORT fmi2Component fmi2Instantiate(fmi2String name, fmi2Type type, fmi2String guid,
                                     fmi2String resources, const fmi2CallbackFunctions *cb,
                                     fmi2Boolean visible, fmi2Boolean loggingOn) {
    Stair *s;
    (void)guid; (void)resources; (void)visible; (void)loggingOn;
    if (type != fmi2CoSimulation) return NULL;
    s = calloc(1, sizeof *s);
    if (!s) return NULL;
    s->counter = 1;
    s->limit = 10;
    s->terminate = 1;
    if (cb) s->cb = *cb;
    strncpy(s->name, name ? name : "", sizeof s->name - 1);
    return s;
}

EXPORT void fmi2FreeInstance(fmi2Component c) { free(c); }
EXPORT fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean on, size_t n,
                                      const fmi2String cat[]) {
    (void)c; (void)on; (void)n; (void)cat; return fmi2OK;
}
EXPORT fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean tolDef, fmi2Real tol,
                                      fmi2Real start, fmi2Boolean stopDef, fmi2Real stop) {
    Stair *s = c;
    (void)tolDef; (void)tol; (void)stopDef; (void)stop;
    s->time = start;
    return fmi2OK;
}
EXPORT fmi2Status fmi2EnterInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2ExitInitializationMode(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2Terminate(fmi2Component c) { (void)c; return fmi2OK; }
EXPORT fmi2Status fmi2Reset(fmi2Component c) {
    Stair *s = c;
    s->time = 0; s->counter = 1; s->terminated = 0;
    return fmi2OK;
}

EXPORT fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                              fmi2Real v[]) {
    Stair *s = c;
    size_t i;
    for (i = 0; i < n; i++) {
        if (vr[i] != 0) return fmi2Error;
        v[i] = s->time;
    }
    return fmi2OK;
}
EXPORT fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                 fmi2Integer v[]) {
    Stair *s = c;
    size_t i;
    for (i = 0; i < n; i++) {
        if (vr[i] == 1) v[i] = s->counter;
        else if (vr[i] == 2) v[i] = s->limit;
        else return fmi2Error;
    }
    return fmi2OK;
}
EXPORT fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                 fmi2Boolean v[]) {
    Stair *s = c;
    size_t i;
    for (i = 0; i < n; i++) {
        if (vr[i] != 3) return fmi2Error;
        v[i] = s->terminate;
    }
    return fmi2OK;
}
EXPORT fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                fmi2String v[]) {
    (void)c; (void)vr; (void)v; return n ? fmi2Error : fmi2OK;
}
EXPORT fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                              const fmi2Real v[]) {
    (void)c; (void)vr; (void)v; return n ? fmi2Error : fmi2OK;
}
EXPORT fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                 const fmi2Integer v[]) {
    Stair *s = c;
    size_t i;
    for (i = 0; i < n; i++) {
        if (vr[i] != 2) return fmi2Error;
        s->limit = v[i];
    }
    return fmi2OK;
}
EXPORT fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                 const fmi2Boolean v[]) {
    Stair *s = c;
    size_t i;
    for (i = 0; i < n; i++) {
        if (vr[i] != 3) return fmi2Error;
        s->terminate = v[i] != 0;
    }
    return fmi2OK;
}
EXPORT fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t n,
                                const fmi2String v[]) {
    (void)c; (void)vr; (void)v; return n ? fmi2Error : fmi2OK;
}

EXPORT fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *st) {
    Stair *copy = malloc(sizeof(Stair));
    if (!copy) return fmi2Error;
    memcpy(copy, c, sizeof(Stair));
    *st = copy;
    return fmi2OK;
}
EXPORT fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate st) {
    memcpy(c, st, sizeof(Stair));
    return fmi2OK;
}
EXPORT fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *st) {
    (void)c; free(*st); *st = NULL; return fmi2OK;
}
EXPORT fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate st, size_t *n) {
    (void)c; (void)st; *n = 0; return fmi2Error;
}
EXPORT fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate st, fmi2Byte b[],
                                        size_t n) {
    (void)c; (void)st; (void)b; (void)n; return fmi2Error;
}
EXPORT fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte b[], size_t n,
                                          fmi2FMUstate *st) {
    (void)c; (void)b; (void)n; (void)st; return fmi2Error;
}
EXPORT fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference u[],
                                               size_t nu, const fmi2ValueReference z[],
                                               size_t nz, const fmi2Real dv[], fmi2Real dz[]) {
    (void)c; (void)u; (void)nu; (void)z; (void)nz; (void)dv; (void)dz; return fmi2Error;
}
EXPORT fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                              size_t n, const fmi2Integer o[],
                                              const fmi2Real v[]) {
    (void)c; (void)vr; (void)n; (void)o; (void)v; return fmi2Error;
}
EXPORT fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                               size_t n, const fmi2Integer o[], fmi2Real v[]) {
    (void)c; (void)vr; (void)n; (void)o; (void)v; return fmi2Error;
}

EXPORT fmi2Status fmi2DoStep(fmi2Component c, fmi2Real t, fmi2Real h, fmi2Boolean noSet) {
    Stair *s = c;
    int next;
    (void)noSet;
    if (s->terminated) return fmi2Error;
    next = (int)floor(t + h + 1e-9) + 1;
    if (next >= s->limit) {
        s->terminated = s->terminate;
        if (s->terminate) {  /* as the Reference FMU: it reached the event that ends it */
            s->time = t + h;
            s->counter = next;
        }
        if (s->cb.logger)
            s->cb.logger(s->cb.componentEnvironment, s->name, fmi2Discard, "logStatusDiscard",
                         s->terminate ? "counter reached %d: end of simulation"
                                      : "counter would reach %d: step discarded", s->limit);
        return fmi2Discard;
    }
    s->time = t + h;
    s->counter = next;
    return fmi2OK;
}
EXPORT fmi2Status fmi2CancelStep(fmi2Component c) { (void)c; return fmi2Error; }
EXPORT fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind k, fmi2Status *v) {
    (void)c; (void)k; (void)v; return fmi2Discard;
}
EXPORT fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind k, fmi2Real *v) {
    Stair *s = c;
    if (k != fmi2LastSuccessfulTime) return fmi2Discard;
    *v = s->time;
    return fmi2OK;
}
EXPORT fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind k,
                                       fmi2Integer *v) {
    (void)c; (void)k; (void)v; return fmi2Discard;
}
EXPORT fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind k,
                                       fmi2Boolean *v) {
    Stair *s = c;
    if (k != fmi2Terminated) return fmi2Discard;
    *v = s->terminated;
    return fmi2OK;
}
EXPORT fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind k,
                                      fmi2String *v) {
    (void)c; (void)k; (void)v; return fmi2Discard;
}
