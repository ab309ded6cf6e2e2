/* A Co-Simulation step taken in C: FmuInstance.do_step (deltafmi/runtime/instance.py), statement
 * for statement, over the state both share (DfmiCs, bridge.h): the same solver calls in the same
 * order, so either side may take any step and the results are the same bit for bit. CVODE's
 * right-hand side, root functions and projection are the compiled kernels' (cvode_rhs.c of the
 * generated library), so a step without events runs no Python. Python runs where the model's
 * Python must: the event iteration (its update()), the solver's creation, the explanation of a
 * failure, and an evaluation the kernels do not cover. */
#include "glibc_floor.h"
#include <math.h>
#include <string.h>

#include "cs_step.h"

#define TINY 1e-12 /* relative time below which intervals are round-off (instance.py _TINY) */
#define CV_NORMAL 1
#define CV_ROOT_RETURN 2

int dfmi_cs_takes_step(const Instance *c) {
    const DfmiLayout *L = &c->L;
    return L->cs && L->cs->enabled && L->kernels_ready && *L->kernels_ready && L->kernel_derivatives;
}

/* FmuInstance._communication_point: t + h, or the grid point start + k H that differs from it by round-off. */
static double communication_point(DfmiCs *s, double t, double h) {
    double t_end = t + h, steps[2] = {s->grid_step, h};
    for (int i = 0; i < 2; i++) {
        double step = steps[i];
        if (step > 0.0) {
            /* Python's round() rounds half to even, as nearbyint in the default rounding mode */
            double on_grid = s->start_time + nearbyint((t_end - s->start_time) / step) * step;
            if (fabs(on_grid - t_end) <= TINY * fmax(1.0, fabs(t_end))) {
                s->grid_step = step;
                return on_grid;
            }
        }
    }
    return t_end;
}

/* FmuInstance._inputs_changed: whether the inputs differ from the last step's (kept as floats). */
static int inputs_changed(const DfmiLayout *L, DfmiCs *s) {
    int changed = !s->inputs_valid;
    int64_t k = 0;
    for (int64_t i = 0; i < s->n_real_inputs; i++, k++) {
        double value = L->real[s->real_inputs[i]];
        if (!(value == s->inputs[k])) changed = 1;
        s->inputs[k] = value;
    }
    for (int64_t i = 0; i < s->n_int_inputs; i++, k++) {
        double value = (double)L->ints[s->int_inputs[i]];
        if (!(value == s->inputs[k])) changed = 1;
        s->inputs[k] = value;
    }
    s->inputs_valid = 1;
    return changed;
}

static void reinit(DfmiCs *s, size_t nx, double t, const double *x) {
    if (s->x != x) memmove(s->x, x, nx * sizeof(double));
    s->reinit(s->mem, t, s->y);
    s->solver_t = t;
}

/* FmuInstance._restart_for_inputs: whether CVODE restarts because the held inputs changed. */
static int restart_for_inputs(const DfmiLayout *L, DfmiCs *s, double t_end) {
    int restart = 1;
    size_t nx = L->nx;
    if (s->jump_tolerance > 0 && s->after_valid && !s->restart_solver &&
        L->kernel_derivatives(L->kernel_attributes, s->time, L->real, L->ints, L->event_indicators) == 0) {
        /* Cvode.error_norm of the derivatives' jump, as Python computes it (a kernel that raised restarts) */
        double total = 0.0;
        for (size_t i = 0; i < nx; i++) {
            double jump = L->real[L->dx_offset + i] - s->after[i];
            total += pow(jump / (s->rtol * fabs(s->x[i]) + s->atol[i]), 2.0);
        }
        double norm = nx ? sqrt(total / (double)nx) : 0.0;
        restart = (t_end - s->time) * norm > s->jump_tolerance;
    }
    s->jump_kept = !restart;
    return restart;
}

/* Cvode.advance: 1 at a root, 0 at t_stop, < 0 CVODE's failure flag (tret: where). */
static int advance(DfmiCs *s, double t_stop, double *tret) {
    s->set_stop_time(s->mem, t_stop);
    int flag = s->cvode(s->mem, t_stop, s->y, tret, CV_NORMAL);
    if (flag < 0) return flag;
    s->solver_t = *tret;
    return flag == CV_ROOT_RETURN;
}

/* CVODE failed: Python raises what the Python step raises (status >= error), or, with retry, says
 * whether a restart may try again (OK: no callback raised). */
static int failed(Instance *c, int flag, double t, int retry) {
    double args[3] = {(double)flag, t, retry ? 1.0 : 0.0};
    int status = bridge_call(c->py, DFMI_CS_FAILED, args, 3);
    return status < DFMI_ERROR ? status : DFMI_ERROR;
}

/* FmuInstance._integrate_to (with _advance_over_jump): *root = whether a root stopped it. */
static int integrate_to(Instance *c, double t_stop, int *root) {
    const DfmiLayout *L = &c->L;
    DfmiCs *s = L->cs;
    size_t nx = L->nx;
    if (!s->mem) {
        int status = bridge_call(c->py, DFMI_CS_PREPARE, NULL, 0);
        if (status >= DFMI_ERROR) return status;
        if (!s->mem) return dfmi_fail(c, "the Co-Simulation solver was not made");
    }
    double tret = t_stop;
    int result;
    if (s->jump_kept) {
        /* the first advance over a kept input jump: a failure there restarts from where it began */
        double t0 = s->solver_t, x0[nx ? nx : 1];
        memcpy(x0, s->x, nx * sizeof(double));
        s->jump_kept = 0;
        *s->quiet = 1;
        result = advance(s, t_stop, &tret);
        if (result < 0) {
            *s->quiet = 0;
            int status = failed(c, result, tret, 1);
            if (status != DFMI_OK) return status;
            reinit(s, nx, t0, x0);
            result = advance(s, t_stop, &tret);
        }
        *s->quiet = 0;
    } else {
        result = advance(s, t_stop, &tret);
    }
    if (result < 0) return failed(c, result, tret, 0);
    memcpy(L->real + L->x_offset, s->x, nx * sizeof(double));
    *root = result;
    s->time = result ? s->solver_t : t_stop;
    return DFMI_OK;
}

/* FmuInstance._keep_indicators */
static void keep_indicators(const DfmiLayout *L, DfmiCs *s) {
    if (!L->nz) return;
    memcpy(s->pre_indicators, L->event_indicators, L->nz * sizeof(double));
    s->pre_indicators_valid = 1;
}

/* FmuInstance._indicators_crossed: an event indicator now on the other side of zero (z > 0 or
 * z <= 0) than where the last step or event left it; < 0: a status (Python failed). */
static int indicators_crossed(Instance *c) {
    const DfmiLayout *L = &c->L;
    DfmiCs *s = L->cs;
    if (!L->nz || !s->pre_indicators_valid) return 0;
    double t = s->time;
    if (!(*L->kernels_ready && L->kernel_indicators &&
          L->kernel_indicators(L->kernel_attributes, t, L->real, L->ints, L->event_indicators) == 0)) {
        int status = bridge_call(c->py, DFMI_EVALUATE_DERIVATIVES, &t, 1);
        if (status >= DFMI_ERROR) return -status;
    }
    for (size_t i = 0; i < L->nz; i++)
        if ((s->pre_indicators[i] > 0.0) != (L->event_indicators[i] > 0.0)) return 1;
    return 0;
}

/* FmuInstance.evaluate at the step's end: by the kernels where they cover it, else in Python. */
static int evaluate(Instance *c) {
    const DfmiLayout *L = &c->L;
    double t = L->cs->time;
    const void *a = L->kernel_attributes;
    if (*L->kernels_ready && L->kernel_outputs && (!L->nz || L->kernel_indicators) &&
        L->kernel_derivatives(a, t, L->real, L->ints, L->event_indicators) == 0 &&
        (!L->nz || L->kernel_indicators(a, t, L->real, L->ints, L->event_indicators) == 0) &&
        L->kernel_outputs(a, t, L->real, L->ints, L->event_indicators) == 0)
        return DFMI_OK;
    return bridge_call(c->py, DFMI_EVALUATE, &t, 1);
}

int dfmi_cs_step(Instance *c, double t, double h, DfmiStepEvents events) {
    const DfmiLayout *L = &c->L;
    DfmiCs *s = L->cs;
    double *control = (double *)L->control;
    size_t nx = L->nx;
    double t_end = communication_point(s, t, h);
    control[2] = 0.0;
    int changed = inputs_changed(L, s); /* since the last step (kept: the next step compares with these) */
    /* a zero-order-hold input jumped too far for CVODE's history, or the importer handled an event here */
    if (s->mem && ((changed && restart_for_inputs(L, s, t_end)) || s->restart_solver))
        reinit(s, nx, s->time, L->real + L->x_offset);
    if (s->restart_solver) s->event_time = s->time; /* the solver starts here after the importer's Event Mode */
    s->restart_solver = 0;
    int handled = 0;
    if (changed) {
        /* the inputs set at t moved an event indicator across zero: an event at t (instance.py) */
        int crossed = indicators_crossed(c);
        if (crossed < 0) return -crossed;
        if (crossed) {
            int status = bridge_call(c->py, DFMI_CS_EVENT, NULL, 0);
            if (status >= DFMI_ERROR) return status;
            handled = 1;
        }
    }
    while (s->time < t_end && !dfmi_terminated(c)) {
        /* Python drops the time event of a clock-driven component in event mode (its Clocks'
         * ticks are the importer's): one stepped here has states, so it is never clock-driven */
        double nte = s->next_time_event;
        int timed = !isnan(nte);
        double t_stop = timed && nte > s->time ? fmin(t_end, nte) : t_end;
        int root = 0;
        if (t_stop - s->time <= TINY * fmax(1.0, fabs(t_stop))) {
            s->time = t_stop; /* a round-off sliver (a time event at a step end): no motion */
        } else {
            int status = integrate_to(c, t_stop, &root);
            if (status != DFMI_OK) return status;
        }
        int time_event = timed && s->time >= nte - TINY * fmax(1.0, fabs(nte));
        int at_end = s->time >= t_end - TINY * fmax(1.0, fabs(t_end));
        /* a root within round-off of the event the solver restarted at is that event's indicator
         * crossing back: handled inside, not reported again (instance.py) */
        int echo = root && fabs(s->time - s->event_time) <= TINY * fmax(1.0, fabs(s->time));
        if ((time_event || (root && !echo)) &&
            (events == DFMI_EVENTS_EARLY_RETURN || (events == DFMI_EVENTS_AT_STEP_END && at_end))) {
            control[1] = s->time; /* fmi3DoStep: eventHandlingNeeded here */
            control[2] = 1.0;
            int status = evaluate(c);
            keep_indicators(L, s);
            s->after_valid = 0; /* the event restarts the solver */
            return status;
        }
        if (root || time_event) {
            int status = bridge_call(c->py, DFMI_CS_EVENT, NULL, 0);
            if (status >= DFMI_ERROR) return status;
            handled = 1;
        }
    }
    int ended = dfmi_terminated(c);
    if (ended) control[1] = s->time; /* fmi2LastSuccessfulTime */
    else s->time = t_end;            /* remove round-off so the next doStep matches exactly */
    int status = evaluate(c);
    if (status >= DFMI_ERROR) return status;
    keep_indicators(L, s);
    if (handled && events == DFMI_EVENTS_AT_STEP_END && !ended) {
        control[1] = s->time; /* eventHandlingNeeded for the events handled inside */
        control[2] = 1.0;
        s->handled_reported = 1;
    }
    memcpy(s->after, L->real + L->dx_offset, nx * sizeof(double));
    s->after_valid = 1;
    return ended ? DFMI_DISCARD : status;
}
