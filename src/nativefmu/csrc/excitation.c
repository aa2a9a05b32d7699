/* Excitation kernel: two sine-burst channels (distfmu.excitation).
 *
 *   v_i(t) = amp_i sin(2 pi freq_i (t - t_start))  for t_start <= t < t_stop, else 0
 *
 * the window's edges met within JF_TIME_RTOL of the step (jf_reached), as
 * distfmu.excitation.sine_burst with the step as its period,
 * written at the start time on initialisation and at t + h after each step.
 * No internal state.
 */
#include <math.h>
#include <stdlib.h>

#include "jfmu.h"

#define PI 3.141592653589793

typedef struct {
    long amp[2], freq[2], out[2], start, stop;
} Excitation;

int model_instantiate(JfInstance *inst) {
    static const char *amp[2] = {"amp1", "amp2"}, *freq[2] = {"freq1", "freq2"},
                      *out[2] = {"v1", "v2"};
    Excitation *m = (Excitation *)jf_alloc(inst, 1, sizeof(Excitation));
    int i;
    inst->model = m;
    if (m == NULL) return JF_ERROR;
    for (i = 0; i < 2; i++) {
        if ((m->amp[i] = jf_vr(inst, amp[i], JF_REAL)) < 0 ||
            (m->freq[i] = jf_vr(inst, freq[i], JF_REAL)) < 0 ||
            (m->out[i] = jf_vr(inst, out[i], JF_REAL)) < 0)
            return JF_ERROR;
    }
    if ((m->start = jf_vr(inst, "t_start", JF_REAL)) < 0 ||
        (m->stop = jf_vr(inst, "t_stop", JF_REAL)) < 0)
        return JF_ERROR;
    inst->n_state = 1; /* the time of the outputs */
    inst->state = (double *)jf_alloc(inst, 1, sizeof(double));
    if (inst->state == NULL) return JF_ERROR;
    return JF_OK;
}

void model_free(JfInstance *inst) {
    free(inst->model);
    inst->model = NULL;
}

static void write_outputs(JfInstance *inst, double t, double h) {
    const Excitation *m = (const Excitation *)inst->model;
    const double *r = inst->r;
    double t0 = r[m->start], t1 = r[m->stop];
    int i;
    for (i = 0; i < 2; i++) {
        double a = r[m->amp[i]], f = r[m->freq[i]];
        int on = jf_reached(t, t0, h) && !jf_reached(t, t1, h);
        inst->r[m->out[i]] = on ? a * jm_sin(2 * PI * f * (t - t0)) : 0.0;
    }
}

int model_exit_initialization(JfInstance *inst) {
    inst->state[0] = inst->start_time;
    write_outputs(inst, inst->start_time, 0.0);
    return JF_OK;
}

int model_inputs_changed(JfInstance *inst) {
    (void)inst;
    return JF_OK;
}

int model_state_restored(JfInstance *inst) {
    (void)inst;
    return JF_OK;
}

int model_do_step(JfInstance *inst, double t, double h) {
    inst->state[0] = jf_end_time(t, h, inst->state[0]);
    write_outputs(inst, inst->state[0], h);
    return JF_OK;
}
