/* Every fmi2 function of Model Exchange and Co-Simulation for the models of tests/third_party
 * (see plumbing.h): the FMI 2.0 front end of common.c. */
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "plumbing.h"

/* The importer's logger, called with the FMI 2.0 signature. */
static void logFMI2(ModelInstance *comp, Status status, const char *category, const char *message) {
    ((fmi2CallbackLogger)comp->logger)(comp->environment, comp->instanceName, (fmi2Status)status, category,
                                       message);
}

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
    char resources[sizeof(((ModelInstance *)0)->resourceDir)];
    resourcePath(fmuResourceLocation, resources, sizeof(resources));
    return newInstance(instanceName, fmuType == fmi2ModelExchange ? ModelExchange : CoSimulation,
                       loggingOn != fmi2False, logFMI2, functions != NULL ? (void (*)(void))functions->logger : NULL,
                       functions != NULL ? functions->componentEnvironment : NULL, resources);
}

void fmi2FreeInstance(fmi2Component c) { freeInstance((ModelInstance *)c); }

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
    Status status = initialize(comp);
    if (status > Warning) {
        comp->state = ErrorState;
        return (fmi2Status)status;
    }
    if (comp->type == ModelExchange) {
        comp->state = EventMode;  /* the importer runs the initial event iteration */
    } else {
        eventIteration(comp);
        comp->state = StepMode;
    }
    return (fmi2Status)status;
}

fmi2Status fmi2Terminate(fmi2Component c) {
    CHECK("fmi2Terminate", STATE(EventMode) | STATE(ContinuousTimeMode) | STATE(StepMode) | STATE(StepDiscarded))
    comp->state = Terminated;
    return fmi2OK;
}

fmi2Status fmi2Reset(fmi2Component c) {
    CHECK("fmi2Reset", ANY_STATE)
    return (fmi2Status)resetInstance(comp);
}

/* --- getters and setters ---------------------------------------------------------------------- */

#define GET_SET(Type, CType, ModelType, toFMI, fromFMI)                                           \
    fmi2Status fmi2Get##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, CType value[]) { \
        CHECK("fmi2Get" #Type, ~STATE(Instantiated))                                              \
        for (size_t i = 0; i < nvr; i++) {                                                        \
            ModelType v;                                                                          \
            if (get##Type(comp, vr[i], &v) != OK) {                                               \
                logError(comp, "fmi2Get" #Type ": cannot get value reference %u", vr[i]);         \
                return fmi2Error;                                                                 \
            }                                                                                     \
            value[i] = toFMI(v);                                                                  \
        }                                                                                         \
        return fmi2OK;                                                                            \
    }                                                                                             \
    fmi2Status fmi2Set##Type(fmi2Component c, const fmi2ValueReference vr[], size_t nvr, const CType value[]) { \
        CHECK("fmi2Set" #Type, ~(STATE(Terminated) | STATE(ErrorState) | STATE(StepDiscarded)))   \
        for (size_t i = 0; i < nvr; i++) {                                                        \
            if (set##Type(comp, vr[i], fromFMI(value[i])) != OK) {                                \
                logError(comp, "fmi2Set" #Type ": cannot set value reference %u", vr[i]);         \
                return fmi2Error;                                                                 \
            }                                                                                     \
        }                                                                                         \
        return fmi2OK;                                                                            \
    }

#define SAME(v) (v)
#define TO_FMI2_BOOLEAN(v) ((v) ? fmi2True : fmi2False)
#define FROM_FMI2_BOOLEAN(v) ((v) != fmi2False)

GET_SET(Real, fmi2Real, double, SAME, SAME)
GET_SET(Integer, fmi2Integer, int, SAME, SAME)
GET_SET(Boolean, fmi2Boolean, bool, TO_FMI2_BOOLEAN, FROM_FMI2_BOOLEAN)
GET_SET(String, fmi2String, const char *, SAME, SAME)

/* --- FMU state ----------------------------------------------------------------------------------- */

fmi2Status fmi2GetFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK("fmi2GetFMUstate", ~STATE(ErrorState))
    return (fmi2Status)getSnapshot(comp, FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component c, fmi2FMUstate FMUstate) {
    CHECK("fmi2SetFMUstate", ~STATE(ErrorState))
    return (fmi2Status)setSnapshot(comp, FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component c, fmi2FMUstate *FMUstate) {
    CHECK("fmi2FreeFMUstate", ANY_STATE)
    free(*FMUstate);
    *FMUstate = NULL;
    return fmi2OK;
}

#define UNSUPPORTED(function) return (fmi2Status)unsupported((ModelInstance *)c, function)

fmi2Status fmi2SerializedFMUstateSize(fmi2Component c, fmi2FMUstate FMUstate, size_t *size) {
    (void)FMUstate, (void)size;
    UNSUPPORTED("fmi2SerializedFMUstateSize");
}

fmi2Status fmi2SerializeFMUstate(fmi2Component c, fmi2FMUstate FMUstate, fmi2Byte bytes[], size_t size) {
    (void)FMUstate, (void)bytes, (void)size;
    UNSUPPORTED("fmi2SerializeFMUstate");
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component c, const fmi2Byte bytes[], size_t size, fmi2FMUstate *FMUstate) {
    (void)bytes, (void)size, (void)FMUstate;
    UNSUPPORTED("fmi2DeSerializeFMUstate");
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component c, const fmi2ValueReference vUnknown_ref[], size_t nUnknown,
                                        const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    (void)vUnknown_ref, (void)nUnknown, (void)vKnown_ref, (void)nKnown, (void)dvKnown, (void)dvUnknown;
    UNSUPPORTED("fmi2GetDirectionalDerivative");
}

/* --- Model Exchange ---------------------------------------------------------------------------- */

fmi2Status fmi2EnterEventMode(fmi2Component c) {
    CHECK("fmi2EnterEventMode", STATE(EventMode) | STATE(ContinuousTimeMode))
    comp->state = EventMode;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component c, fmi2EventInfo *eventInfo) {
    CHECK("fmi2NewDiscreteStates", STATE(EventMode))
    eventRound(comp);
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
    UNSUPPORTED("fmi2SetRealInputDerivatives");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component c, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    (void)vr, (void)nvr, (void)order, (void)value;
    UNSUPPORTED("fmi2GetRealOutputDerivatives");
}

fmi2Status fmi2DoStep(fmi2Component c, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    CHECK("fmi2DoStep", STATE(StepMode))
    (void)noSetFMUStatePriorToCurrentPoint;
    Status status = checkStep(comp, "fmi2DoStep", currentCommunicationPoint, communicationStepSize);
    if (status != OK) return (fmi2Status)status;
    if (stepTo(comp, currentCommunicationPoint + communicationStepSize, HandleEvents) == StoppedTerminated) {
        comp->state = StepDiscarded;
        return fmi2Discard;
    }
    return fmi2OK;
}

fmi2Status fmi2CancelStep(fmi2Component c) { UNSUPPORTED("fmi2CancelStep"); }

fmi2Status fmi2GetStatus(fmi2Component c, const fmi2StatusKind s, fmi2Status *value) {
    (void)s, (void)value;
    UNSUPPORTED("fmi2GetStatus");
}

fmi2Status fmi2GetRealStatus(fmi2Component c, const fmi2StatusKind s, fmi2Real *value) {
    CHECK("fmi2GetRealStatus", STATE(StepMode) | STATE(StepDiscarded))
    if (s != fmi2LastSuccessfulTime) UNSUPPORTED("fmi2GetRealStatus (other than fmi2LastSuccessfulTime)");
    *value = comp->time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component c, const fmi2StatusKind s, fmi2Integer *value) {
    (void)s, (void)value;
    UNSUPPORTED("fmi2GetIntegerStatus");
}

fmi2Status fmi2GetBooleanStatus(fmi2Component c, const fmi2StatusKind s, fmi2Boolean *value) {
    CHECK("fmi2GetBooleanStatus", STATE(StepMode) | STATE(StepDiscarded))
    if (s != fmi2Terminated) UNSUPPORTED("fmi2GetBooleanStatus (other than fmi2Terminated)");
    *value = comp->terminateSimulation;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component c, const fmi2StatusKind s, fmi2String *value) {
    (void)s, (void)value;
    UNSUPPORTED("fmi2GetStringStatus");
}
