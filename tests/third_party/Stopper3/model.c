/* Stopper3: samples its input u every `period` seconds after the start (time events) and ends the
 * simulation at `stop_time` (a time event too, at which it sets terminateSimulation: from
 * fmi3UpdateDiscreteStates in Model Exchange and Co-Simulation with Event Mode, from fmi3DoStep
 * otherwise).
 *
 *   samples = number of samples so far      (UInt32)
 *   held    = u at the last sample (u at the start before the first one)
 *   stopped = the simulation was terminated (Boolean)
 */
#include <math.h>

#include "plumbing.h"

struct ModelData {
    double time, period, stop_time, u, held;
    uint32_t samples;
    bool stopped;
};

const char *const MODEL_GUID = "{8c4e2a90-3f1b-4d6e-9a7c-5b2d1e0f3a04}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = 0;
const size_t NUMBER_OF_EVENT_INDICATORS = 0;

const Variable VARIABLES[] = {
    VARIABLE(0, time, Float64Type, Calculated),
    VARIABLE(1, period, Float64Type, Fixed),
    VARIABLE(2, stop_time, Float64Type, Fixed),
    VARIABLE(3, u, Float64Type, ContinuousInput),
    VARIABLE(4, held, Float64Type, Calculated),
    VARIABLE(5, samples, UInt32Type, Calculated),
    VARIABLE(6, stopped, BooleanType, Calculated),
};
const size_t NUMBER_OF_VARIABLES = sizeof(VARIABLES) / sizeof(VARIABLES[0]);

#define M(v) (comp->data->v)

Status setStartValues(ModelInstance *comp) {
    M(period) = 0.25;
    M(stop_time) = 1.55;
    return OK;
}

/* The next sample time, computed from the count so that round-off does not accumulate. */
static double nextSample(const ModelInstance *comp) { return comp->startTime + (M(samples) + 1) * M(period); }

static void scheduleNextEvent(ModelInstance *comp) {
    comp->nextEventTimeDefined = !M(stopped);
    comp->nextEventTime = fmin(nextSample(comp), M(stop_time));
}

Status initialize(ModelInstance *comp) {
    if (!(M(period) > 0)) {
        logError(comp, "period = %g must be positive", M(period));
        return Error;
    }
    M(samples) = 0;
    M(held) = M(u);
    M(stopped) = false;
    scheduleNextEvent(comp);
    return OK;
}

Status calculateValues(ModelInstance *comp) {
    M(time) = comp->time;
    if (comp->state == InitializationMode) M(held) = M(u);  /* initialization computes it from u */
    return OK;
}

void getContinuousStates(ModelInstance *comp, double x[]) { (void)comp, (void)x; }

void setContinuousStates(ModelInstance *comp, const double x[]) { (void)comp, (void)x; }

void getDerivatives(ModelInstance *comp, double dx[]) { (void)comp, (void)dx; }

void getEventIndicators(ModelInstance *comp, double z[]) { (void)comp, (void)z; }

void eventUpdate(ModelInstance *comp) {
    if (M(stopped) || !timeEventDue(comp)) return;
    const double eps = 1e-12 * fmax(1.0, fabs(comp->time));
    if (comp->time >= nextSample(comp) - eps) {
        M(samples) += 1;
        M(held) = M(u);
    }
    if (comp->time >= M(stop_time) - eps) {
        M(stopped) = true;
        comp->terminateSimulation = true;
        logInfo(comp, "stop_time %g reached after %u samples: terminating", M(stop_time), (unsigned)M(samples));
    }
    scheduleNextEvent(comp);
}

bool advance(ModelInstance *comp, double t_stop) {
    comp->time = t_stop;
    return false;
}
