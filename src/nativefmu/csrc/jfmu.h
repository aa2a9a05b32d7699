/* Shared interface of the native FMUs of jitterfmu (C99, libc and libm only).
 *
 * jfcore.c implements once for every model what the FMI API needs: variable storage
 * by value reference, phases, logging, and the FMU state as one versioned, checksummed
 * byte layout; fmi2.c maps the FMI 2.0 co-simulation API onto it, fmi3.c the FMI 3.0
 * one (an FMU carries one of the two).  A model kernel (structure.c, piezo.c, controller.c,
 * excitation.c) implements the model_* functions below and reads its data from a
 * file in resources/ with jf_data_*.
 */
#ifndef JFMU_H
#define JFMU_H

#include <stddef.h>

#include "jfmath.h" /* sin, exp, log, ... with the same bits everywhere */

enum { JF_REAL = 0, JF_INTEGER = 1, JF_BOOLEAN = 2, JF_STRING = 3 };
enum { JF_PARAMETER = 0, JF_INPUT = 1, JF_OUTPUT = 2, JF_LOCAL = 3, JF_OTHER = 4 };

/* One variable of the model description (model_config.h holds the table). */
typedef struct {
    const char *name;
    unsigned int vr;
    int type;
    int causality;
    int tunable;      /* variability tunable, discrete or continuous */
    double start;     /* Real, Integer and Boolean start values */
    const char *sstart;
    double min, max;  /* a Real's declared range (+-DBL_MAX when undeclared) */
} JfVar;

typedef struct JfInstance JfInstance;

struct JfInstance {
    char *instance_name;
    char *resource_dir;   /* local path of resources/, with a trailing separator */
    const void *callbacks; /* FMI 2.0: const fmi2CallbackFunctions * */
    int logging_on;
    int phase;
    double *r;            /* Real values, indexed by value reference */
    int *iv;              /* Integer values */
    int *bv;              /* Boolean values (0 or 1) */
    char **sv;            /* String values */
    double start_time;
    double t_next;        /* the communication point the next step must start from */
    size_t n_state;       /* internal state (beyond the variables), saved with the FMU state */
    double *state;
    void *model;          /* kernel data that is not state (matrices, caches) */
    void *environment;    /* FMI 3.0: the host's instanceEnvironment */
    void (*log_message)(void); /* FMI 3.0: its fmi3LogMessageCallback */
};

/* Phases of an instance (the co-simulation state machine of FMI 2.0 and 3.0). */
enum { JF_INSTANTIATED = 0, JF_INITIALIZATION = 1, JF_STEPPING = 2, JF_TERMINATED = 3,
       JF_FAILED = 4 };

/* Status values of the kernel functions. */
enum { JF_OK = 0, JF_ERROR = 1 };

/* Value reference of variable `name` of `type`, or -1 (logged as an error). */
long jf_vr(JfInstance *inst, const char *name, int type);
/* Log a message: status 0 ok, 1 warning, 3 error. */
void jf_log(JfInstance *inst, int status, const char *fmt, ...);
/* calloc that logs on failure. */
void *jf_alloc(JfInstance *inst, size_t n, size_t size);

/* Model data file: named real arrays, values as little-endian binary64 (csrc/data.c). */
typedef struct JfData JfData;
JfData *jf_data_open(JfInstance *inst, const char *file_name);
/* Array `name` of shape (rows, cols), copied into a new allocation; NULL if missing or
 * of another shape (logged).  A 0-element array gives a valid 1-element allocation. */
double *jf_data_array(JfData *data, const char *name, size_t rows, size_t cols);
/* Scalar `name`; returns JF_ERROR (logged) if missing. */
int jf_data_scalar(JfData *data, const char *name, double *value);
void jf_data_close(JfData *data);

/* Dense linear algebra on row-major matrices. */
/* out = expm(a), a of shape (n, n); returns JF_ERROR if out of memory. */
int jf_expm(const double *a, size_t n, double *out);
/* expm(a) after exact power-of-two diagonal balancing (stiff, badly scaled blocks). */
int jf_expm_balanced(const double *a, size_t n, double *out);

/* The communication point at the end of a step from t by h, robust to the host's time
 * arithmetic: the step starts at `last` (the previous end) when t is within 1e-6 h of
 * it, and an end within 4 ulps of a multiple of 1 ps is that multiple, correctly
 * rounded (so t_k + h, an accumulated t += h and the exact t_{k+1} are one time).
 * The same rule as fmukit.timing.end_time. */
double jf_end_time(double t, double h, double last);
/* Two times closer than this fraction of a step (or sample period) are one time; a step
 * within JF_STEP_RTOL (relative) of a known step is that step.  As fmukit.timing. */
#define JF_TIME_RTOL 1e-6
#define JF_STEP_RTOL 1e-9
/* The longest step one doStep takes (s), and the largest time an FMU runs to (s): a
 * step's work is bounded (a kernel steps its samples one by one). */
#define JF_MAX_STEP 1e4
#define JF_MAX_TIME 1e9
/* t is the communication point `known` up to a host's rounding of steps h: 1e-6 h, plus
 * what t += h accumulates (a few ulps of t per step taken), never half a step. */
int jf_same_point(double t, double known, double h);
/* t at or after event within JF_TIME_RTOL of period (fmukit.timing.reached). */
int jf_reached(double t, double event, double period);
/* h is the step known up to host rounding (fmukit.timing.same_step): JF_STEP_RTOL of it,
 * or for a step ending at t what a host's t += h accumulates there (its last step,
 * shortened to land on its stop time), never a quarter of the step; t = 0: the first. */
int jf_same_step(double h, double known, double t);

/* Kernel interface. */
int model_instantiate(JfInstance *inst);           /* read data, allocate, set n_state */
int model_exit_initialization(JfInstance *inst);   /* parameters final: initial outputs */
int model_do_step(JfInstance *inst, double t, double h);
int model_inputs_changed(JfInstance *inst);        /* after fmi2Set* / fmi3Set* (feedthrough) */
int model_state_restored(JfInstance *inst);        /* after a state is set: check, refresh */
void model_free(JfInstance *inst);

#endif
