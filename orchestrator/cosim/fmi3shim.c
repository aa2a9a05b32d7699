/* FMI 3.0 calls behind the FMI 2.0 signatures the master's loops use.
 *
 * The master (bus.py, schedule.py, fastloop.c) calls raw fmi2GetReal / fmi2SetReal /
 * fmi2DoStep style functions on a component pointer.  For an FMI 3.0 instance the
 * component is a shim_t and the functions are these: each forwards to the FMU's own
 * fmi3 function with the same values (Float64 as double, Int32 as int32, Boolean as
 * bool converted from and to the master's int32), so both loops run FMI 3.0 FMUs with
 * the arithmetic they use for FMI 2.0 ones.  fmi3DoStep's flags are kept for the
 * master's questions afterwards (terminateSimulation, lastSuccessfulTime).
 */
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef int (*get_f64_fn)(void *, const uint32_t *, size_t, double *, size_t);
typedef int (*set_f64_fn)(void *, const uint32_t *, size_t, const double *, size_t);
typedef int (*get_i32_fn)(void *, const uint32_t *, size_t, int32_t *, size_t);
typedef int (*set_i32_fn)(void *, const uint32_t *, size_t, const int32_t *, size_t);
typedef int (*get_bool_fn)(void *, const uint32_t *, size_t, bool *, size_t);
typedef int (*set_bool_fn)(void *, const uint32_t *, size_t, const bool *, size_t);
typedef int (*do_step_fn)(void *, double, double, bool, bool *, bool *, bool *, double *);

typedef struct {
    void *instance;          /* fmi3Instance */
    void *get_f64, *set_f64, *get_i32, *set_i32, *get_bool, *set_bool, *do_step;
    bool *bbuf;              /* scratch for Boolean values, n_bbuf of them */
    int64_t n_bbuf;
    int64_t terminate;       /* terminateSimulation of the last fmi3DoStep */
    int64_t event;           /* eventHandlingNeeded of the last fmi3DoStep */
    double last_time;        /* lastSuccessfulTime of the last fmi3DoStep */
} shim_t;

enum { ERROR = 3 };

int shim_get_real(shim_t *s, const uint32_t *vr, size_t n, double *v)
{
    return ((get_f64_fn)s->get_f64)(s->instance, vr, n, v, n);
}

int shim_set_real(shim_t *s, const uint32_t *vr, size_t n, const double *v)
{
    return ((set_f64_fn)s->set_f64)(s->instance, vr, n, v, n);
}

int shim_get_int(shim_t *s, const uint32_t *vr, size_t n, int32_t *v)
{
    return ((get_i32_fn)s->get_i32)(s->instance, vr, n, v, n);
}

int shim_set_int(shim_t *s, const uint32_t *vr, size_t n, const int32_t *v)
{
    return ((set_i32_fn)s->set_i32)(s->instance, vr, n, v, n);
}

int shim_get_bool(shim_t *s, const uint32_t *vr, size_t n, int32_t *v)
{
    size_t i;
    int st;
    if ((int64_t)n > s->n_bbuf)
        return ERROR;
    st = ((get_bool_fn)s->get_bool)(s->instance, vr, n, s->bbuf, n);
    for (i = 0; i < n; i++)
        v[i] = s->bbuf[i] ? 1 : 0;
    return st;
}

int shim_set_bool(shim_t *s, const uint32_t *vr, size_t n, const int32_t *v)
{
    size_t i;
    if ((int64_t)n > s->n_bbuf)
        return ERROR;
    for (i = 0; i < n; i++)
        s->bbuf[i] = v[i] != 0;
    return ((set_bool_fn)s->set_bool)(s->instance, vr, n, s->bbuf, n);
}

int shim_do_step(shim_t *s, double t, double h, int no_set_prior)
{
    bool event = false, terminate = false, early = false;
    double last = t;
    int st = ((do_step_fn)s->do_step)(s->instance, t, h, no_set_prior != 0, &event,
                                      &terminate, &early, &last);
    s->event = event;
    s->terminate = terminate;
    s->last_time = last;
    return st;
}
