/* The FMI-independent core of a jitterfmu native FMU (C99, libc and libm only).
 *
 * jfcore.c holds what the FMI 2.0 layer (fmi2.c) and the FMI 3.0 layer (fmi3.c) share:
 * an instance's life (allocation, start values, phases, reset), the checks on value
 * references, and the FMU state as one versioned, checksummed byte layout.  Each layer
 * maps its API onto these functions and provides jf_api_log, the one function that
 * knows the host's logger.  The model kernels see only jfmu.h.
 */
#ifndef JFCORE_H
#define JFCORE_H

#include <stddef.h>

#include "jfmu.h"

/* Provided by the FMI layer: hand one formatted message to the host's logger. */
void jf_api_log(JfInstance *inst, int status, const char *category, const char *message);

/* A new instance named `name` (NULL if out of memory); nothing else is set up yet. */
JfInstance *jf_instance_new(const char *name, int logging_on);
/* Check the GUID / instantiation token, allocate the variables, set the start values
 * and instantiate the kernel; `resource_dir` (malloc'ed, a trailing separator) is owned
 * by the instance from here on.  JF_OK, or JF_ERROR (logged): free the instance then. */
int jf_instance_setup(JfInstance *inst, const char *token, char *resource_dir);
void jf_instance_free(JfInstance *inst);
/* Back to the instantiated phase with start values and a fresh kernel. */
int jf_instance_reset(JfInstance *inst);

/* Phase transitions; `fn` names the FMI function in the logged message. */
int jf_enter_initialization(JfInstance *inst, double start_time, const char *fn);
int jf_exit_initialization(JfInstance *inst, const char *fn);
int jf_do_step(JfInstance *inst, double t, double h, const char *fn);

/* JF_OK when every value reference is a variable of `type` that may be read (setting
 * 0) or set (setting 1) now; JF_ERROR (logged) otherwise or if the instance failed. */
int jf_check_refs(JfInstance *inst, const unsigned int *vr, size_t nvr, int type,
                  int setting);
/* JF_OK when every Real value to set is finite and inside its variable's declared
 * range; JF_ERROR (logged, naming the variable) otherwise. */
int jf_check_reals(JfInstance *inst, const unsigned int *vr, size_t nvr, const double *v,
                   const char *fn);
/* JF_OK when every Real output is finite (and, with `ranges`, inside its declared
 * range); else JF_ERROR (logged) and the instance failed. */
int jf_check_outputs(JfInstance *inst, const char *fn, int ranges);
/* After a set of nvr values: let the kernel refresh its direct feedthrough. */
int jf_after_set(JfInstance *inst, size_t nvr);
/* Replace String value reference vr by a copy of s; JF_ERROR if out of memory. */
int jf_set_string(JfInstance *inst, unsigned int vr, const char *s);
/* JF_OK stays; anything else marks the instance failed. */
int jf_kernel_status(JfInstance *inst, int status);

/* The FMU state: one byte layout (jfcore.c), saved and restored all or nothing. */
typedef struct {
    size_t size;
    unsigned char bytes[1];
} JfState;
/* The instance's state now (NULL if out of memory). */
JfState *jf_state_save(JfInstance *inst);
/* A copy of serialised bytes, checked field by field first (NULL, logged, if invalid). */
JfState *jf_state_copy(JfInstance *inst, const unsigned char *p, size_t n);
/* Restore checked bytes; a state the kernel refuses leaves the previous one. */
int jf_state_restore(JfInstance *inst, const unsigned char *p, size_t n);

#endif
