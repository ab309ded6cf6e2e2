/* AllTypes: one input, one output and one tunable parameter of every FMI 2.0 type.
 *
 *   y       = gain * u                 (Real, direct feedthrough)
 *   der(x)  = y                        (Real state x, an output)
 *   y_discrete = gain * u_discrete     (Real, discrete: the input may change at events only)
 *   y_int   = u_int + offset           (Integer)
 *   y_bool  = u_bool xor invert        (Boolean)
 *   y_str   = prefix + u_str           (String)
 *   y_color = u_color turned by tint   (Enumeration Color: red 1, green 2, blue 3; red turns nothing)
 */
#include <stdio.h>
#include <string.h>

#include "plumbing.h"

enum {
    vr_gain = 0, vr_u = 1, vr_y = 2, vr_x = 3, vr_der_x = 4, vr_u_discrete = 5, vr_y_discrete = 6,
    vr_offset = 10, vr_u_int = 11, vr_y_int = 12,
    vr_invert = 20, vr_u_bool = 21, vr_y_bool = 22,
    vr_prefix = 30, vr_u_str = 31, vr_y_str = 32,
    vr_tint = 40, vr_u_color = 41, vr_y_color = 42,
};

struct ModelData {
    double gain, u, x, u_discrete;
    int offset, u_int;
    bool invert, u_bool;
    char prefix[STRING_SIZE], u_str[STRING_SIZE], y_str[2 * STRING_SIZE];
    int tint, u_color;
};

const char *const MODEL_GUID = "{5b0f3c1e-6a3d-4a53-9c61-2f1a1f7c0a01}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = 1;
const size_t NUMBER_OF_EVENT_INDICATORS = 0;

#define M(v) (comp->data->v)

void setStartValues(ModelInstance *comp) {
    M(gain) = 2.0;
    M(u) = 0.0;
    M(x) = 0.0;
    M(u_discrete) = 0.0;
    M(offset) = 1;
    M(u_int) = 0;
    M(invert) = false;
    M(u_bool) = false;
    strcpy(M(prefix), "id: ");
    strcpy(M(u_str), "");
    M(tint) = 1;
    M(u_color) = 1;
}

fmi2Status initialize(ModelInstance *comp) {
    (void)comp;
    return fmi2OK;
}

static int turn(int color, int tint) { return (color - 1 + tint - 1) % 3 + 1; }

fmi2Status getReal(ModelInstance *comp, fmi2ValueReference vr, fmi2Real *value) {
    switch (vr) {
        case vr_gain: *value = M(gain); return fmi2OK;
        case vr_u: *value = M(u); return fmi2OK;
        case vr_y:
        case vr_der_x: *value = M(gain) * M(u); return fmi2OK;
        case vr_x: *value = M(x); return fmi2OK;
        case vr_u_discrete: *value = M(u_discrete); return fmi2OK;
        case vr_y_discrete: *value = M(gain) * M(u_discrete); return fmi2OK;
        default: return fmi2Error;
    }
}

fmi2Status setReal(ModelInstance *comp, fmi2ValueReference vr, fmi2Real value) {
    switch (vr) {
        case vr_gain:
            if (checkSettable(comp, "gain", Tunable)) return fmi2Error;
            M(gain) = value;
            return fmi2OK;
        case vr_u:
            if (checkSettable(comp, "u", ContinuousInput)) return fmi2Error;
            M(u) = value;
            return fmi2OK;
        case vr_x:
            if (checkSettable(comp, "x", Fixed)) return fmi2Error;
            M(x) = value;
            return fmi2OK;
        case vr_u_discrete:
            if (checkSettable(comp, "u_discrete", DiscreteInput)) return fmi2Error;
            M(u_discrete) = value;
            return fmi2OK;
        default: return fmi2Error;
    }
}

fmi2Status getInteger(ModelInstance *comp, fmi2ValueReference vr, fmi2Integer *value) {
    switch (vr) {
        case vr_offset: *value = M(offset); return fmi2OK;
        case vr_u_int: *value = M(u_int); return fmi2OK;
        case vr_y_int: *value = M(u_int) + M(offset); return fmi2OK;
        case vr_tint: *value = M(tint); return fmi2OK;
        case vr_u_color: *value = M(u_color); return fmi2OK;
        case vr_y_color: *value = turn(M(u_color), M(tint)); return fmi2OK;
        default: return fmi2Error;
    }
}

static fmi2Status setColor(ModelInstance *comp, int *target, const char *name, Settable kind, int value) {
    if (checkSettable(comp, name, kind)) return fmi2Error;
    if (value < 1 || value > 3) {
        logError(comp, "%s = %d is not a Color (1 red, 2 green, 3 blue)", name, value);
        return fmi2Error;
    }
    *target = value;
    return fmi2OK;
}

fmi2Status setInteger(ModelInstance *comp, fmi2ValueReference vr, fmi2Integer value) {
    switch (vr) {
        case vr_offset:
            if (checkSettable(comp, "offset", Tunable)) return fmi2Error;
            M(offset) = value;
            return fmi2OK;
        case vr_u_int:
            if (checkSettable(comp, "u_int", DiscreteInput)) return fmi2Error;
            M(u_int) = value;
            return fmi2OK;
        case vr_tint: return setColor(comp, &M(tint), "tint", Tunable, value);
        case vr_u_color: return setColor(comp, &M(u_color), "u_color", DiscreteInput, value);
        default: return fmi2Error;
    }
}

fmi2Status getBoolean(ModelInstance *comp, fmi2ValueReference vr, fmi2Boolean *value) {
    switch (vr) {
        case vr_invert: *value = M(invert); return fmi2OK;
        case vr_u_bool: *value = M(u_bool); return fmi2OK;
        case vr_y_bool: *value = M(u_bool) != M(invert); return fmi2OK;
        default: return fmi2Error;
    }
}

fmi2Status setBoolean(ModelInstance *comp, fmi2ValueReference vr, fmi2Boolean value) {
    switch (vr) {
        case vr_invert:
            if (checkSettable(comp, "invert", Tunable)) return fmi2Error;
            M(invert) = value != fmi2False;
            return fmi2OK;
        case vr_u_bool:
            if (checkSettable(comp, "u_bool", DiscreteInput)) return fmi2Error;
            M(u_bool) = value != fmi2False;
            return fmi2OK;
        default: return fmi2Error;
    }
}

fmi2Status getString(ModelInstance *comp, fmi2ValueReference vr, fmi2String *value) {
    switch (vr) {
        case vr_prefix: *value = M(prefix); return fmi2OK;
        case vr_u_str: *value = M(u_str); return fmi2OK;
        case vr_y_str:
            snprintf(M(y_str), sizeof(M(y_str)), "%s%s", M(prefix), M(u_str));
            *value = M(y_str);
            return fmi2OK;
        default: return fmi2Error;
    }
}

fmi2Status setString(ModelInstance *comp, fmi2ValueReference vr, fmi2String value) {
    switch (vr) {
        case vr_prefix:
            if (checkSettable(comp, "prefix", Tunable)) return fmi2Error;
            return copyString(comp, M(prefix), value);
        case vr_u_str:
            if (checkSettable(comp, "u_str", DiscreteInput)) return fmi2Error;
            return copyString(comp, M(u_str), value);
        default: return fmi2Error;
    }
}

void getContinuousStates(ModelInstance *comp, double x[]) { x[0] = M(x); }

void setContinuousStates(ModelInstance *comp, const double x[]) { M(x) = x[0]; }

void getDerivatives(ModelInstance *comp, double dx[]) { dx[0] = M(gain) * M(u); }

void getEventIndicators(ModelInstance *comp, double z[]) { (void)comp, (void)z; }

void eventUpdate(ModelInstance *comp) { comp->nextEventTimeDefined = false; }

bool advance(ModelInstance *comp, double t_stop) {
    M(x) += M(gain) * M(u) * (t_stop - comp->time);  /* exact: the input is held over the step */
    comp->time = t_stop;
    return false;
}
