/* A 1-D table read from a text file (lines "u y", '#' starts a comment, u increasing) and its
 * linear interpolation, held constant beyond the ends; shared by LookupTable (FMI 2.0) and
 * Table3 (FMI 3.0). */
#ifndef TABLE_H
#define TABLE_H

#include <stdio.h>
#include <string.h>

#include "plumbing.h"

#define MAX_ROWS 64

typedef struct {
    int rows;
    double u[MAX_ROWS], y[MAX_ROWS];
} Table;

/* OK, or Error (logged, naming the file and line) when the file cannot be read or is not a table. */
static inline Status tableRead(ModelInstance *comp, Table *table, const char *path) {
    FILE *file = fopen(path, "r");
    if (file == NULL) {
        logError(comp, "cannot open the table '%s'", path);
        return Error;
    }
    char line[256];
    int number = 0;
    table->rows = 0;
    while (fgets(line, sizeof(line), file) != NULL) {
        number++;
        char *comment = strchr(line, '#');
        if (comment != NULL) *comment = '\0';
        double u, y;
        char rest;
        int found = sscanf(line, " %lf %lf %c", &u, &y, &rest);
        if (found <= 0) continue;  /* blank */
        int n = table->rows;
        if (found != 2 || n == MAX_ROWS || (n > 0 && u <= table->u[n - 1])) {
            logError(comp, "%s:%d: expected two numbers 'u y' with u increasing (at most %d rows)", path, number,
                     MAX_ROWS);
            fclose(file);
            return Error;
        }
        table->u[n] = u;
        table->y[n] = y;
        table->rows++;
    }
    fclose(file);
    if (table->rows == 0) {
        logError(comp, "%s: no rows", path);
        return Error;
    }
    return OK;
}

static inline double tableInterpolate(const Table *table, double u) {
    int n = table->rows;
    if (u <= table->u[0]) return table->y[0];
    if (u >= table->u[n - 1]) return table->y[n - 1];
    int i = 1;
    while (table->u[i] < u) i++;
    return table->y[i - 1] + (table->y[i] - table->y[i - 1]) * (u - table->u[i - 1]) / (table->u[i] - table->u[i - 1]);
}

#endif
