/* LookupTable: y = table(u), linear interpolation in a table read from the FMU's resources
 * (the file named by the String parameter `file`; lines "u y", '#' starts a comment), held
 * constant beyond its ends. `rows` tells how many rows were read.
 */
#include <stdio.h>
#include <string.h>

#include "plumbing.h"

#define MAX_ROWS 64

enum { vr_u = 0, vr_y = 1, vr_rows = 10, vr_file = 20 };

struct ModelData {
    char file[STRING_SIZE];
    double u;
    int rows;
    double table[MAX_ROWS][2];
};

const char *const MODEL_GUID = "{5b0f3c1e-6a3d-4a53-9c61-2f1a1f7c0a03}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = 0;
const size_t NUMBER_OF_EVENT_INDICATORS = 0;

#define M(v) (comp->data->v)

void setStartValues(ModelInstance *comp) {
    strcpy(M(file), "table.txt");
    M(u) = 0.0;
}

fmi2Status initialize(ModelInstance *comp) {
    char path[sizeof(comp->resourceDir) + STRING_SIZE];
    snprintf(path, sizeof(path), "%s%s", comp->resourceDir, M(file));
    FILE *file = fopen(path, "r");
    if (file == NULL) {
        logError(comp, "cannot open the table '%s'", path);
        return fmi2Error;
    }
    char line[256];
    int number = 0;
    M(rows) = 0;
    while (fgets(line, sizeof(line), file) != NULL) {
        number++;
        char *comment = strchr(line, '#');
        if (comment != NULL) *comment = '\0';
        double u, y;
        char rest;
        int found = sscanf(line, " %lf %lf %c", &u, &y, &rest);
        if (found <= 0) continue;  /* blank */
        if (found != 2 || M(rows) == MAX_ROWS || (M(rows) > 0 && u <= M(table)[M(rows) - 1][0])) {
            logError(comp, "%s:%d: expected two numbers 'u y' with u increasing (at most %d rows)",
                     path, number, MAX_ROWS);
            fclose(file);
            return fmi2Error;
        }
        M(table)[M(rows)][0] = u;
        M(table)[M(rows)][1] = y;
        M(rows)++;
    }
    fclose(file);
    if (M(rows) == 0) {
        logError(comp, "%s: no rows", path);
        return fmi2Error;
    }
    return fmi2OK;
}

static double interpolate(const ModelInstance *comp, double u) {
    int n = M(rows);
    if (u <= M(table)[0][0]) return M(table)[0][1];
    if (u >= M(table)[n - 1][0]) return M(table)[n - 1][1];
    int i = 1;
    while (M(table)[i][0] < u) i++;
    double u0 = M(table)[i - 1][0], y0 = M(table)[i - 1][1];
    double u1 = M(table)[i][0], y1 = M(table)[i][1];
    return y0 + (y1 - y0) * (u - u0) / (u1 - u0);
}

fmi2Status getReal(ModelInstance *comp, fmi2ValueReference vr, fmi2Real *value) {
    switch (vr) {
        case vr_u: *value = M(u); return fmi2OK;
        case vr_y:
            if (M(rows) == 0) return fmi2Error;  /* not initialized */
            *value = interpolate(comp, M(u));
            return fmi2OK;
        default: return fmi2Error;
    }
}

fmi2Status setReal(ModelInstance *comp, fmi2ValueReference vr, fmi2Real value) {
    if (vr != vr_u || checkSettable(comp, "u", ContinuousInput)) return fmi2Error;
    M(u) = value;
    return fmi2OK;
}

fmi2Status getInteger(ModelInstance *comp, fmi2ValueReference vr, fmi2Integer *value) {
    if (vr != vr_rows) return fmi2Error;
    *value = M(rows);
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
    if (vr != vr_file) return fmi2Error;
    *value = M(file);
    return fmi2OK;
}

fmi2Status setString(ModelInstance *comp, fmi2ValueReference vr, fmi2String value) {
    if (vr != vr_file || checkSettable(comp, "file", Fixed)) return fmi2Error;
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
