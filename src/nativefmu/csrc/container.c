/* A scenario as one FMI 2.0 co-simulation FMU (C99, libc and libm only); under FMI 3.0
 * the same code behind container_fmi3.c (its FMI 2.0 API renamed, container_fmi2.h).
 *
 * The inner FMUs are the scenario's native FMUs, compiled into this binary with their
 * FMI functions and model symbols renamed (uN_fmi2DoStep, ...; jfmu_names.h).  The
 * master's schedule comes from Python as generated tables (container_data.h): the
 * bus slots, the raw FMI calls of every tick of the hyperperiod and the order of the
 * initialisation, exactly as orchestrator.cosim.fastloop builds them.  This file fills
 * fastloop.c's tables with the inner functions and instances and runs them with
 * fastloop_snapshot / fastloop_calls / fastloop_check, so a doStep of m base ticks
 * makes the calls `jitterfmu run` makes over those ticks, in the same order.
 *
 * Time inside is the tick count k: t_k = (A + k B) / D, correctly rounded, as the
 * master computes it; a step must end on the tick grid, judged with a tolerance that
 * grows with the host's accumulated time (host_tolerance: a host that adds t += h and
 * shortens its last step to land on its stop time is off by some ulps per step taken),
 * and take at most CT_MAX_STEP_TICKS ticks.
 * After fmi2ExitInitializationMode and after every doStep, the first phase of the
 * current tick has run (inputs set, feedthrough outputs read), so the outputs are the
 * master's recorded values at t_k; setting an input marks that phase stale and it runs
 * again before the next read or step.
 *
 * FMU state: one byte layout, checked field by field before anything is written:
 *
 *   offset  size        field
 *   0       8           magic "JFCONTNR"
 *   8       4           layout version (uint32, 1)
 *   12      4           byte-order mark 0x01020304 (uint32, host order)
 *   16      64          GUID of this container, zero padded
 *   80      4 x 4       number of instances, number of bus values, phase, stale (uint32)
 *   96      8           tick (int64)
 *   104     8 x 3n      the bus (double)
 *   ...     per inner instance: size (uint64), then its serialised FMU state
 *   end-8   8           FNV-1a 64 checksum of every byte before it
 *
 * Each inner state is validated by its own fmi2DeSerializeFMUstate before any instance
 * is changed; if one inner fmi2SetFMUstate still refuses, the instances already set get
 * their previous states back, so a refused state changes nothing.
 */
#include <math.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define FASTLOOP_TYPES_ONLY
#include "fastloop.c"
#include "fmi2Functions.h"
#include "jfstate.h"

enum { CT_REAL = 0, CT_INTEGER = 1, CT_BOOLEAN = 2, CT_STRING = 3 };
enum { CT_OUTPUT = 0, CT_INPUT = 1, CT_PARAMETER = 2 };
enum { FN_GET_REAL = 0, FN_GET_INTEGER, FN_GET_BOOLEAN, FN_SET_REAL, FN_SET_INTEGER,
       FN_SET_BOOLEAN, FN_DO_STEP };

typedef struct {
    fmi2InstantiateTYPE *instantiate;
    fmi2FreeInstanceTYPE *free_instance;
    fmi2SetupExperimentTYPE *setup_experiment;
    fmi2EnterInitializationModeTYPE *enter_init;
    fmi2ExitInitializationModeTYPE *exit_init;
    fmi2TerminateTYPE *terminate;
    fmi2ResetTYPE *reset;
    fmi2SetDebugLoggingTYPE *set_debug_logging;
    fmi2GetRealTYPE *get_real;
    fmi2GetIntegerTYPE *get_integer;
    fmi2GetBooleanTYPE *get_boolean;
    fmi2GetStringTYPE *get_string;
    fmi2SetRealTYPE *set_real;
    fmi2SetIntegerTYPE *set_integer;
    fmi2SetBooleanTYPE *set_boolean;
    fmi2SetStringTYPE *set_string;
    fmi2DoStepTYPE *do_step;
    fmi2GetFMUstateTYPE *get_state;
    fmi2SetFMUstateTYPE *set_state;
    fmi2FreeFMUstateTYPE *free_state;
    fmi2SerializedFMUstateSizeTYPE *state_size;
    fmi2SerializeFMUstateTYPE *serialize;
    fmi2DeSerializeFMUstateTYPE *deserialize;
} ct_unit;

typedef struct {
    const char *name;    /* scenario instance */
    int unit;
    const char *guid;    /* of its FMU */
    const char *res;     /* its resources, below the container's */
    double h;            /* communication step (s) */
    int read0, read1;    /* reading its outputs into the latest view: CT_READS[read0..read1) */
    int write0, write1;  /* setting its connected inputs: CT_WRITES[write0..write1) */
} ct_inst;

typedef struct {
    int kind;            /* fastloop.c READ_REAL ... DO_STEP */
    int fn;              /* FN_GET_REAL ... FN_DO_STEP */
    int inst;
    int nv;
    int start;           /* reads: first bus index */
    int off;             /* into CT_VR, CT_IDX, CT_GAIN, CT_OFFSET */
    int scaled;
} ct_part;

typedef struct {
    const char *name;
    int type;
    int causality;
    int inst;            /* inputs and parameters: the inner instance and variable */
    unsigned int ivr;
    int slot;            /* outputs: index into the bus */
} ct_var;

typedef struct {
    int inst;
    int type;
    unsigned int vr;
    double value;
    const char *text;
} ct_value;

typedef struct {
    int64_t tick;
    ct_value value;
} ct_action;

#include "container_data.h"

#ifndef CT_FMI_VERSION
#define CT_FMI_VERSION 2
#endif
#if CT_FMI_VERSION == 3
/* An FMI 3.0 container: the FMI 2.0 API below is internal (ct2_fmi2...), called by
 * container_fmi3.c. */
#include "container_fmi2.h"
const unsigned int ct2_time_vr = CT_N_VARS;
const char *const ct2_model_identifier = CT_MODEL_IDENTIFIER;
#endif

/* The host's names of the functions the messages below name. */
#if CT_FMI_VERSION == 3
#define CT_FN_DOSTEP "fmi3DoStep"
#define CT_FN_SETUPEXPERIMENT "fmi3EnterInitializationMode"
#define CT_FN_ENTERINITIALIZATIONMODE "fmi3EnterInitializationMode"
#define CT_FN_INSTANTIATE "fmi3InstantiateCoSimulation"
#define CT_FN_EXITINITIALIZATIONMODE "fmi3ExitInitializationMode"
#define CT_FN_RESET "fmi3Reset"
#else
#define CT_FN_DOSTEP "fmi2DoStep"
#define CT_FN_SETUPEXPERIMENT "fmi2SetupExperiment"
#define CT_FN_ENTERINITIALIZATIONMODE "fmi2EnterInitializationMode"
#define CT_FN_INSTANTIATE "fmi2Instantiate"
#define CT_FN_EXITINITIALIZATIONMODE "fmi2ExitInitializationMode"
#define CT_FN_RESET "fmi2Reset"
#endif

enum { PH_INSTANTIATED = 0, PH_INITIALIZATION = 1, PH_STEPPING = 2, PH_TERMINATED = 3,
       PH_FAILED = 4 };

typedef struct {
    char *name;
    char *resources;             /* the container's resource URI, with a trailing '/' */
    const fmi2CallbackFunctions *cb;
    int logging;
    int phase;
    int stale;                   /* inputs changed since the current tick's first phase */
    int64_t tick;
    fmi2Component comp[CT_N_INST];
    part_t parts[CT_N_PARTS];
    double fbuf[CT_N_BUF];
    int32_t ibuf[CT_N_BUF];
    double values[3 * CT_N_SLOTS];
    int64_t flag_ticks[1], flag_first[1];
    double rec[1];
    int64_t rec_idx[1];
    loop_t loop;
    result_t res;
} Container;

#define C ((Container *)c)

static void ct_log(const Container *ct, int status, const char *fmt, ...) {
    char buf[1024];
    va_list ap;
    static const char *categories[] = {"logAll", "logStatusWarning", "logStatusDiscard",
                                       "logStatusError", "logStatusFatal"};
    if (ct == NULL || ct->cb == NULL || ct->cb->logger == NULL) return;
    if (status < 3 && !ct->logging) return;
    va_start(ap, fmt);
    vsnprintf(buf, sizeof buf, fmt, ap);
    va_end(ap);
    ct->cb->logger(ct->cb->componentEnvironment, ct->name, (fmi2Status)status,
                   categories[status], "%s", buf);
}

static fmi2Status failed(Container *ct, const char *fmt, const char *what) {
    ct_log(ct, 3, fmt, what);
    return fmi2Error;
}

static char *dup_string(const char *s) {
    size_t n = strlen(s);
    char *out = (char *)malloc(n + 1);
    if (out != NULL) memcpy(out, s, n + 1);
    return out;
}

/* The most ticks one doStep takes (its work is bounded: a longer step is refused, not
 * hung on); CT_MAX_TICK (container_data.h) is the last tick whose time is exact. */
#define CT_MAX_STEP_TICKS INT64_C(10000000)

/* How far a host's time t may be from a tick after steps of h: 1e-6 of a base step plus
 * a few ulps of t per step taken, never a quarter of a base step. */
static double host_tolerance(double t, double h) {
    double tol;
    if (!(h > CT_BASE_STEP)) h = CT_BASE_STEP;   /* a host's last, shortened step */
    tol = 1e-6 * CT_BASE_STEP + 4.0 * 2.220446049250313e-16 * fabs(t) * (1.0 + fabs(t) / h);
    return tol < 0.25 * CT_BASE_STEP ? tol : 0.25 * CT_BASE_STEP;
}

/* t_k exactly rounded: (A + k B) / D with A + k B and D exact in a double. */
static double tick_time(int64_t k) {
    return (double)(CT_TIME_A + k * CT_TIME_B) / (double)CT_TIME_D;
}

static fmi2Status set_value(Container *ct, const ct_value *v) {
    const ct_unit *u = &CT_UNITS[CT_INSTS[v->inst].unit];
    fmi2Component comp = ct->comp[v->inst];
    fmi2Integer iv = (fmi2Integer)v->value;
    fmi2Boolean bv = v->value != 0.0;
    switch (v->type) {
    case CT_REAL: return u->set_real(comp, &v->vr, 1, &v->value);
    case CT_INTEGER: return u->set_integer(comp, &v->vr, 1, &iv);
    case CT_BOOLEAN: return u->set_boolean(comp, &v->vr, 1, &bv);
    default: return u->set_string(comp, &v->vr, 1, &v->text);
    }
}

static fastloop_fn part_fn(const ct_unit *u, int fn) {
    switch (fn) {
    case FN_GET_REAL: return (fastloop_fn)u->get_real;
    case FN_GET_INTEGER: return (fastloop_fn)u->get_integer;
    case FN_GET_BOOLEAN: return (fastloop_fn)u->get_boolean;
    case FN_SET_REAL: return (fastloop_fn)u->set_real;
    case FN_SET_INTEGER: return (fastloop_fn)u->set_integer;
    case FN_SET_BOOLEAN: return (fastloop_fn)u->set_boolean;
    default: return (fastloop_fn)u->do_step;
    }
}

/* fastloop.c's tables, pointing at this container's inner instances and buffers. */
static void bind_loop(Container *ct) {
    int i, used = 0;
    for (i = 0; i < CT_N_PARTS_USED; i++) {
        const ct_part *g = &CT_PARTS[i];
        part_t *p = &ct->parts[i];
        memset(p, 0, sizeof *p);
        p->kind = g->kind;
        p->fn = part_fn(&CT_UNITS[CT_INSTS[g->inst].unit], g->fn);
        p->comp = ct->comp[g->inst];
        p->vr = CT_VR + g->off;
        p->nv = g->nv;
        p->start = g->start;
        p->idx = CT_IDX + g->off;
        p->gain = CT_GAIN + g->off;
        p->offset = CT_OFFSET + g->off;
        p->scaled = g->scaled;
        p->fbuf = ct->fbuf + used;
        p->ibuf = ct->ibuf + used;
        p->h = CT_INSTS[g->inst].h;
        used += g->nv;
    }
    memset(&ct->loop, 0, sizeof ct->loop);
    ct->loop.values = ct->values;
    ct->loop.n = CT_N_SLOTS;
    ct->loop.parts = ct->parts;
    ct->loop.ops = CT_OPS;
    ct->loop.prog = CT_PROG;
    ct->loop.snap_idx = CT_SNAP;
    ct->loop.prog_of_tick = CT_PROG_OF_TICK;
    ct->loop.hyperperiod = CT_HYPERPERIOD;
    ct->loop.output_ticks = INT64_MAX;   /* the container records nothing itself */
    ct->loop.rec = ct->rec;
    ct->loop.rec_idx = ct->rec_idx;
    ct->loop.n_rec = 0;
    ct->loop.lo = CT_LO;
    ct->loop.hi = CT_HI;
    ct->loop.flag_idx = ct->flag_ticks;
    ct->loop.n_flag = 0;
    ct->loop.flag_ticks = ct->flag_ticks;
    ct->loop.flag_first = ct->flag_first;
}

static void free_container(Container *ct) {
    int i;
    if (ct == NULL) return;
    for (i = 0; i < CT_N_INST; i++)
        if (ct->comp[i] != NULL) CT_UNITS[CT_INSTS[i].unit].free_instance(ct->comp[i]);
    free(ct->resources);
    free(ct->name);
    free(ct);
}

/* Inner resource URI: the container's resources/ plus the unit's folder. */
static char *inner_uri(const Container *ct, const char *folder) {
    size_t n = strlen(ct->resources) + strlen(folder) + 2;
    char *out = (char *)malloc(n);
    if (out != NULL) snprintf(out, n, "%s%s/", ct->resources, folder);
    return out;
}

static fmi2Status start_values(Container *ct) {
    int i;
    for (i = 0; i < CT_N_START; i++)
        if (set_value(ct, &CT_START[i]) > fmi2Warning) {
            ct_log(ct, 3, "setting the scenario's start values of %s failed",
                   CT_INSTS[CT_START[i].inst].name);
            return fmi2Error;
        }
    return fmi2OK;
}

static fmi2Status instantiate_inner(Container *ct, fmi2Boolean visible) {
    int i;
    for (i = 0; i < CT_N_INST; i++) {
        const ct_inst *in = &CT_INSTS[i];
        char *uri = inner_uri(ct, in->res);
        if (uri == NULL) return fmi2Error;
        ct->comp[i] = CT_UNITS[in->unit].instantiate(in->name, fmi2CoSimulation, in->guid, uri,
                                                     ct->cb, visible, ct->logging);
        free(uri);
        if (ct->comp[i] == NULL) {
            ct_log(ct, 3, "inner instance %s could not be instantiated", in->name);
            return fmi2Error;
        }
    }
    return start_values(ct);
}

/* ------------------------------------------------------------------ the schedule */

static fmi2Status loop_failure(Container *ct, int code, int64_t k) {
    double t = tick_time(k);
    ct->phase = PH_FAILED;
    if (code == RUN_FMI_STATUS) {
        const ct_part *g = &CT_PARTS[ct->res.part];
        const char *what = g->kind == DO_STEP ? "fmi2DoStep" :
                           g->kind == READ_REAL || g->kind == READ_INT ? "reading outputs" :
                           "setting inputs";
        ct_log(ct, 3, "instance %s failed in %s at t = %.17g s with status %d",
               CT_INSTS[g->inst].name, what, t, (int)ct->res.status);
    } else {
        int64_t i;
        for (i = CT_N_SLOTS; i < 3 * CT_N_SLOTS; i++) {
            double x = ct->values[i];
            if (!isfinite(x) || x < CT_LO[i - CT_N_SLOTS] || x > CT_HI[i - CT_N_SLOTS]) {
                ct_log(ct, 3, "instance %s produced %s = %.17g at t = %.17g s, %s: the run "
                       "diverged", CT_SLOT_INST[(i - CT_N_SLOTS) % CT_N_SLOTS],
                       CT_SLOT_NAMES[(i - CT_N_SLOTS) % CT_N_SLOTS], x, t,
                       isfinite(x) ? "outside its declared range" : "not finite");
                break;
            }
        }
    }
    return fmi2Error;
}

static int apply_actions(Container *ct, int64_t k) {
    int i;
    for (i = 0; i < CT_N_ACTIONS; i++)
        if (CT_ACTIONS[i].tick == k && set_value(ct, &CT_ACTIONS[i].value) > fmi2Warning) {
            ct_log(ct, 3, "the scenario's action at t = %.17g s on %s failed", tick_time(k),
                   CT_INSTS[CT_ACTIONS[i].value.inst].name);
            return 1;
        }
    return 0;
}

/* Start tick k: snapshot, the scenario's actions at k, first phase (outputs at t_k). */
static fmi2Status begin_tick(Container *ct, int64_t k) {
    int code;
    fastloop_snapshot(&ct->loop, k);
    if (apply_actions(ct, k)) {
        ct->phase = PH_FAILED;
        return fmi2Error;
    }
    code = fastloop_calls(&ct->loop, k, tick_time(k), 0, &ct->res);
    ct->stale = 0;
    return code == RUN_OK ? fmi2OK : loop_failure(ct, code, k);
}

static fmi2Status refresh(Container *ct) {
    int code;
    if (!ct->stale || ct->phase != PH_STEPPING) return fmi2OK;
    code = fastloop_calls(&ct->loop, ct->tick, tick_time(ct->tick), 0, &ct->res);
    ct->stale = 0;
    return code == RUN_OK ? fmi2OK : loop_failure(ct, code, ct->tick);
}

/* ------------------------------------------------------------------ common functions */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    int i;
    if (c == NULL) return fmi2Error;
    C->logging = loggingOn != 0;
    for (i = 0; i < CT_N_INST; i++)
        CT_UNITS[CT_INSTS[i].unit].set_debug_logging(C->comp[i], loggingOn, nCategories,
                                                     categories);
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation,
                              const fmi2CallbackFunctions *functions, fmi2Boolean visible,
                              fmi2Boolean loggingOn) {
    Container *ct = (Container *)calloc(1, sizeof(Container));
    size_t n;
    if (ct == NULL) return NULL;
    ct->cb = functions;
    ct->logging = loggingOn != 0;
    ct->name = dup_string(instanceName ? instanceName : "");
    if (ct->name == NULL) {
        free(ct);
        return NULL;
    }
    if (fmuType != fmi2CoSimulation) {
        ct_log(ct, 3, "%s supports co-simulation only", CT_MODEL_IDENTIFIER);
        free_container(ct);
        return NULL;
    }
    if (fmuGUID == NULL || strcmp(fmuGUID, CT_GUID) != 0) {
        ct_log(ct, 3, "GUID %s does not match the model's %s", fmuGUID ? fmuGUID : "(null)",
               CT_GUID);
        free_container(ct);
        return NULL;
    }
    if (fmuResourceLocation == NULL) {
        ct_log(ct, 3, "%s needs its resource location", CT_MODEL_IDENTIFIER);
        free_container(ct);
        return NULL;
    }
    n = strlen(fmuResourceLocation);
    ct->resources = (char *)malloc(n + 2);
    if (ct->resources == NULL) {
        free_container(ct);
        return NULL;
    }
    memcpy(ct->resources, fmuResourceLocation, n + 1);
    if (n == 0 || fmuResourceLocation[n - 1] != '/') strcat(ct->resources, "/");
    if (instantiate_inner(ct, visible) != fmi2OK) {
        free_container(ct);
        return NULL;
    }
    bind_loop(ct);
    ct->phase = PH_INSTANTIATED;
    return ct;
}

void fmi2FreeInstance(fmi2Component c) { free_container(C); }

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined,
                               fmi2Real tolerance, fmi2Real startTime,
                               fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    (void)toleranceDefined;
    (void)tolerance;
    (void)stopTimeDefined;
    (void)stopTime;
    if (c == NULL) return fmi2Error;
    if (C->phase != PH_INSTANTIATED)
        return failed(C, CT_FN_SETUPEXPERIMENT ": %s", "only allowed after " CT_FN_INSTANTIATE);
    if (!(fabs(startTime - CT_START_TIME) <= 1e-6 * CT_BASE_STEP)) {
        ct_log(C, 3, CT_FN_SETUPEXPERIMENT ": the container starts at its scenario's start time "
               "%.17g s; got %.17g s", CT_START_TIME, startTime);
        return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    int i;
    if (c == NULL) return fmi2Error;
    if (C->phase != PH_INSTANTIATED)
        return failed(C, CT_FN_ENTERINITIALIZATIONMODE ": %s", "only allowed once, after "
                      CT_FN_INSTANTIATE);
    for (i = 0; i < CT_N_INST; i++) {
        const ct_unit *u = &CT_UNITS[CT_INSTS[i].unit];
        if (u->setup_experiment(C->comp[i], fmi2False, 0.0, CT_START_TIME, fmi2False, 0.0) >
                fmi2Warning || u->enter_init(C->comp[i]) > fmi2Warning) {
            ct_log(C, 3, "instance %s failed to enter initialisation", CT_INSTS[i].name);
            C->phase = PH_FAILED;
            return fmi2Error;
        }
    }
    C->phase = PH_INITIALIZATION;
    return fmi2OK;
}

static int run_parts(Container *ct, const int *list, int first, int last) {
    int i;
    for (i = first; i < last; i++) {
        const ct_part *g = &CT_PARTS[list[i]];
        part_t one = ct->parts[list[i]];
        loop_t L = ct->loop;
        int64_t op = 0, prog[5] = {0, 1, 1, -2, -2};
        L.parts = &one;
        L.ops = &op;
        L.prog = prog;
        L.prog_of_tick = &op;
        L.hyperperiod = 1;
        if (fastloop_calls(&L, 0, CT_START_TIME, 0, &ct->res) != RUN_OK) {
            ct_log(ct, 3, "instance %s failed in initialisation with status %d",
                   CT_INSTS[g->inst].name, (int)ct->res.status);
            return 1;
        }
    }
    return 0;
}

static int read_all(Container *ct) {
    int i;
    for (i = 0; i < CT_N_INST; i++) {
        const ct_inst *in = &CT_INSTS[CT_INIT_ORDER[i]];
        if (run_parts(ct, CT_READS, in->read0, in->read1)) return 1;
    }
    return 0;
}

/* The master's initialisation (Simulation.initialize), then the first phase of tick 0. */
fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    int i, code;
    if (c == NULL) return fmi2Error;
    if (C->phase != PH_INITIALIZATION)
        return failed(C, CT_FN_EXITINITIALIZATIONMODE ": %s", "not in initialization mode");
    C->phase = PH_FAILED;
    for (i = 0; i < CT_N_INST; i++) {
        int m = CT_INIT_ORDER[i];
        const ct_inst *in = &CT_INSTS[m];
        if (read_all(C)) return fmi2Error;
        memcpy(C->values, C->values + CT_N_SLOTS, CT_N_SLOTS * sizeof(double));
        if (run_parts(C, CT_WRITES, in->write0, in->write1)) return fmi2Error;
        if (CT_UNITS[in->unit].exit_init(C->comp[m]) > fmi2Warning) {
            ct_log(C, 3, "instance %s failed to leave initialisation", in->name);
            return fmi2Error;
        }
    }
    if (read_all(C)) return fmi2Error;
    memcpy(C->values, C->values + CT_N_SLOTS, CT_N_SLOTS * sizeof(double));
    for (i = 0; i < CT_N_INST; i++) {
        const ct_inst *in = &CT_INSTS[CT_INIT_ORDER[i]];
        if (run_parts(C, CT_WRITES, in->write0, in->write1)) return fmi2Error;
    }
    code = fastloop_check(&C->loop, 0);
    if (code != RUN_OK) return loop_failure(C, code, 0);
    C->phase = PH_STEPPING;
    C->tick = 0;
    return begin_tick(C, 0);
}

fmi2Status fmi2Terminate(fmi2Component c) {
    int i;
    if (c == NULL) return fmi2Error;
    for (i = 0; i < CT_N_INST; i++) CT_UNITS[CT_INSTS[i].unit].terminate(C->comp[i]);
    C->phase = PH_TERMINATED;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    int i;
    if (c == NULL) return fmi2Error;
    for (i = 0; i < CT_N_INST; i++)
        if (CT_UNITS[CT_INSTS[i].unit].reset(C->comp[i]) > fmi2Warning) {
            C->phase = PH_FAILED;
            return failed(C, CT_FN_RESET ": %s", "an inner instance could not be reset");
        }
    memset(C->values, 0, sizeof C->values);
    C->tick = 0;
    C->stale = 0;
    C->phase = PH_INSTANTIATED;
    return start_values(C);
}

/* ------------------------------------------------------------------ getters and setters */

static const ct_var *var_of(Container *ct, fmi2ValueReference vr, int type, int setting) {
    const ct_var *v;
    if (ct->phase == PH_FAILED) {
        ct_log(ct, 3, "container %s failed before; no further calls allowed", ct->name);
        return NULL;
    }
    if (vr >= (fmi2ValueReference)CT_N_VARS || CT_VARS[vr].type != type) {
        ct_log(ct, 3, "value reference %u is not a variable of this type (%d)", (unsigned)vr,
               type);
        return NULL;
    }
    v = &CT_VARS[vr];
    if (setting && v->causality == CT_OUTPUT) {
        ct_log(ct, 3, "variable %s is an output and cannot be set", v->name);
        return NULL;
    }
    return v;
}

/* Value of a variable as a double: an output from the bus (in step mode; the inner
 * instance's own value while initialising), an input or parameter from its instance. */
static int get_one(Container *ct, const ct_var *v, double *x) {
    if (v->causality == CT_OUTPUT && ct->phase >= PH_STEPPING) {
        *x = ct->values[v->slot];
        return 0;
    }
    {
        const ct_unit *u = &CT_UNITS[CT_INSTS[v->inst].unit];
        fmi2Component comp = ct->comp[v->inst];
        fmi2Integer iv = 0;
        fmi2Boolean bv = 0;
        int st;
        if (v->type == CT_REAL) return u->get_real(comp, &v->ivr, 1, x) > fmi2Warning;
        st = v->type == CT_INTEGER ? u->get_integer(comp, &v->ivr, 1, &iv)
                                   : u->get_boolean(comp, &v->ivr, 1, &bv);
        *x = v->type == CT_INTEGER ? (double)iv : (double)(bv != 0);
        return st > fmi2Warning;
    }
}

static fmi2Status get_values(Container *ct, const fmi2ValueReference vr[], size_t nvr,
                             int type, double *out) {
    size_t k;
    if (refresh(ct) != fmi2OK) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        const ct_var *v = var_of(ct, vr[k], type, 0);
        if (v == NULL || get_one(ct, v, &out[k])) return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2GetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       fmi2Real value[]) {
    if (c == NULL) return fmi2Error;
    return get_values(C, vr, nvr, CT_REAL, value);
}

fmi2Status fmi2GetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Integer value[]) {
    size_t k;
    double x;
    if (c == NULL) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        if (get_values(C, &vr[k], 1, CT_INTEGER, &x) != fmi2OK) return fmi2Error;
        value[k] = (fmi2Integer)x;
    }
    return fmi2OK;
}

fmi2Status fmi2GetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          fmi2Boolean value[]) {
    size_t k;
    double x;
    if (c == NULL) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        if (get_values(C, &vr[k], 1, CT_BOOLEAN, &x) != fmi2OK) return fmi2Error;
        value[k] = x != 0.0 ? fmi2True : fmi2False;
    }
    return fmi2OK;
}

fmi2Status fmi2GetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         fmi2String value[]) {
    size_t k;
    if (c == NULL) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        const ct_var *v = var_of(C, vr[k], CT_STRING, 0);
        if (v == NULL) return fmi2Error;
        if (CT_UNITS[CT_INSTS[v->inst].unit].get_string(C->comp[v->inst], &v->ivr, 1,
                                                        &value[k]) > fmi2Warning)
            return fmi2Error;
    }
    return fmi2OK;
}

static fmi2Status set_values(Container *ct, const fmi2ValueReference vr[], size_t nvr,
                             int type, const double *x, const fmi2String *s) {
    size_t k;
    for (k = 0; k < nvr; k++) {
        const ct_var *v = var_of(ct, vr[k], type, 1);
        ct_value one;
        if (v == NULL) return fmi2Error;
        one.inst = v->inst;
        one.type = type;
        one.vr = v->ivr;
        one.value = x ? x[k] : 0.0;
        one.text = s ? s[k] : NULL;
        if (set_value(ct, &one) > fmi2Warning) {
            ct_log(ct, 3, "setting %s failed (see the inner instance's message)", v->name);
            return fmi2Error;
        }
    }
    if (nvr > 0) ct->stale = 1;
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                       const fmi2Real value[]) {
    if (c == NULL) return fmi2Error;
    return set_values(C, vr, nvr, CT_REAL, value, NULL);
}

fmi2Status fmi2SetInteger(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Integer value[]) {
    size_t k;
    if (c == NULL) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        double x = (double)value[k];
        if (set_values(C, &vr[k], 1, CT_INTEGER, &x, NULL) != fmi2OK) return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2SetBoolean(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                          const fmi2Boolean value[]) {
    size_t k;
    if (c == NULL) return fmi2Error;
    for (k = 0; k < nvr; k++) {
        double x = value[k] != fmi2False;
        if (set_values(C, &vr[k], 1, CT_BOOLEAN, &x, NULL) != fmi2OK) return fmi2Error;
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                         const fmi2String value[]) {
    if (c == NULL) return fmi2Error;
    return set_values(C, vr, nvr, CT_STRING, NULL, value);
}

/* ------------------------------------------------------------------ co-simulation */

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint,
                      fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    double m_real, t_now;
    int64_t m, j;
    int code;
    (void)noSetFMUStatePriorToCurrentPoint;
    if (c == NULL) return fmi2Error;
    if (C->phase != PH_STEPPING)
        return failed(C, CT_FN_DOSTEP ": %s", "not in step mode (initialise first, and no step "
                      "after an error or fmi2Terminate)");
    m_real = nearbyint(communicationStepSize / CT_BASE_STEP);
    t_now = tick_time(C->tick);
    if (isfinite(communicationStepSize) && m_real > (double)CT_MAX_STEP_TICKS) {
        ct_log(C, 3, CT_FN_DOSTEP ": communication step %.17g s is %.0f base steps, more than "
               "the %lld one doStep takes; step in pieces", communicationStepSize, m_real,
               (long long)CT_MAX_STEP_TICKS);
        return fmi2Error;
    }
    if (m_real == 0.0 && communicationStepSize > 0.0 &&
        fabs(currentCommunicationPoint - t_now) <= host_tolerance(t_now, 0.0) &&
        fabs(currentCommunicationPoint + communicationStepSize - t_now) <=
            host_tolerance(t_now, 0.0))
        return fmi2OK;   /* a host's rounding remainder (t += h short of its stop time) */
    if (!isfinite(communicationStepSize) || !(m_real >= 1.0) ||
        !(fabs(currentCommunicationPoint + communicationStepSize -
               tick_time(C->tick + (int64_t)m_real)) <=
          host_tolerance(currentCommunicationPoint + communicationStepSize,
                         communicationStepSize))) {
        ct_log(C, 3, CT_FN_DOSTEP ": communication step %.17g s is not a whole number of base "
               "steps; allowed steps are m x %.17g s for m = 1, 2, 3, ... (the scenario's base "
               "step: the GCD of its periods and output interval)", communicationStepSize,
               CT_BASE_STEP);
        return fmi2Error;
    }
    if (C->tick + (int64_t)m_real > CT_MAX_TICK) {
        ct_log(C, 3, CT_FN_DOSTEP ": the step would end past tick %lld, the last whose time "
               "is exact", (long long)CT_MAX_TICK);
        return fmi2Error;
    }
    if (!(fabs(currentCommunicationPoint - t_now) <=
          host_tolerance(t_now, communicationStepSize))) {
        ct_log(C, 3, CT_FN_DOSTEP ": the step starts at %.17g s but the container is at "
               "t = %.17g s (tick %lld); step from where the last step ended",
               currentCommunicationPoint, t_now, (long long)C->tick);
        return fmi2Error;
    }
    m = (int64_t)m_real;
    if (refresh(C) != fmi2OK) return fmi2Error;
    for (j = C->tick; j < C->tick + m; j++) {
        code = fastloop_calls(&C->loop, j, tick_time(j), 1, &C->res);
        if (code == RUN_OK) code = fastloop_check(&C->loop, j);
        if (code != RUN_OK) return loop_failure(C, code, j);
        if (begin_tick(C, j + 1) != fmi2OK) return fmi2Error;
    }
    C->tick += m;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) {
    if (c == NULL) return fmi2Error;
    return failed(C, "fmi2CancelStep: %s", "fmi2DoStep never returns fmi2Pending");
}

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s;
    (void)value;
    return c == NULL ? fmi2Error : fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    if (c == NULL || value == NULL) return fmi2Error;
    if (s == fmi2LastSuccessfulTime) {
        *value = tick_time(C->tick);
        return fmi2OK;
    }
    return fmi2Discard;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s;
    (void)value;
    return c == NULL ? fmi2Error : fmi2Discard;
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
    return c == NULL ? fmi2Error : fmi2Discard;
}

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                       size_t nvr, const fmi2Integer order[],
                                       const fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    if (c == NULL) return fmi2Error;
    return failed(C, "fmi2SetRealInputDerivatives: %s", "canInterpolateInputs is false");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[],
                                        size_t nvr, const fmi2Integer order[],
                                        fmi2Real value[]) {
    (void)vr;
    (void)nvr;
    (void)order;
    (void)value;
    if (c == NULL) return fmi2Error;
    return failed(C, "fmi2GetRealOutputDerivatives: %s", "maxOutputDerivativeOrder is 0");
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
    return failed(C, "fmi2GetDirectionalDerivative: %s", "not provided "
                  "(providesDirectionalDerivative is false)");
}


/* ------------------------------------------------------------------ FMU state */

#define STATE_MAGIC "JFCONTNR"
#define STATE_VERSION 1u
#define STATE_HEADER JF_STATE_HEADER

typedef struct {
    size_t size;
    unsigned char bytes[1];
} StateBlob;

/* Serialised state of inner instance i in a new allocation (*size bytes), or NULL. */
static unsigned char *inner_bytes(Container *ct, int i, size_t *size) {
    const ct_unit *u = &CT_UNITS[CT_INSTS[i].unit];
    fmi2FMUstate st = NULL;
    unsigned char *out = NULL;
    if (u->get_state(ct->comp[i], &st) > fmi2Warning) return NULL;
    if (u->state_size(ct->comp[i], st, size) <= fmi2Warning) {
        out = (unsigned char *)malloc(*size ? *size : 1);
        if (out != NULL && u->serialize(ct->comp[i], st, (fmi2Byte *)out, *size) > fmi2Warning) {
            free(out);
            out = NULL;
        }
    }
    u->free_state(ct->comp[i], &st);
    return out;
}

static StateBlob *state_write(Container *ct) {
    unsigned char *parts[CT_N_INST];
    size_t sizes[CT_N_INST], n = STATE_HEADER + 3u * CT_N_SLOTS * 8u + 8u, off;
    uint32_t head[6];
    uint64_t sum;
    StateBlob *blob = NULL;
    int i, ok = 1;
    for (i = 0; i < CT_N_INST; i++) {
        parts[i] = ok ? inner_bytes(ct, i, &sizes[i]) : NULL;
        if (parts[i] == NULL) {
            if (ok) ct_log(ct, 3, "the FMU state of instance %s could not be saved",
                           CT_INSTS[i].name);
            ok = 0;
        } else {
            n += 8u + sizes[i];
        }
    }
    if (ok) blob = (StateBlob *)malloc(sizeof(StateBlob) + n);
    if (blob != NULL) {
        unsigned char *p = blob->bytes;
        blob->size = n;
        jf_state_head_write(p, STATE_MAGIC, STATE_VERSION, CT_GUID);
        head[2] = (uint32_t)CT_N_INST;
        head[3] = (uint32_t)(3 * CT_N_SLOTS);
        head[4] = (uint32_t)ct->phase;
        head[5] = (uint32_t)ct->stale;
        memcpy(p + 80, head + 2, 16);
        memcpy(p + 96, &ct->tick, 8);
        memcpy(p + STATE_HEADER, ct->values, 3u * CT_N_SLOTS * 8u);
        off = STATE_HEADER + 3u * CT_N_SLOTS * 8u;
        for (i = 0; i < CT_N_INST; i++) {
            uint64_t sz = (uint64_t)sizes[i];
            memcpy(p + off, &sz, 8);
            memcpy(p + off + 8, parts[i], sizes[i]);
            off += 8u + sizes[i];
        }
        sum = jf_state_sum(p, n - 8u);
        memcpy(p + off, &sum, 8);
    }
    for (i = 0; i < CT_N_INST; i++) free(parts[i]);
    return blob;
}

/* Check the container's own fields; 0 if valid. */
static int state_check(Container *ct, const unsigned char *p, size_t n) {
    uint32_t head[6];
    uint64_t sum, sz;
    char why[160];
    int64_t tick;
    size_t off, i;
    if (jf_state_head_check(p, n, STATE_MAGIC, STATE_VERSION, CT_GUID, "container", why,
                            sizeof why)) {
        ct_log(ct, 3, "FMU state rejected: %s", why);
        return 1;
    }
    memcpy(&sum, p + n - 8u, 8);
    if (sum != jf_state_sum(p, n - 8u)) {
        ct_log(ct, 3, "FMU state rejected: checksum mismatch (corrupted bytes)");
        return 1;
    }
    memcpy(head + 2, p + 80, 16);
    memcpy(&tick, p + 96, 8);
    if (head[2] != (uint32_t)CT_N_INST || head[3] != (uint32_t)(3 * CT_N_SLOTS) ||
        head[4] > PH_TERMINATED || head[5] > 1u || tick < 0 || tick > CT_MAX_TICK) {
        ct_log(ct, 3, "FMU state rejected: %u instances, %u bus values, phase %u, tick %lld; "
               "expected %u instances, %u bus values, a valid phase and tick",
               (unsigned)head[2], (unsigned)head[3], (unsigned)head[4], (long long)tick,
               (unsigned)CT_N_INST, (unsigned)(3 * CT_N_SLOTS));
        return 1;
    }
    for (i = 0; i < 3u * CT_N_SLOTS; i++) {
        double x;
        memcpy(&x, p + STATE_HEADER + 8u * i, 8);
        if (x != x) {
            ct_log(ct, 3, "FMU state rejected: bus value %lu is NaN", (unsigned long)i);
            return 1;
        }
    }
    off = STATE_HEADER + 3u * CT_N_SLOTS * 8u;
    for (i = 0; i < (size_t)CT_N_INST; i++) {
        if (off + 8u > n - 8u) break;
        memcpy(&sz, p + off, 8);
        if (sz > n - 8u - off - 8u) break;
        off += 8u + (size_t)sz;
    }
    if (i < (size_t)CT_N_INST || off != n - 8u) {
        ct_log(ct, 3, "FMU state rejected: its inner states do not fill its %lu bytes",
               (unsigned long)n);
        return 1;
    }
    return 0;
}

/* Restore all or nothing: every inner state deserialised (and so validated) first. */
static fmi2Status state_read(Container *ct, const unsigned char *p, size_t n) {
    fmi2FMUstate inner[CT_N_INST];
    StateBlob *before = NULL;
    size_t off = STATE_HEADER + 3u * CT_N_SLOTS * 8u;
    int i, set = 0, ok = 1;
    uint32_t head[2];
    if (state_check(ct, p, n) != 0) return fmi2Error;
    memset(inner, 0, sizeof inner);
    for (i = 0; i < CT_N_INST; i++) {
        uint64_t sz;
        const ct_unit *u = &CT_UNITS[CT_INSTS[i].unit];
        memcpy(&sz, p + off, 8);
        if (ok && u->deserialize(ct->comp[i], (const fmi2Byte *)(p + off + 8), (size_t)sz,
                                 &inner[i]) > fmi2Warning) {
            ct_log(ct, 3, "FMU state rejected: the state of instance %s is invalid",
                   CT_INSTS[i].name);
            ok = 0;
        }
        off += 8u + (size_t)sz;
    }
    if (ok) before = state_write(ct);
    if (before == NULL) ok = 0;
    for (i = 0; ok && i < CT_N_INST; i++, set++)
        if (CT_UNITS[CT_INSTS[i].unit].set_state(ct->comp[i], inner[i]) > fmi2Warning) {
            ct_log(ct, 3, "FMU state rejected by instance %s; the previous state is kept",
                   CT_INSTS[i].name);
            ok = 0;
        }
    if (!ok && set > 0) {   /* put back the instances already set */
        off = STATE_HEADER + 3u * CT_N_SLOTS * 8u;
        for (i = 0; i < CT_N_INST; i++) {
            uint64_t sz;
            fmi2FMUstate st = NULL;
            const ct_unit *u = &CT_UNITS[CT_INSTS[i].unit];
            memcpy(&sz, before->bytes + off, 8);
            if (i < set) {
                if (u->deserialize(ct->comp[i], (const fmi2Byte *)(before->bytes + off + 8),
                                   (size_t)sz, &st) <= fmi2Warning)
                    (void)u->set_state(ct->comp[i], st);
                u->free_state(ct->comp[i], &st);
            }
            off += 8u + (size_t)sz;
        }
    }
    for (i = 0; i < CT_N_INST; i++)
        if (inner[i] != NULL) CT_UNITS[CT_INSTS[i].unit].free_state(ct->comp[i], &inner[i]);
    free(before);
    if (!ok) return fmi2Error;
    memcpy(head, p + 88, 8);
    ct->phase = (int)head[0];
    ct->stale = (int)head[1];
    memcpy(&ct->tick, p + 96, 8);
    memcpy(ct->values, p + STATE_HEADER, 3u * CT_N_SLOTS * 8u);
    return fmi2OK;
}

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    StateBlob *blob;
    if (c == NULL || FMUstate == NULL) return fmi2Error;
    blob = state_write(C);
    if (blob == NULL) return fmi2Error;
    free(*FMUstate);
    *FMUstate = blob;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    const StateBlob *blob = (const StateBlob *)FMUstate;
    if (c == NULL || blob == NULL) return fmi2Error;
    return state_read(C, blob->bytes, blob->size);
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
        return failed(C, "fmi2SerializeFMUstate: %s", "size differs from "
                      "fmi2SerializedFMUstateSize");
    memcpy(serializedState, blob->bytes, size);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte serializedState[],
                                   size_t size, fmi2FMUstate *FMUstate) {
    StateBlob *blob;
    if (c == NULL || serializedState == NULL || FMUstate == NULL) return fmi2Error;
    if (state_check(C, (const unsigned char *)serializedState, size) != 0) return fmi2Error;
    blob = (StateBlob *)malloc(sizeof(StateBlob) + size);
    if (blob == NULL) return fmi2Error;
    blob->size = size;
    memcpy(blob->bytes, serializedState, size);
    free(*FMUstate);
    *FMUstate = blob;
    return fmi2OK;
}
