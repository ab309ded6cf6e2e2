/* Oscillator: a damped mass-spring oscillator m x'' = F - k x - c x' driven by the input force F.
 * Model Exchange gives the importer the derivatives; Co-Simulation integrates them itself with the
 * classical Runge-Kutta method on equal substeps no longer than `substep` (the step's work grows
 * with the communication step over `substep`: a plain C FMU whose fmi2DoStep takes measurable time).
 */
#include <math.h>

#include "plumbing.h"

enum { vr_x = 0, vr_der_x = 1, vr_v = 2, vr_der_v = 3, vr_k = 4, vr_c = 5, vr_m = 6, vr_F = 7, vr_substep = 8 };

struct ModelData {
    double x, v, k, c, m, F, substep;
};

const char *const MODEL_GUID = "{8d3c2f4a-1b7e-4c59-a0d6-3e5f7b9c1a28}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = 2;
const size_t NUMBER_OF_EVENT_INDICATORS = 0;

#define M(v) (comp->data->v)

static double acceleration(const ModelData *d, double x, double v) { return (d->F - d->k * x - d->c * v) / d->m; }

Status setStartValues(ModelInstance *comp) {
    M(x) = 1.0, M(v) = 0.0, M(k) = 1.0, M(c) = 0.1, M(m) = 1.0, M(F) = 0.0, M(substep) = 1e-5;
    return OK;
}

Status initialize(ModelInstance *comp) {
    if (!(M(m) > 0) || !(M(substep) > 0)) {
        logError(comp, "m and substep must be positive");
        return Error;
    }
    return OK;
}

Status getReal(ModelInstance *comp, ValueReference vr, double *value) {
    switch (vr) {
        case vr_x: *value = M(x); return OK;
        case vr_der_x:
        case vr_v: *value = M(v); return OK;
        case vr_der_v: *value = acceleration(comp->data, M(x), M(v)); return OK;
        case vr_k: *value = M(k); return OK;
        case vr_c: *value = M(c); return OK;
        case vr_m: *value = M(m); return OK;
        case vr_F: *value = M(F); return OK;
        case vr_substep: *value = M(substep); return OK;
        default: return Error;
    }
}

Status setReal(ModelInstance *comp, ValueReference vr, double value) {
    switch (vr) {
        case vr_x: if (checkSettable(comp, "x", Fixed)) return Error; M(x) = value; return OK;
        case vr_v: if (checkSettable(comp, "v", Fixed)) return Error; M(v) = value; return OK;
        case vr_k: if (checkSettable(comp, "k", Fixed)) return Error; M(k) = value; return OK;
        case vr_c: if (checkSettable(comp, "c", Fixed)) return Error; M(c) = value; return OK;
        case vr_m: if (checkSettable(comp, "m", Fixed)) return Error; M(m) = value; return OK;
        case vr_F: if (checkSettable(comp, "F", ContinuousInput)) return Error; M(F) = value; return OK;
        case vr_substep: if (checkSettable(comp, "substep", Fixed)) return Error; M(substep) = value; return OK;
        default: return Error;
    }
}

Status getInteger(ModelInstance *comp, ValueReference vr, int *value) { (void)comp, (void)vr, (void)value; return Error; }
Status setInteger(ModelInstance *comp, ValueReference vr, int value) { (void)comp, (void)vr, (void)value; return Error; }
Status getBoolean(ModelInstance *comp, ValueReference vr, bool *value) { (void)comp, (void)vr, (void)value; return Error; }
Status setBoolean(ModelInstance *comp, ValueReference vr, bool value) { (void)comp, (void)vr, (void)value; return Error; }
Status getString(ModelInstance *comp, ValueReference vr, const char **value) { (void)comp, (void)vr, (void)value; return Error; }
Status setString(ModelInstance *comp, ValueReference vr, const char *value) { (void)comp, (void)vr, (void)value; return Error; }

void getContinuousStates(ModelInstance *comp, double x[]) {
    x[0] = M(x);
    x[1] = M(v);
}

void setContinuousStates(ModelInstance *comp, const double x[]) {
    M(x) = x[0];
    M(v) = x[1];
}

void getDerivatives(ModelInstance *comp, double dx[]) {
    dx[0] = M(v);
    dx[1] = acceleration(comp->data, M(x), M(v));
}

void getEventIndicators(ModelInstance *comp, double z[]) { (void)comp, (void)z; }

void eventUpdate(ModelInstance *comp) {
    comp->nextEventTimeDefined = false;
    comp->valuesOfContinuousStatesChanged = false;
}

bool advance(ModelInstance *comp, double t_stop) {
    const ModelData *d = comp->data;
    double span = t_stop - comp->time;
    int n = span > 0 ? (int)ceil(span / d->substep - 1e-9) : 0;
    double h = n > 0 ? span / n : 0.0, x = d->x, v = d->v;
    for (int i = 0; i < n; i++) {
        double k1x = v, k1v = acceleration(d, x, v);
        double k2x = v + 0.5 * h * k1v, k2v = acceleration(d, x + 0.5 * h * k1x, v + 0.5 * h * k1v);
        double k3x = v + 0.5 * h * k2v, k3v = acceleration(d, x + 0.5 * h * k2x, v + 0.5 * h * k2v);
        double k4x = v + h * k3v, k4v = acceleration(d, x + h * k3x, v + h * k3v);
        x += h / 6.0 * (k1x + 2.0 * k2x + 2.0 * k3x + k4x);
        v += h / 6.0 * (k1v + 2.0 * k2v + 2.0 * k3v + k4v);
    }
    comp->data->x = x, comp->data->v = v;
    comp->time = t_stop;
    return false;
}
