/* Every fmi2 function of Model Exchange and Co-Simulation for the models of tests/third_party
 * (see plumbing.h). Kept small: a state machine that rejects calls in the wrong state, the
 * Co-Simulation step loop with events, FMU state snapshots by copying the model's data. */
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "plumbing.h"

#define MAX_EVENT_ITERATIONS 100

/* --- helpers -------------------------------------------------------------------------------- */

static void logMessage(ModelInstance *comp, fmi2Status status, const char *category, const char *format,
                       va_list args) {
    char message[1024];
    vsnprintf(message, sizeof(message), format, args);
    if (comp->logger) {
        comp->logger(comp->environment, comp->instanceName, status, category, message);
    }
}

void logError(ModelInstance *comp, const char *format, ...) {
    va_list args;
    va_start(args, format);
    logMessage(comp, fmi2Error, "logStatusError", format, args);
    va_end(args);
}

void logInfo(ModelInstance *comp, const char *format, ...) {
    if (!comp->loggingOn) return;
    va_list args;
    va_start(args, format);
    logMessage(comp, fmi2OK, "logEvents", format, args);
    va_end(args);
}

bool timeEventDue(const ModelInstance *comp) {
    return comp->nextEventTimeDefined &&
           comp->time >= comp->nextEventTime - 1e-12 * fmax(1.0, fabs(comp->nextEventTime));
}

fmi2Status checkSettable(ModelInstance *comp, const char *name, Settable kind) {
    ModelState s = comp->state;
    bool ok = s == Instantiated || s == InitializationMode;
    if (kind == Tunable) ok = ok || s == EventMode || s == StepComplete;
    if (kind == ContinuousInput) ok = ok || s == EventMode || s == ContinuousTimeMode || s == StepComplete;
    if (kind == DiscreteInput) ok = ok || s == EventMode || s == StepComplete;
    if (ok) return fmi2OK;
    static const char *const what[] = {"fixed parameter", "tunable parameter", "continuous input",
                                       "discrete input"};
    logError(comp, "%s %s cannot be set in the current state (%d)", what[kind], name, (int)s);
    return fmi2Error;
}

fmi2Status copyString(ModelInstance *comp, char *target, fmi2String value) {
    if (value == NULL) value = "";
    if (strlen(value) >= STRING_SIZE) {
        logError(comp, "string of %zu characters is longer than %d", strlen(value), STRING_SIZE - 1);
        return fmi2Error;
    }
    strcpy(target, value);
    return fmi2OK;
}

/* `allowed` lists the states in which `function` may be called. */
static bool invalidState(ModelInstance *comp, const char *function, int allowed) {
    if (comp == NULL) return true;
    if (allowed & (1 << comp->state)) return false;
    logError(comp, "%s must not be called in state %d", function, (int)comp->state);
    return true;
}

#define ANY_STATE 0xff
#define STATE(s) (1 << (s))
#define CHECK(function, allowed)                                              \
    ModelInstance *comp = (ModelInstance *)c;                                 \
    if (invalidState(comp, function, allowed)) return fmi2Error;

/* "file:///a/b%20c/resources" -> "/a/b c/resources/" */
static void resourcePath(const char *uri, char *path, size_t size) {
    path[0] = '\0';
    if (uri == NULL || strncmp(uri, "file:", 5) != 0) return;
    const char *p = uri + 5;
    if (strncmp(p, "//", 2) == 0) {
        p += 2;
        p = strchr(p, '/');  /* skip the (empty) authority */
        if (p == NULL) return;
    }
    size_t n = 0;
    for (; *p && n + 2 < size; p++) {
        if (*p == '%' && p[1] && p[2]) {
            char hex[3] = {p[1], p[2], 0};
            path[n++] = (char)strtol(hex, NULL, 16);
            p += 2;
        } else {
            path[n++] = *p;
        }
    }
    if (n > 0 && path[n - 1] != '/') path[n++] = '/';
    path[n] = '\0';
}

static void eventIteration(ModelInstance *comp) {
    for (int i = 0; i < MAX_EVENT_ITERATIONS; i++) {
        comp->newDiscreteStatesNeeded = false;
        comp->terminateSimulation = false;
        comp->valuesOfContinuousStatesChanged = false;
        eventUpdate(comp);
        if (comp->terminateSimulation || !comp->newDiscreteStatesNeeded) return;
    }
}

/* --- common functions ------------------------------------------------------------------------ */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }

const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Status fmi2SetDebugLogging(fmi2Component c, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    CHECK("fmi2SetDebugLogging", ANY_STATE)
    (void)nCategories, (void)categories;
    comp->loggingOn = loggingOn != fmi2False;
    return fmi2OK;
}

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)visible;
    if (instanceName == NULL || fmuGUID == NULL || strcmp(fmuGUID, MODEL_GUID) != 0) return NULL;
    ModelInstance *comp = calloc(1, sizeof(ModelInstance));
    if (comp == NULL) return NULL;
    comp->data = calloc(1, MODEL_DATA_SIZE);
    comp->instanceName = strdup(instanceName);
    comp->type = fmuType;
    comp->state = Instantiated;
    comp->loggingOn = loggingOn != fmi2False;
    if (functions != NULL) {
        comp->logger = functions->logger;
        comp->environment = functions->componentEnvironment;
    }
    resourcePath(fmuResourceLocation, comp->resourceDir, sizeof(comp->resourceDir));
    setStartValues(comp);
    return comp;
}

void fmi2FreeInstance(fmi2Component c) {
    ModelInstance *comp = (ModelInstance *)c;
    if (comp == NULL) return;
    free(comp->data);
    free(comp->instanceName);
    free(comp);
}

fmi2Status fmi2SetupExperiment(fmi2Component c, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    CHECK("fmi2SetupExperiment", STATE(Instantiated))
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    comp->startTime = comp->time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component c) {
    CHECK("fmi2EnterInitializationMode", STATE(Instantiated))
    comp->state = InitializationMode;
    return fmi2OK;
}

fmi2Status fmi2ExitInitializationMode(fmi2Component c) {
    CHECK("fmi2ExitInitializationMode", STATE(InitializationMode))
    fmi2Status status = initialize(comp);
    if (status > fmi2Warning) {
        comp->state = ErrorState;
        return status;
    }
    if (comp->type == fmi2ModelExchange) {
        comp->state = EventMode;  /* the importer runs the initial event iteration */
    } else {
        eventIteration(comp);
        comp->state = StepComplete;
    }
    return status;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    CHECK("fmi2Terminate", STATE(EventMode) | STATE(ContinuousTimeMode) | STATE(StepComplete) | STATE(StepFailed))
    comp->state = Terminated;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    CHECK("fmi2Reset", ANY_STATE)
    memset(comp->data, 0, MODEL_DATA_SIZE);
    comp->state = Instantiated;
    comp->startTime = comp->time = 0.0;
    comp->nextEventTimeDefined = comp->terminateSimulation = false;
    comp->maxStepSize = 0.0;
    setStartValues(comp);
    return fmi2OK;
}

/* --- getters and setters ---------------------------------------------------------------------- */

#define GET_SET(Type, CType)                                                                      \
    fmi2Status fmi2Get##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, CType value[]) { \
        CHECK("fmi2Get" #Type, ~STATE(Instantiated))                                              \
        for (size_t i = 0; i < nvr; i++) {                                                        \
            if (get##Type(comp, vr[i], &value[i]) != fmi2OK) {                                    \
                logError(comp, "fmi2Get" #Type ": cannot get value reference %u", vr[i]);         \
                return fmi2Error;                                                                 \
            }                                                                                     \
        }                                                                                         \
        return fmi2OK;                                                                            \
    }                                                                                             \
    fmi2Status fmi2Set##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const CType value[]) { \
        CHECK("fmi2Set" #Type, ~(STATE(Terminated) | STATE(ErrorState) | STATE(StepFailed)))      \
        for (size_t i = 0; i < nvr; i++) {                                                        \
            if (set##Type(comp, vr[i], value[i]) != fmi2OK) {                                     \
                logError(comp, "fmi2Set" #Type ": cannot set value reference %u", vr[i]);         \
                return fmi2Error;                                                                 \
            }                                                                                     \
        }                                                                                         \
        return fmi2OK;                                                                            \
    }

GET_SET(Real, fmi2Real)
GET_SET(Integer, fmi2Integer)
GET_SET(Boolean, fmi2Boolean)
GET_SET(String, fmi2String)

/* --- FMU state: a copy of the model's data and the instance's time and event flags ----------- */

typedef struct {
    ModelState state;
    double time;
    bool terminateSimulation, nextEventTimeDefined;
    double nextEventTime;
    unsigned char data[];
} Snapshot;

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK("fmi2GetFMUstate", ~STATE(ErrorState))
    Snapshot *s = *FMUstate != NULL ? *FMUstate : malloc(sizeof(Snapshot) + MODEL_DATA_SIZE);
    if (s == NULL) return fmi2Error;
    s->state = comp->state;
    s->time = comp->time;
    s->terminateSimulation = comp->terminateSimulation;
    s->nextEventTimeDefined = comp->nextEventTimeDefined;
    s->nextEventTime = comp->nextEventTime;
    memcpy(s->data, comp->data, MODEL_DATA_SIZE);
    *FMUstate = s;
    return fmi2OK;
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    CHECK("fmi2SetFMUstate", ~STATE(ErrorState))
    const Snapshot *s = FMUstate;
    if (s == NULL) return fmi2Error;
    comp->state = s->state;
    comp->time = s->time;
    comp->terminateSimulation = s->terminateSimulation;
    comp->nextEventTimeDefined = s->nextEventTimeDefined;
    comp->nextEventTime = s->nextEventTime;
    memcpy(comp->data, s->data, MODEL_DATA_SIZE);
    return fmi2OK;
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK("fmi2FreeFMUstate", ANY_STATE)
    free(*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

static fmi2Status unsupported(fmi2Component c, const char *function) {
    CHECK(function, ANY_STATE)
    logError(comp, "%s is not supported", function);
    return fmi2Error;
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    (void)FMUstate, (void)size;
    return unsupported(c, "fmi2SerializedFMUstateSize");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte bytes[], size_t size) {
    (void)FMUstate, (void)bytes, (void)size;
    return unsupported(c, "fmi2SerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *FMUstate) {
    (void)bytes, (void)size, (void)FMUstate;
    return unsupported(c, "fmi2DeSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown, (void)dvUnknown;
    return unsupported(c, "fmi2GetDirectionalDerivative");
}

/* --- Model Exchange ---------------------------------------------------------------------------- */

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    CHECK("fmi2EnterEventMode", STATE(EventMode) | STATE(ContinuousTimeMode))
    comp->state = EventMode;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    CHECK("fmi2NewDiscreteStates", STATE(EventMode))
    comp->newDiscreteStatesNeeded = false;
    comp->terminateSimulation = false;
    comp->valuesOfContinuousStatesChanged = false;
    eventUpdate(comp);
    eventInfo->newDiscreteStatesNeeded = comp->newDiscreteStatesNeeded;
    eventInfo->terminateSimulation = comp->terminateSimulation;
    eventInfo->nominalsOfContinuousStatesChanged = fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = comp->valuesOfContinuousStatesChanged;
    eventInfo->nextEventTimeDefined = comp->nextEventTimeDefined;
    eventInfo->nextEventTime = comp->nextEventTime;
    return fmi2OK;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component c) {
    CHECK("fmi2EnterContinuousTimeMode", STATE(EventMode))
    comp->state = ContinuousTimeMode;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component c, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    CHECK("fmi2CompletedIntegratorStep", STATE(ContinuousTimeMode))
    (void)noSetFMUStatePriorToCurrentPoint;
    *enterEventMode = fmi2False;
    *terminateSimulation = fmi2False;
    return fmi2OK;
}

fmi2Status fmi2SetTime(fmi2Component c, fmi2Real time) {
    CHECK("fmi2SetTime", STATE(EventMode) | STATE(ContinuousTimeMode))
    comp->time = time;
    return fmi2OK;
}

static bool wrongSize(ModelInstance *comp, const char *function, size_t n, size_t expected) {
    if (n == expected) return false;
    logError(comp, "%s: expected %zu values, got %zu", function, expected, n);
    return true;
}

fmi2Status fmi2SetContinuousStates(fmi2Component c, const fmi2Real x[], size_t nx) {
    CHECK("fmi2SetContinuousStates", STATE(ContinuousTimeMode))
    if (wrongSize(comp, "fmi2SetContinuousStates", nx, NUMBER_OF_STATES)) return fmi2Error;
    setContinuousStates(comp, x);
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component c, fmi2Real derivatives[], size_t nx) {
    CHECK("fmi2GetDerivatives", ~STATE(Instantiated))
    if (wrongSize(comp, "fmi2GetDerivatives", nx, NUMBER_OF_STATES)) return fmi2Error;
    getDerivatives(comp, derivatives);
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component c, fmi2Real eventIndicators[], size_t ni) {
    CHECK("fmi2GetEventIndicators", ~STATE(Instantiated))
    if (wrongSize(comp, "fmi2GetEventIndicators", ni, NUMBER_OF_EVENT_INDICATORS)) return fmi2Error;
    getEventIndicators(comp, eventIndicators);
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component c, fmi2Real x[], size_t nx) {
    CHECK("fmi2GetContinuousStates", ~STATE(Instantiated))
    if (wrongSize(comp, "fmi2GetContinuousStates", nx, NUMBER_OF_STATES)) return fmi2Error;
    getContinuousStates(comp, x);
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component c, fmi2Real x_nominal[], size_t nx) {
    CHECK("fmi2GetNominalsOfContinuousStates", ANY_STATE)
    if (wrongSize(comp, "fmi2GetNominalsOfContinuousStates", nx, NUMBER_OF_STATES)) return fmi2Error;
    for (size_t i = 0; i < nx; i++) x_nominal[i] = 1.0;
    return fmi2OK;
}

/* --- Co-Simulation ----------------------------------------------------------------------------- */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    return unsupported(c, "fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    CHECK("fmi2DoStep", STATE(StepComplete))
    (void)noSetFMUStatePriorToCurrentPoint;
    const double t_end = currentCommunicationPoint + communicationStepSize;
    const double eps = 1e-12 * fmax(1.0, fabs(t_end));
    if (communicationStepSize <= 0 || fabs(currentCommunicationPoint - comp->time) > 1e3 * eps) {
        logError(comp, "fmi2DoStep: cannot step from %.17g by %g (the FMU is at %.17g)",
                 currentCommunicationPoint, communicationStepSize, comp->time);
        return fmi2Error;
    }
    if (comp->maxStepSize > 0 && communicationStepSize > comp->maxStepSize * (1 + 1e-12)) {
        logError(comp, "fmi2DoStep: a step of %g s is longer than the %g s this FMU can take",
                 communicationStepSize, comp->maxStepSize);
        return fmi2Discard;
    }
    while (comp->time < t_end - eps) {
        double t_stop = comp->nextEventTimeDefined && comp->nextEventTime < t_end ? comp->nextEventTime : t_end;
        bool stateEvent = advance(comp, t_stop);
        if (stateEvent || timeEventDue(comp)) {
            eventIteration(comp);
            if (comp->terminateSimulation) {
                logInfo(comp, "terminated the simulation at t = %.17g", comp->time);
                comp->state = StepFailed;
                return fmi2Discard;
            }
        }
    }
    comp->time = t_end;
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { return unsupported(c, "fmi2CancelStep"); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s, (void)value;
    return unsupported(c, "fmi2GetStatus");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    CHECK("fmi2GetRealStatus", STATE(StepComplete) | STATE(StepFailed))
    if (s != fmi2LastSuccessfulTime) return unsupported(c, "fmi2GetRealStatus (other than fmi2LastSuccessfulTime)");
    *value = comp->time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s, (void)value;
    return unsupported(c, "fmi2GetIntegerStatus");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    CHECK("fmi2GetBooleanStatus", STATE(StepComplete) | STATE(StepFailed))
    if (s != fmi2Terminated) return unsupported(c, "fmi2GetBooleanStatus (other than fmi2Terminated)");
    *value = comp->terminateSimulation;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s, (void)value;
    return unsupported(c, "fmi2GetStringStatus");
}
