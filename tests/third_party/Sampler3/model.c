/* Sampler3: a discrete-time model driven ONLY by two periodic input Clocks (no time events, no
 * nextEventTime): an importer that does not activate its clocks never sees it sample.
 *
 *   sample (Clock, fixed: interval T, shift delay, from fmi3GetIntervalDecimal/fmi3GetShiftDecimal)
 *       y     := y + T * u          a discrete integrator (forward Euler of der(y) = u)
 *       ticks := ticks + 1
 *   slow   (Clock, constant: interval 0.25 s, shift 0.05 s, in the XML)
 *       held  := u                  a sample-and-hold
 *       slow_ticks := slow_ticks + 1
 *   overflow (output Clock, triggered): ticks with every 4th tick of sample
 *
 * y and held start at 0; when both clocks tick at one instant both partitions run with the same u.
 */
#include "plumbing.h"

struct ModelData {
    double time, T, delay, u, y, held;
    int32_t ticks, slow_ticks;
};

const char *const MODEL_GUID = "{8c4e2a90-3f1b-4d6e-9a7c-5b2d1e0f3a06}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = 0;
const size_t NUMBER_OF_EVENT_INDICATORS = 0;

const Variable VARIABLES[] = {
    VARIABLE(0, time, Float64Type, Calculated),
    VARIABLE(1, T, Float64Type, Fixed),
    VARIABLE(2, delay, Float64Type, Fixed),
    VARIABLE(3, u, Float64Type, ContinuousInput),
    VARIABLE(4, y, Float64Type, Calculated),
    VARIABLE(5, held, Float64Type, Calculated),
    VARIABLE(6, ticks, Int32Type, Calculated),
    VARIABLE(7, slow_ticks, Int32Type, Calculated),
};
const size_t NUMBER_OF_VARIABLES = sizeof(VARIABLES) / sizeof(VARIABLES[0]);

enum { SAMPLE, SLOW, OVERFLOW };
static const ClockVariable CLOCKS[] = {{8, "sample", false, false}, {9, "slow", true, false},
                                       {10, "overflow", false, true}};

const ClockVariable *clockVariables(size_t *n) {
    *n = sizeof(CLOCKS) / sizeof(CLOCKS[0]);
    return CLOCKS;
}

#define M(v) (comp->data->v)

Status clockTiming(ModelInstance *comp, size_t i, double *interval, double *shift) {
    *interval = i == SAMPLE ? M(T) : 0.25;
    *shift = i == SAMPLE ? M(delay) : 0.05;
    return OK;
}

/* overflow ticks with every 4th tick of sample (decided when sample is activated, before its partition runs) */
bool outputClockTicks(ModelInstance *comp, size_t i) {
    return i == OVERFLOW && (comp->activeClocks & (1u << SAMPLE)) && (M(ticks) + 1) % 4 == 0;
}

Status setStartValues(ModelInstance *comp) {
    M(T) = 0.1;
    M(delay) = 0.0;
    return OK;
}

Status initialize(ModelInstance *comp) {
    if (!(M(T) > 0) || !(M(delay) >= 0)) {
        logError(comp, "T = %g must be positive and delay = %g not negative", M(T), M(delay));
        return Error;
    }
    M(y) = M(held) = 0.0;
    M(ticks) = M(slow_ticks) = 0;
    return OK;
}

Status calculateValues(ModelInstance *comp) {
    M(time) = comp->time;
    return OK;
}

void getContinuousStates(ModelInstance *comp, double x[]) { (void)comp, (void)x; }

void setContinuousStates(ModelInstance *comp, const double x[]) { (void)comp, (void)x; }

void getDerivatives(ModelInstance *comp, double dx[]) { (void)comp, (void)dx; }

void getEventIndicators(ModelInstance *comp, double z[]) { (void)comp, (void)z; }

void eventUpdate(ModelInstance *comp) {
    if (comp->activeClocks & (1u << SAMPLE)) {
        M(y) += M(T) * M(u);
        M(ticks) += 1;
    }
    if (comp->activeClocks & (1u << SLOW)) {
        M(held) = M(u);
        M(slow_ticks) += 1;
    }
    if (comp->activeClocks) logInfo(comp, "clocks 0x%x at t = %.17g", comp->activeClocks, comp->time);
}

bool advance(ModelInstance *comp, double t_stop) {
    comp->time = t_stop;
    return false;
}
