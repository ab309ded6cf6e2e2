/* LookupTable: y = table(u), linear interpolation in a table read from the FMU's resources
 * (the file named by the String parameter `file`; lines "u y", '#' starts a comment), held
 * constant beyond its ends. `rows` tells how many rows were read.
 */
#include <stdio.h>
#include <string.h>

#include "plumbing.h"
#include "shared/table.h"

enum { vr_u = 0, vr_y = 1, vr_rows = 10, vr_file = 20 };

struct ModelData {
    char file[STRING_SIZE];
    double u;
    Table table;
};

const char *const MODEL_GUID = "{5b0f3c1e-6a3d-4a53-9c61-2f1a1f7c0a03}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = 0;
const size_t NUMBER_OF_EVENT_INDICATORS = 0;

#define M(v) (comp->data->v)

Status setStartValues(ModelInstance *comp) {
    strcpy(M(file), "table.txt");
    M(u) = 0.0;
    return OK;
}

Status initialize(ModelInstance *comp) {
    char path[sizeof(comp->resourceDir) + STRING_SIZE];
    snprintf(path, sizeof(path), "%s%s", comp->resourceDir, M(file));
    return tableRead(comp, &M(table), path);
}

Status getReal(ModelInstance *comp, ValueReference vr, double *value) {
    switch (vr) {
        case vr_u: *value = M(u); return OK;
        case vr_y:
            if (M(table).rows == 0) return Error;  /* not initialized */
            *value = tableInterpolate(&M(table), M(u));
            return OK;
        default: return Error;
    }
}

Status setReal(ModelInstance *comp, ValueReference vr, double value) {
    if (vr != vr_u || checkSettable(comp, "u", ContinuousInput)) return Error;
    M(u) = value;
    return OK;
}

Status getInteger(ModelInstance *comp, ValueReference vr, int *value) {
    if (vr != vr_rows) return Error;
    *value = M(table).rows;
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
    if (vr != vr_file) return Error;
    *value = M(file);
    return OK;
}

Status setString(ModelInstance *comp, ValueReference vr, const char *value) {
    if (vr != vr_file || checkSettable(comp, "file", Fixed)) return Error;
    return copyString(comp, M(file), value);
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
