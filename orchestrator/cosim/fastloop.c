/* The master's tick loop in C for the common case (no algebraic loop, no action).
 *
 * Python (fastloop.py) flattens the schedule's hyperperiod pattern into programs of
 * "parts": one raw FMI call each (get/set a block of variables, or doStep) plus the
 * bus arithmetic around it.  fastloop_run executes ticks k0..k1 exactly as the Python
 * loop of Simulation.run does: snapshot, phase one, record a row, phase two, check that
 * every produced value is finite and inside its declared range, count the ticks each
 * saturation flag is set.  The arithmetic is numpy's: gain and offset as two
 * roundings (compile with -ffp-contract=off), Integer by rint (round half to even),
 * Boolean by != 0.  Any FMI status above Warning, a non-finite value or one out of its
 * range stops the run
 * and is reported back so that Python raises the error it raises today.
 *
 * The container FMU (nativefmu.container, `jitterfmu export-fmu`) compiles this file
 * into its binary and drives the same tables one tick (and half tick) at a time with
 * fastloop_snapshot / fastloop_calls / fastloop_check; it includes this file with
 * FASTLOOP_TYPES_ONLY defined to get the table types.  Function pointers are held as a
 * generic function pointer type, so the file also compiles with -pedantic.
 */
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

enum { READ_REAL = 0, READ_INT = 1, SET_REAL = 2, SET_INT = 3, SET_BOOL = 4, DO_STEP = 5 };
enum { RUN_OK = 0, RUN_FMI_STATUS = 1, RUN_NOT_FINITE = 2, RUN_OUT_OF_RANGE = 3 };

#ifndef FASTLOOP_H
#define FASTLOOP_H
typedef void (*fastloop_fn)(void);   /* any FMI function, cast back before the call */
typedef int (*get_real_fn)(void *, const uint32_t *, size_t, double *);
typedef int (*get_int_fn)(void *, const uint32_t *, size_t, int32_t *);
typedef int (*set_real_fn)(void *, const uint32_t *, size_t, const double *);
typedef int (*set_int_fn)(void *, const uint32_t *, size_t, const int32_t *);
typedef int (*do_step_fn)(void *, double, double, int);

typedef struct {
    int64_t kind;          /* READ_REAL ... DO_STEP */
    fastloop_fn fn;        /* the raw FMI function */
    void *comp;            /* fmi2Component */
    const uint32_t *vr;    /* value references, nv of them */
    int64_t nv;
    int64_t start;         /* reads: index into values of the first variable */
    const int64_t *idx;    /* sets: index into values of each variable */
    const double *gain;    /* sets: per variable */
    const double *offset;
    int64_t scaled;        /* sets: apply gain and offset */
    double *fbuf;          /* nv doubles */
    int32_t *ibuf;         /* nv ints (Integer and Boolean) */
    double h;              /* doStep: step size (s) */
} part_t;

typedef struct {
    double *values;              /* the bus, 3 n */
    int64_t n;
    const part_t *parts;
    const int64_t *ops;          /* part numbers of every program, back to back */
    const int64_t *prog;         /* per program: first, mid, end into ops; snap start, end */
    const int64_t *snap_idx;     /* slots snapshot by programs that snapshot a subset */
    const int64_t *prog_of_tick; /* program of each tick of the hyperperiod */
    int64_t hyperperiod;
    int64_t output_ticks;
    double *rec;                 /* recorded rows, n_rec per row */
    const int64_t *rec_idx;
    int64_t n_rec;
    const double *lo;            /* range of values[n..3n), 2 n each */
    const double *hi;
    const int64_t *flag_idx;     /* saturation flags: index into values */
    int64_t n_flag;
    int64_t *flag_ticks;         /* ticks each flag was set, after the tick's steps */
    int64_t *flag_first;         /* first such tick, -1 before */
} loop_t;

typedef struct {
    int64_t tick;    /* the tick that stopped the run */
    int64_t part;    /* the part whose FMI call failed */
    int64_t status;  /* its FMI status */
    int64_t rows;    /* rows recorded so far */
} result_t;

/* One tick in pieces (fastloop_run is these in order, recording between the calls). */
void fastloop_snapshot(const loop_t *L, int64_t k);
int fastloop_calls(const loop_t *L, int64_t k, double t, int phase, result_t *res);
int fastloop_check(const loop_t *L, int64_t k);
int fastloop_run(const loop_t *L, int64_t k0, int64_t k1, const double *t, result_t *res);
#endif

#ifndef FASTLOOP_TYPES_ONLY

static int run_part(double *values, const part_t *p, double t)
{
    int64_t i;
    switch (p->kind) {
    case READ_REAL:
        return ((get_real_fn)p->fn)(p->comp, p->vr, (size_t)p->nv, values + p->start);
    case READ_INT: {
        int st = ((get_int_fn)p->fn)(p->comp, p->vr, (size_t)p->nv, p->ibuf);
        if (st > 1)
            return st;
        for (i = 0; i < p->nv; i++)
            values[p->start + i] = (double)p->ibuf[i];
        return st;
    }
    case DO_STEP:
        return ((do_step_fn)p->fn)(p->comp, t, p->h, 1);
    default:
        break;
    }
    for (i = 0; i < p->nv; i++) {
        double x = values[p->idx[i]];
        if (p->scaled) {
            x = x * p->gain[i];
            x = x + p->offset[i];
        }
        p->fbuf[i] = x;
    }
    if (p->kind == SET_REAL)
        return ((set_real_fn)p->fn)(p->comp, p->vr, (size_t)p->nv, p->fbuf);
    for (i = 0; i < p->nv; i++)
        p->ibuf[i] = p->kind == SET_BOOL ? (p->fbuf[i] != 0.0) : (int32_t)rint(p->fbuf[i]);
    return ((set_int_fn)p->fn)(p->comp, p->vr, (size_t)p->nv, p->ibuf);
}

static void record_row(const loop_t *L, int64_t k, result_t *res)
{
    int64_t i;
    const int64_t row = k / L->output_ticks;
    for (i = 0; i < L->n_rec; i++)
        L->rec[row * L->n_rec + i] = L->values[L->rec_idx[i]];
    res->rows = row + 1;
}

/* Start of tick k: the values stamped <= t_k (snapshot of the due instances' slots). */
void fastloop_snapshot(const loop_t *L, int64_t k)
{
    const int64_t *pr = L->prog + 5 * L->prog_of_tick[k % L->hyperperiod];
    const int64_t n = L->n;
    int64_t i;
    if (pr[3] < 0)
        memcpy(L->values, L->values + n, (size_t)n * sizeof(double));
    else
        for (i = pr[3]; i < pr[4]; i++)
            L->values[L->snap_idx[i]] = L->values[n + L->snap_idx[i]];
}

/* The calls of tick k at time t: phase 0 (set inputs, read feedthrough outputs at t_k)
 * or phase 1 (step and read).  RUN_OK, or RUN_FMI_STATUS with res->part and res->status. */
int fastloop_calls(const loop_t *L, int64_t k, double t, int phase, result_t *res)
{
    const int64_t *pr = L->prog + 5 * L->prog_of_tick[k % L->hyperperiod];
    int64_t o;
    for (o = phase ? pr[1] : pr[0]; o < (phase ? pr[2] : pr[1]); o++) {
        int st = run_part(L->values, &L->parts[L->ops[o]], t);
        if (st > 1) {
            res->part = L->ops[o];
            res->status = st;
            return RUN_FMI_STATUS;
        }
    }
    return RUN_OK;
}

/* After tick k's steps: every produced value finite and inside its range (RUN_OK,
 * RUN_NOT_FINITE or RUN_OUT_OF_RANGE), then count the saturation flags. */
int fastloop_check(const loop_t *L, int64_t k)
{
    const double *values = L->values;
    const int64_t n = L->n;
    double sum = 0.0;
    int out = 0;
    int64_t i;
    for (i = n; i < 3 * n; i++) {   /* one pass: finite and inside its range */
        sum += values[i];
        out |= values[i] < L->lo[i - n] || values[i] > L->hi[i - n];
    }
    if (!isfinite(sum))
        return RUN_NOT_FINITE;   /* a NaN compares false: reported as not finite */
    if (out)
        return RUN_OUT_OF_RANGE;
    for (i = 0; i < L->n_flag; i++)
        if (values[L->flag_idx[i]] != 0.0) {
            L->flag_ticks[i]++;
            if (L->flag_first[i] < 0)
                L->flag_first[i] = k;
        }
    return RUN_OK;
}

/* Run ticks k0..k1 (inclusive); t[k - k0] is the time of tick k.  Returns RUN_OK, or
 * RUN_FMI_STATUS / RUN_NOT_FINITE with res->tick (and res->part, res->status). */
int fastloop_run(const loop_t *L, int64_t k0, int64_t k1, const double *t, result_t *res)
{
    int64_t k;
    for (k = k0; k <= k1; k++) {
        const double tk = t[k - k0];
        int st;
        res->tick = k;
        fastloop_snapshot(L, k);
        st = fastloop_calls(L, k, tk, 0, res);
        if (st != RUN_OK)
            return st;
        if (k % L->output_ticks == 0)
            record_row(L, k, res);
        st = fastloop_calls(L, k, tk, 1, res);
        if (st != RUN_OK)
            return st;
        st = fastloop_check(L, k);
        if (st != RUN_OK)
            return st;
    }
    return RUN_OK;
}
#endif
