/* Table3: y = table(u), linear interpolation (held constant beyond the ends) in the table
 * resources/table.txt, read when the FMU is instantiated (from the resourcePath the importer
 * passes; instantiation fails when it cannot be read). `rows` tells how many rows were read.
 */
#include <stdio.h>

#include "plumbing.h"
#include "shared/table.h"

struct ModelData {
    double time, u, y;
    uint16_t rows;
    Table table;
};

const char *const MODEL_GUID = "{8c4e2a90-3f1b-4d6e-9a7c-5b2d1e0f3a05}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = 0;
const size_t NUMBER_OF_EVENT_INDICATORS = 0;

const Variable VARIABLES[] = {
    VARIABLE(0, time, Float64Type, Calculated),
    VARIABLE(1, u, Float64Type, ContinuousInput),
    VARIABLE(2, y, Float64Type, Calculated),
    VARIABLE(3, rows, UInt16Type, Calculated),
};
const size_t NUMBER_OF_VARIABLES = sizeof(VARIABLES) / sizeof(VARIABLES[0]);

#define M(v) (comp->data->v)

Status setStartValues(ModelInstance *comp) {
    if (comp->resourceDir[0] == '\0') {
        logError(comp, "no resourcePath: cannot read the table");
        return Error;
    }
    char path[sizeof(comp->resourceDir) + 16];
    snprintf(path, sizeof(path), "%stable.txt", comp->resourceDir);
    M(u) = 0.0;
    return tableRead(comp, &M(table), path);
}

Status initialize(ModelInstance *comp) {
    (void)comp;
    return OK;
}

Status calculateValues(ModelInstance *comp) {
    M(time) = comp->time;
    M(rows) = (uint16_t)M(table).rows;
    M(y) = tableInterpolate(&M(table), M(u));
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
