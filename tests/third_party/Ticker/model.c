/* Ticker: counts time events, one every `period` seconds from the start, samples its input at
 * each, and ends the simulation at the `max_ticks`-th (terminateSimulation in Model Exchange;
 * fmi2Discard with fmi2Terminated in Co-Simulation).
 *
 *   ticks = number of ticks so far          (Integer)
 *   label = "tick <ticks>"                  (String)
 *   held  = u at the last tick (at the start before the first one)
 *   phase = time since the last tick (since the start before the first one)
 */
#include <math.h>
#include <stdio.h>

#include "plumbing.h"

enum { vr_period = 0, vr_u = 1, vr_held = 2, vr_phase = 3, vr_max_ticks = 10, vr_ticks = 11, vr_label = 20 };

struct ModelData {
    double period, u, held, lastTick;
    int maxTicks, ticks;
    char label[STRING_SIZE];
};

const char *const MODEL_GUID = "{5b0f3c1e-6a3d-4a53-9c61-2f1a1f7c0a02}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = 0;
const size_t NUMBER_OF_EVENT_INDICATORS = 0;

#define M(v) (comp->data->v)

Status setStartValues(ModelInstance *comp) {
    M(period) = 0.35;
    M(u) = 0.0;
    M(maxTicks) = 5;
    return OK;
}

Status initialize(ModelInstance *comp) {
    if (M(period) <= 0) {
        logError(comp, "period = %g must be positive", M(period));
        return Error;
    }
    M(ticks) = 0;
    M(held) = M(u);
    M(lastTick) = comp->startTime;
    comp->nextEventTimeDefined = true;
    comp->nextEventTime = comp->startTime + M(period);
    return OK;
}

Status getReal(ModelInstance *comp, ValueReference vr, double *value) {
    switch (vr) {
        case vr_period: *value = M(period); return OK;
        case vr_u: *value = M(u); return OK;
        case vr_held:  /* initialization computes it from u */
            *value = comp->state == InitializationMode ? M(u) : M(held);
            return OK;
        case vr_phase: *value = comp->time - M(lastTick); return OK;
        default: return Error;
    }
}

Status setReal(ModelInstance *comp, ValueReference vr, double value) {
    switch (vr) {
        case vr_period:
            if (checkSettable(comp, "period", Fixed)) return Error;
            M(period) = value;
            return OK;
        case vr_u:
            if (checkSettable(comp, "u", ContinuousInput)) return Error;
            M(u) = value;
            return OK;
        default: return Error;
    }
}

Status getInteger(ModelInstance *comp, ValueReference vr, int *value) {
    switch (vr) {
        case vr_max_ticks: *value = M(maxTicks); return OK;
        case vr_ticks: *value = M(ticks); return OK;
        default: return Error;
    }
}

Status setInteger(ModelInstance *comp, ValueReference vr, int value) {
    if (vr != vr_max_ticks || checkSettable(comp, "max_ticks", Fixed)) return Error;
    M(maxTicks) = value;
    return OK;
}

Status getBoolean(ModelInstance *comp, ValueReference vr, bool *value) {
    (void)comp, (void)vr, (void)value;
    return Error;
}

Status setBoolean(ModelInstance *comp, ValueReference vr, bool value) {
    (void)comp, (void)vr, (void)value;
    return Error;
}

Status getString(ModelInstance *comp, ValueReference vr, const char **value) {
    if (vr != vr_label) return Error;
    snprintf(M(label), sizeof(M(label)), "tick %d", M(ticks));
    *value = M(label);
    return OK;
}

Status setString(ModelInstance *comp, ValueReference vr, const char *value) {
    (void)comp, (void)vr, (void)value;
    return Error;
}

void getContinuousStates(ModelInstance *comp, double x[]) { (void)comp, (void)x; }

void setContinuousStates(ModelInstance *comp, const double x[]) { (void)comp, (void)x; }

void getDerivatives(ModelInstance *comp, double dx[]) { (void)comp, (void)dx; }

void getEventIndicators(ModelInstance *comp, double z[]) { (void)comp, (void)z; }

void eventUpdate(ModelInstance *comp) {
    if (!timeEventDue(comp)) return;
    M(ticks) += 1;
    M(held) = M(u);
    M(lastTick) = comp->nextEventTime;
    /* from the count, so that round-off does not accumulate */
    comp->nextEventTime = comp->startTime + (M(ticks) + 1) * M(period);
    if (M(ticks) >= M(maxTicks)) {
        comp->terminateSimulation = true;
        logInfo(comp, "tick %d of %d at t = %g: terminating", M(ticks), M(maxTicks), comp->time);
    }
}

bool advance(ModelInstance *comp, double t_stop) {
    comp->time = t_stop;
    return false;
}
