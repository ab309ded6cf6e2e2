/* BouncingBall: a ball dropped from h = 1 m bounces on the ground (state event h = 0) with
 * restitution e, and comes to rest once it would leave the ground slower than v_min (the physics:
 * shared/ball.h). Co-Simulation steps with the exact solution and discards communication steps
 * longer than max_step (when positive).
 */
#include "plumbing.h"
#include "shared/ball.h"

enum { vr_h = 0, vr_der_h = 1, vr_v = 2, vr_der_v = 3, vr_g = 4, vr_e = 5, vr_v_min = 6, vr_max_step = 7,
       vr_bounces = 10 };

struct ModelData {
    Ball ball;
    double max_step;
};

const char *const MODEL_GUID = "{5b0f3c1e-6a3d-4a53-9c61-2f1a1f7c0a04}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = 2;
const size_t NUMBER_OF_EVENT_INDICATORS = 1;

#define M(v) (comp->data->v)
#define B(v) (comp->data->ball.v)

Status setStartValues(ModelInstance *comp) {
    ballStart(&comp->data->ball);
    M(max_step) = 0.0;
    return OK;
}

Status initialize(ModelInstance *comp) {
    ballInitialize(&comp->data->ball);
    comp->maxStepSize = M(max_step);
    return OK;
}

Status getReal(ModelInstance *comp, ValueReference vr, double *value) {
    switch (vr) {
        case vr_h: *value = B(h); return OK;
        case vr_der_h:
        case vr_v: *value = B(v); return OK;
        case vr_der_v: *value = ballAcceleration(&comp->data->ball); return OK;
        case vr_g: *value = B(g); return OK;
        case vr_e: *value = B(e); return OK;
        case vr_v_min: *value = B(v_min); return OK;
        case vr_max_step: *value = M(max_step); return OK;
        default: return Error;
    }
}

Status setReal(ModelInstance *comp, ValueReference vr, double value) {
    switch (vr) {
        case vr_h:
            if (checkSettable(comp, "h", Fixed)) return Error;
            B(h) = value;
            return OK;
        case vr_v:
            if (checkSettable(comp, "v", Fixed)) return Error;
            B(v) = value;
            return OK;
        case vr_g:
            if (checkSettable(comp, "g", Fixed)) return Error;
            B(g) = value;
            return OK;
        case vr_e:
            if (checkSettable(comp, "e", Tunable)) return Error;
            B(e) = value;
            return OK;
        case vr_v_min:
            if (checkSettable(comp, "v_min", Fixed)) return Error;
            B(v_min) = value;
            return OK;
        case vr_max_step:
            if (checkSettable(comp, "max_step", Fixed)) return Error;
            M(max_step) = value;
            return OK;
        default: return Error;
    }
}

Status getInteger(ModelInstance *comp, ValueReference vr, int *value) {
    if (vr != vr_bounces) return Error;
    *value = B(bounces);
    return OK;
}

Status setInteger(ModelInstance *comp, ValueReference vr, int value) {
    (void)comp, (void)vr, (void)value;
    return Error;
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
    (void)comp, (void)vr, (void)value;
    return Error;
}

Status setString(ModelInstance *comp, ValueReference vr, const char *value) {
    (void)comp, (void)vr, (void)value;
    return Error;
}

void getContinuousStates(ModelInstance *comp, double x[]) {
    x[0] = B(h);
    x[1] = B(v);
}

void setContinuousStates(ModelInstance *comp, const double x[]) {
    B(h) = x[0];
    B(v) = x[1];
}

void getDerivatives(ModelInstance *comp, double dx[]) {
    dx[0] = B(v);
    dx[1] = ballAcceleration(&comp->data->ball);
}

void getEventIndicators(ModelInstance *comp, double z[]) { z[0] = ballIndicator(&comp->data->ball); }

void eventUpdate(ModelInstance *comp) {
    comp->nextEventTimeDefined = false;
    comp->valuesOfContinuousStatesChanged = ballBounce(&comp->data->ball);
}

bool advance(ModelInstance *comp, double t_stop) {
    double dt = t_stop - comp->time;
    bool impact = ballFly(&comp->data->ball, &dt);
    comp->time = impact ? comp->time + dt : t_stop;
    return impact;
}
