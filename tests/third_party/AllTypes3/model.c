/* AllTypes3: one input and one output of every FMI 3.0 variable type, each output the input
 * passed through, and three tunable parameters:
 *
 *   y_f32 = u_f32, y_f64 = scale * u_f64          (Float32, Float64: continuous)
 *   y_i8 = u_i8, ..., y_u64 = u_u64               (Int8 ... UInt64: every bit kept)
 *   y_bool = u_bool xor invert                    (Boolean)
 *   y_str = prefix + u_str                        (String)
 *   y_bin = u_bin                                 (Binary)
 *   y_color = u_color                             (Enumeration Color: red 1, green 2, blue 3)
 */
#include <stdio.h>
#include <string.h>

#include "plumbing.h"

struct ModelData {
    double time;
    float u_f32, y_f32;
    double u_f64, y_f64, scale;
    int8_t u_i8, y_i8;
    uint8_t u_u8, y_u8;
    int16_t u_i16, y_i16;
    uint16_t u_u16, y_u16;
    int32_t u_i32, y_i32;
    uint32_t u_u32, y_u32;
    int64_t u_i64, y_i64;
    uint64_t u_u64, y_u64;
    bool u_bool, y_bool, invert;
    char u_str[STRING_SIZE], y_str[STRING_SIZE], prefix[STRING_SIZE];
    BinaryValue u_bin, y_bin;
    int64_t u_color, y_color;
};

const char *const MODEL_GUID = "{8c4e2a90-3f1b-4d6e-9a7c-5b2d1e0f3a02}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = 0;
const size_t NUMBER_OF_EVENT_INDICATORS = 0;

const Variable VARIABLES[] = {
    VARIABLE(0, time, Float64Type, Calculated),
    VARIABLE(1, u_f32, Float32Type, ContinuousInput),
    VARIABLE(2, y_f32, Float32Type, Calculated),
    VARIABLE(3, u_f64, Float64Type, ContinuousInput),
    VARIABLE(4, y_f64, Float64Type, Calculated),
    VARIABLE(5, scale, Float64Type, Tunable),
    VARIABLE(10, u_i8, Int8Type, DiscreteInput),
    VARIABLE(11, y_i8, Int8Type, Calculated),
    VARIABLE(12, u_u8, UInt8Type, DiscreteInput),
    VARIABLE(13, y_u8, UInt8Type, Calculated),
    VARIABLE(14, u_i16, Int16Type, DiscreteInput),
    VARIABLE(15, y_i16, Int16Type, Calculated),
    VARIABLE(16, u_u16, UInt16Type, DiscreteInput),
    VARIABLE(17, y_u16, UInt16Type, Calculated),
    VARIABLE(18, u_i32, Int32Type, DiscreteInput),
    VARIABLE(19, y_i32, Int32Type, Calculated),
    VARIABLE(20, u_u32, UInt32Type, DiscreteInput),
    VARIABLE(21, y_u32, UInt32Type, Calculated),
    VARIABLE(22, u_i64, Int64Type, DiscreteInput),
    VARIABLE(23, y_i64, Int64Type, Calculated),
    VARIABLE(24, u_u64, UInt64Type, DiscreteInput),
    VARIABLE(25, y_u64, UInt64Type, Calculated),
    VARIABLE(30, u_bool, BooleanType, DiscreteInput),
    VARIABLE(31, y_bool, BooleanType, Calculated),
    VARIABLE(32, invert, BooleanType, Tunable),
    VARIABLE(40, u_str, StringType, DiscreteInput),
    VARIABLE(41, y_str, StringType, Calculated),
    VARIABLE(42, prefix, StringType, Tunable),
    VARIABLE(50, u_bin, BinaryType, DiscreteInput),
    VARIABLE(51, y_bin, BinaryType, Calculated),
    VARIABLE(60, u_color, Int64Type, DiscreteInput),
    VARIABLE(61, y_color, Int64Type, Calculated),
};
const size_t NUMBER_OF_VARIABLES = sizeof(VARIABLES) / sizeof(VARIABLES[0]);

#define M(v) (comp->data->v)

Status setStartValues(ModelInstance *comp) {
    M(scale) = 1.0;
    strcpy(M(prefix), "id: ");
    M(u_color) = 1;
    return OK;  /* all else starts at zero, false, "" and no bytes */
}

Status initialize(ModelInstance *comp) {
    (void)comp;
    return OK;
}

Status calculateValues(ModelInstance *comp) {
    if (M(u_color) < 1 || M(u_color) > 3) {
        logError(comp, "u_color = %lld is not a Color (1 red, 2 green, 3 blue)", (long long)M(u_color));
        return Error;
    }
    if (strlen(M(prefix)) + strlen(M(u_str)) >= STRING_SIZE) {
        logError(comp, "prefix + u_str is longer than %d characters", STRING_SIZE - 1);
        return Error;
    }
    M(time) = comp->time;
    M(y_f32) = M(u_f32);
    M(y_f64) = M(scale) * M(u_f64);
    M(y_i8) = M(u_i8);
    M(y_u8) = M(u_u8);
    M(y_i16) = M(u_i16);
    M(y_u16) = M(u_u16);
    M(y_i32) = M(u_i32);
    M(y_u32) = M(u_u32);
    M(y_i64) = M(u_i64);
    M(y_u64) = M(u_u64);
    M(y_bool) = M(u_bool) != M(invert);
    strcat(strcpy(M(y_str), M(prefix)), M(u_str));  /* fits: checked above */
    M(y_bin) = M(u_bin);
    M(y_color) = M(u_color);
    return OK;
}

void getContinuousStates(ModelInstance *comp, double x[]) { (void)comp, (void)x; }

void setContinuousStates(ModelInstance *comp, const double x[]) { (void)comp, (void)x; }

void getDerivatives(ModelInstance *comp, double dx[]) { (void)comp, (void)dx; }

void getEventIndicators(ModelInstance *comp, double z[]) { (void)comp, (void)z; }

void eventUpdate(ModelInstance *comp) { comp->nextEventTimeDefined = false; }

bool advance(ModelInstance *comp, double t_stop) {
    comp->time = t_stop;
    return false;
}
