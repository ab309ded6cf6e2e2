/* What the FMI 2.0 and FMI 3.0 front ends (plumbing.c, plumbing3.c) share: the instance and
 * its state checks, logging, the event iteration, the Co-Simulation step loop with events and
 * FMU state snapshots (see plumbing.h). */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plumbing.h"

#define MAX_EVENT_ITERATIONS 100

/* --- logging and checks --------------------------------------------------------------------- */

static void logMessage(ModelInstance *comp, Status status, const char *category, const char *format,
                       va_list args) {
    char message[1024];
    vsnprintf(message, sizeof(message), format, args);
    if (comp->log != NULL && comp->logger != NULL) comp->log(comp, status, category, message);
}

void logError(ModelInstance *comp, const char *format, ...) {
    va_list args;
    va_start(args, format);
    logMessage(comp, Error, "logStatusError", format, args);
    va_end(args);
}

void logWarning(ModelInstance *comp, const char *format, ...) {
    va_list args;
    va_start(args, format);
    logMessage(comp, Warning, "logStatusWarning", format, args);
    va_end(args);
}

void logInfo(ModelInstance *comp, const char *format, ...) {
    if (!comp->loggingOn) return;
    va_list args;
    va_start(args, format);
    logMessage(comp, OK, "logEvents", format, args);
    va_end(args);
}

bool timeEventDue(const ModelInstance *comp) {
    return comp->nextEventTimeDefined &&
           comp->time >= comp->nextEventTime - 1e-12 * fmax(1.0, fabs(comp->nextEventTime));
}

Status checkSettable(ModelInstance *comp, const char *name, Settable kind) {
    ModelState s = comp->state;
    bool ok = kind != Calculated && (s == Instantiated || s == InitializationMode);
    if (kind == Tunable) ok = ok || s == EventMode || s == StepMode;
    if (kind == ContinuousInput) ok = ok || s == EventMode || s == ContinuousTimeMode || s == StepMode;
    if (kind == DiscreteInput) ok = ok || s == EventMode || s == StepMode;
    if (ok) return OK;
    static const char *const what[] = {"fixed parameter", "tunable parameter", "continuous input",
                                       "discrete input", "calculated variable"};
    logError(comp, "%s %s cannot be set in the current state (%d)", what[kind], name, (int)s);
    return Error;
}

Status copyString(ModelInstance *comp, char *target, const char *value) {
    if (value == NULL) value = "";
    if (strlen(value) >= STRING_SIZE) {
        logError(comp, "string of %zu characters is longer than %d", strlen(value), STRING_SIZE - 1);
        return Error;
    }
    strcpy(target, value);
    return OK;
}

bool invalidState(ModelInstance *comp, const char *function, int allowed) {
    if (comp == NULL) return true;
    if (allowed & STATE(comp->state)) return false;
    logError(comp, "%s must not be called in state %d", function, (int)comp->state);
    return true;
}

Status unsupported(ModelInstance *comp, const char *function) {
    if (comp == NULL) return Error;
    logError(comp, "%s is not supported", function);
    return Error;
}

bool wrongSize(ModelInstance *comp, const char *function, size_t n, size_t expected) {
    if (n == expected) return false;
    logError(comp, "%s: expected %zu values, got %zu", function, expected, n);
    return true;
}

/* --- the instance ------------------------------------------------------------------------------ */

ModelInstance *newInstance(const char *instanceName, InterfaceType type, bool loggingOn, LogFunction log,
                           void (*logger)(void), void *environment, const char *resourceDir) {
    ModelInstance *comp = calloc(1, sizeof(ModelInstance));
    if (comp == NULL) return NULL;
    comp->data = calloc(1, MODEL_DATA_SIZE);
    comp->instanceName = strdup(instanceName);
    if (comp->data == NULL || comp->instanceName == NULL) {
        freeInstance(comp);
        return NULL;
    }
    comp->type = type;
    comp->state = Instantiated;
    comp->loggingOn = loggingOn;
    comp->categories = ~0u;  /* all */
    comp->log = log;
    comp->logger = logger;
    comp->environment = environment;
    if (strlen(resourceDir) < sizeof(comp->resourceDir)) strcpy(comp->resourceDir, resourceDir);
    if (setStartValues(comp) > Warning) {
        freeInstance(comp);
        return NULL;
    }
    return comp;
}

void freeInstance(ModelInstance *comp) {
    if (comp == NULL) return;
    free(comp->data);
    free(comp->instanceName);
    free(comp);
}

Status resetInstance(ModelInstance *comp) {
    memset(comp->data, 0, MODEL_DATA_SIZE);
    comp->state = Instantiated;
    comp->startTime = comp->time = 0.0;
    comp->nextEventTimeDefined = comp->terminateSimulation = false;
    comp->maxStepSize = 0.0;
    comp->activeClocks = comp->intervalsGiven = 0;
    return setStartValues(comp);
}

/* --- events and steps -------------------------------------------------------------------------- */

void eventRound(ModelInstance *comp) {
    comp->newDiscreteStatesNeeded = false;
    comp->terminateSimulation = false;
    comp->valuesOfContinuousStatesChanged = false;
    eventUpdate(comp);
}

void eventIteration(ModelInstance *comp) {
    for (int i = 0; i < MAX_EVENT_ITERATIONS; i++) {
        eventRound(comp);
        if (comp->terminateSimulation || !comp->newDiscreteStatesNeeded) return;
    }
}

static double roundOff(double t) { return 1e-12 * fmax(1.0, fabs(t)); }

Status checkStep(ModelInstance *comp, const char *function, double t, double h) {
    if (h <= 0 || fabs(t - comp->time) > 1e3 * roundOff(t + h)) {
        logError(comp, "%s: cannot step from %.17g by %g (the FMU is at %.17g)", function, t, h, comp->time);
        return Error;
    }
    if (comp->maxStepSize > 0 && h > comp->maxStepSize * (1 + 1e-12)) {
        logError(comp, "%s: a step of %g s is longer than the %g s this FMU can take", function, h,
                 comp->maxStepSize);
        return Discard;
    }
    return OK;
}

StepOutcome stepTo(ModelInstance *comp, double t_end, EventHandling handling) {
    const double eps = roundOff(t_end);
    while (comp->time < t_end - eps) {
        double t_stop = comp->nextEventTimeDefined && comp->nextEventTime < t_end ? comp->nextEventTime : t_end;
        bool stateEvent = advance(comp, t_stop);
        if (!stateEvent && !timeEventDue(comp)) continue;
        bool atEnd = comp->time >= t_end - eps;
        if (handling == ReturnAtEvents || (handling == ReturnAtLastEvent && atEnd)) {
            if (atEnd) comp->time = t_end;
            logInfo(comp, "event at t = %.17g: returning to the importer", comp->time);
            return StoppedAtEvent;
        }
        eventIteration(comp);
        if (comp->terminateSimulation) {
            logInfo(comp, "terminated the simulation at t = %.17g", comp->time);
            return StoppedTerminated;
        }
    }
    comp->time = t_end;
    return ReachedEnd;
}

/* --- FMU state snapshots ------------------------------------------------------------------------ */

typedef struct {
    ModelState state;
    double time;
    bool terminateSimulation, nextEventTimeDefined;
    double nextEventTime;
    unsigned char data[];
} Snapshot;

size_t snapshotSize(void) { return sizeof(Snapshot) + MODEL_DATA_SIZE; }

Status getSnapshot(ModelInstance *comp, void **snapshot) {
    Snapshot *s = *snapshot != NULL ? *snapshot : malloc(snapshotSize());
    if (s == NULL) return Error;
    s->state = comp->state;
    s->time = comp->time;
    s->terminateSimulation = comp->terminateSimulation;
    s->nextEventTimeDefined = comp->nextEventTimeDefined;
    s->nextEventTime = comp->nextEventTime;
    memcpy(s->data, comp->data, MODEL_DATA_SIZE);
    *snapshot = s;
    return OK;
}

Status setSnapshot(ModelInstance *comp, const void *snapshot) {
    const Snapshot *s = snapshot;
    if (s == NULL) return Error;
    comp->state = s->state;
    comp->time = s->time;
    comp->terminateSimulation = s->terminateSimulation;
    comp->nextEventTimeDefined = s->nextEventTimeDefined;
    comp->nextEventTime = s->nextEventTime;
    memcpy(comp->data, s->data, MODEL_DATA_SIZE);
    return OK;
}
