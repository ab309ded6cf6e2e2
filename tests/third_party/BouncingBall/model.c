/* BouncingBall: a ball dropped from h = 1 m bounces on the ground (state event h = 0) with
 * restitution e, and comes to rest once it would leave the ground slower than v_min.
 *
 *   der(h) = v,  der(v) = -g  (0 at rest);  at h = 0 moving down: v := -e v, bounces += 1
 *
 * Co-Simulation steps with the exact solution: parabolas between impacts found in closed form,
 * and discards communication steps longer than max_step (when positive).
 */
#include <math.h>

#include "plumbing.h"

enum { vr_h = 0, vr_der_h = 1, vr_v = 2, vr_der_v = 3, vr_g = 4, vr_e = 5, vr_v_min = 6, vr_max_step = 7,
       vr_bounces = 10 };

struct ModelData {
    double h, v, g, e, v_min, max_step;
    int bounces;
    bool resting;
};

const char *const MODEL_GUID = "{5b0f3c1e-6a3d-4a53-9c61-2f1a1f7c0a04}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = 2;
const size_t NUMBER_OF_EVENT_INDICATORS = 1;

#define M(v) (comp->data->v)

void setStartValues(ModelInstance *comp) {
    M(h) = 1.0;
    M(v) = 0.0;
    M(g) = 9.81;
    M(e) = 0.7;
    M(v_min) = 0.1;
    M(max_step) = 0.0;
}

fmi2Status initialize(ModelInstance *comp) {
    M(bounces) = 0;
    M(resting) = false;
    comp->maxStepSize = M(max_step);
    return fmi2OK;
}

static double acceleration(const ModelInstance *comp) { return M(resting) ? 0.0 : -M(g); }

fmi2Status getReal(ModelInstance *comp, fmi2ValueReference vr, fmi2Real *value) {
    switch (vr) {
        case vr_h: *value = M(h); return fmi2OK;
        case vr_der_h:
        case vr_v: *value = M(v); return fmi2OK;
        case vr_der_v: *value = acceleration(comp); return fmi2OK;
        case vr_g: *value = M(g); return fmi2OK;
        case vr_e: *value = M(e); return fmi2OK;
        case vr_v_min: *value = M(v_min); return fmi2OK;
        case vr_max_step: *value = M(max_step); return fmi2OK;
        default: return fmi2Error;
    }
}

fmi2Status setReal(ModelInstance *comp, fmi2ValueReference vr, fmi2Real value) {
    switch (vr) {
        case vr_h:
            if (checkSettable(comp, "h", Fixed)) return fmi2Error;
            M(h) = value;
            return fmi2OK;
        case vr_v:
            if (checkSettable(comp, "v", Fixed)) return fmi2Error;
            M(v) = value;
            return fmi2OK;
        case vr_g:
            if (checkSettable(comp, "g", Fixed)) return fmi2Error;
            M(g) = value;
            return fmi2OK;
        case vr_e:
            if (checkSettable(comp, "e", Tunable)) return fmi2Error;
            M(e) = value;
            return fmi2OK;
        case vr_v_min:
            if (checkSettable(comp, "v_min", Fixed)) return fmi2Error;
            M(v_min) = value;
            return fmi2OK;
        case vr_max_step:
            if (checkSettable(comp, "max_step", Fixed)) return fmi2Error;
            M(max_step) = value;
            return fmi2OK;
        default: return fmi2Error;
    }
}

fmi2Status getInteger(ModelInstance *comp, fmi2ValueReference vr, fmi2Integer *value) {
    if (vr != vr_bounces) return fmi2Error;
    *value = M(bounces);
    return fmi2OK;
}

fmi2Status setInteger(ModelInstance *comp, fmi2ValueReference vr, fmi2Integer value) {
    (void)comp, (void)vr, (void)value;
    return fmi2Error;
}

fmi2Status getBoolean(ModelInstance *comp, fmi2ValueReference vr, fmi2Boolean *value) {
    (void)comp, (void)vr, (void)value;
    return fmi2Error;
}

fmi2Status setBoolean(ModelInstance *comp, fmi2ValueReference vr, fmi2Boolean value) {
    (void)comp, (void)vr, (void)value;
    return fmi2Error;
}

fmi2Status getString(ModelInstance *comp, fmi2ValueReference vr, fmi2String *value) {
    (void)comp, (void)vr, (void)value;
    return fmi2Error;
}

fmi2Status setString(ModelInstance *comp, fmi2ValueReference vr, fmi2String value) {
    (void)comp, (void)vr, (void)value;
    return fmi2Error;
}

void getContinuousStates(ModelInstance *comp, double x[]) {
    x[0] = M(h);
    x[1] = M(v);
}

void setContinuousStates(ModelInstance *comp, const double x[]) {
    M(h) = x[0];
    M(v) = x[1];
}

void getDerivatives(ModelInstance *comp, double dx[]) {
    dx[0] = M(v);
    dx[1] = acceleration(comp);
}

void getEventIndicators(ModelInstance *comp, double z[]) { z[0] = M(resting) ? 1.0 : M(h); }

void eventUpdate(ModelInstance *comp) {
    comp->nextEventTimeDefined = false;
    if (M(resting) || M(h) > 0 || M(v) >= 0) return;
    M(h) = 0;
    M(v) = -M(e) * M(v);
    M(bounces) += 1;
    if (M(v) < M(v_min)) {
        M(v) = 0;
        M(resting) = true;
    }
    comp->valuesOfContinuousStatesChanged = true;
}

bool advance(ModelInstance *comp, double t_stop) {
    double dt = t_stop - comp->time;
    if (M(resting)) {
        comp->time = t_stop;
        return false;
    }
    /* first tau > 0 (or 0 when on the ground moving down) with h + v tau - g tau^2 / 2 = 0 */
    double tau = (M(v) + sqrt(M(v) * M(v) + 2 * M(g) * fmax(M(h), 0.0))) / M(g);
    if (tau <= dt) {
        M(v) -= M(g) * tau;
        M(h) = 0;
        comp->time += tau;
        return true;
    }
    M(h) += (M(v) - 0.5 * M(g) * dt) * dt;
    M(v) -= M(g) * dt;
    comp->time = t_stop;
    return false;
}
