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

Status setStartValues(ModelInstance *comp) {
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
    return OK;
}

Status initialize(ModelInstance *comp) {
    (void)comp;
    return OK;
}

static int turn(int color, int tint) { return (color - 1 + tint - 1) % 3 + 1; }

Status getReal(ModelInstance *comp, ValueReference vr, double *value) {
    switch (vr) {
        case vr_gain: *value = M(gain); return OK;
        case vr_u: *value = M(u); return OK;
        case vr_y:
        case vr_der_x: *value = M(gain) * M(u); return OK;
        case vr_x: *value = M(x); return OK;
        case vr_u_discrete: *value = M(u_discrete); return OK;
        case vr_y_discrete: *value = M(gain) * M(u_discrete); return OK;
        default: return Error;
    }
}

Status setReal(ModelInstance *comp, ValueReference vr, double value) {
    switch (vr) {
        case vr_gain:
            if (checkSettable(comp, "gain", Tunable)) return Error;
            M(gain) = value;
            return OK;
        case vr_u:
            if (checkSettable(comp, "u", ContinuousInput)) return Error;
            M(u) = value;
            return OK;
        case vr_x:
            if (checkSettable(comp, "x", Fixed)) return Error;
            M(x) = value;
            return OK;
        case vr_u_discrete:
            if (checkSettable(comp, "u_discrete", DiscreteInput)) return Error;
            M(u_discrete) = value;
            return OK;
        default: return Error;
    }
}

Status getInteger(ModelInstance *comp, ValueReference vr, int *value) {
    switch (vr) {
        case vr_offset: *value = M(offset); return OK;
        case vr_u_int: *value = M(u_int); return OK;
        case vr_y_int: *value = M(u_int) + M(offset); return OK;
        case vr_tint: *value = M(tint); return OK;
        case vr_u_color: *value = M(u_color); return OK;
        case vr_y_color: *value = turn(M(u_color), M(tint)); return OK;
        default: return Error;
    }
}

static Status setColor(ModelInstance *comp, int *target, const char *name, Settable kind, int value) {
    if (checkSettable(comp, name, kind)) return Error;
    if (value < 1 || value > 3) {
        logError(comp, "%s = %d is not a Color (1 red, 2 green, 3 blue)", name, value);
        return Error;
    }
    *target = value;
    return OK;
}

Status setInteger(ModelInstance *comp, ValueReference vr, int value) {
    switch (vr) {
        case vr_offset:
            if (checkSettable(comp, "offset", Tunable)) return Error;
            M(offset) = value;
            return OK;
        case vr_u_int:
            if (checkSettable(comp, "u_int", DiscreteInput)) return Error;
            M(u_int) = value;
            return OK;
        case vr_tint: return setColor(comp, &M(tint), "tint", Tunable, value);
        case vr_u_color: return setColor(comp, &M(u_color), "u_color", DiscreteInput, value);
        default: return Error;
    }
}

Status getBoolean(ModelInstance *comp, ValueReference vr, bool *value) {
    switch (vr) {
        case vr_invert: *value = M(invert); return OK;
        case vr_u_bool: *value = M(u_bool); return OK;
        case vr_y_bool: *value = M(u_bool) != M(invert); return OK;
        default: return Error;
    }
}

Status setBoolean(ModelInstance *comp, ValueReference vr, bool value) {
    switch (vr) {
        case vr_invert:
            if (checkSettable(comp, "invert", Tunable)) return Error;
            M(invert) = value;
            return OK;
        case vr_u_bool:
            if (checkSettable(comp, "u_bool", DiscreteInput)) return Error;
            M(u_bool) = value;
            return OK;
        default: return Error;
    }
}

Status getString(ModelInstance *comp, ValueReference vr, const char **value) {
    switch (vr) {
        case vr_prefix: *value = M(prefix); return OK;
        case vr_u_str: *value = M(u_str); return OK;
        case vr_y_str:
            snprintf(M(y_str), sizeof(M(y_str)), "%s%s", M(prefix), M(u_str));
            *value = M(y_str);
            return OK;
        default: return Error;
    }
}

Status setString(ModelInstance *comp, ValueReference vr, const char *value) {
    switch (vr) {
        case vr_prefix:
            if (checkSettable(comp, "prefix", Tunable)) return Error;
            return copyString(comp, M(prefix), value);
        case vr_u_str:
            if (checkSettable(comp, "u_str", DiscreteInput)) return Error;
            return copyString(comp, M(u_str), value);
        default: return Error;
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
