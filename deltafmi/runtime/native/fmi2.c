/* deltafmi's FMI 2.0 binary: every fmi2 function of Model Exchange and Co-Simulation over the
 * shared plumbing of core.c. It enforces the FMI 2.0 state machines (sections 3.2.3 and 4.2.4)
 * and maps FMI 2.0's types and rules; the work is core.c's and the model's (bridge.c).
 *
 * Built with hidden visibility: the binary exports the fmi2 functions and nothing else, so it can
 * neither interpose on a host's symbols nor be interposed by them. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "core.h"

#define MASK_GET (InitializationMode | EventMode | ContinuousTimeMode | StepComplete | StepFailed | \
                  StepCanceled | Terminated | Error)
#define MASK_SET (Instantiated | InitializationMode | EventMode | ContinuousTimeMode | StepComplete)
#define MASK_ME_GET (InitializationMode | EventMode | ContinuousTimeMode | Terminated | Error)

#define CHECK(function, mask) \
    do { if (!dfmi_allowed(c, function, mask)) return fmi2Error; } while (0)
#define CHECK_ARRAYS(function) \
    do { if (nvr > 0 && (!vr || !value)) return (fmi2Status)dfmi_fail(c, "%s: NULL array argument", function); } while (0)

/* FMI 2.0's logger takes a format string: '%' is escaped (some hosts, fmpy among them, print the
 * message without formatting). */
static void emit2(fmi2CallbackLogger logger, fmi2ComponentEnvironment env, const char *name, int status,
                  const char *category, const char *message) {
    if (!logger) return;
    size_t n = strlen(message), extra = 0;
    for (size_t i = 0; i < n; i++) extra += message[i] == '%';
    char *escaped = malloc(n + extra + 1);
    if (!escaped) return;
    char *p = escaped;
    for (size_t i = 0; i < n; i++) {
        *p++ = message[i];
        if (message[i] == '%') *p++ = '%';
    }
    *p = 0;
    logger(env, name ? name : "", (fmi2Status)status, category, escaped);
    free(escaped);
}

static void emit_instance(const Instance *c, int status, const char *category, const char *message) {
    fmi2CallbackLogger logger;
    memcpy(&logger, &c->host_logger, sizeof logger);
    emit2(logger, c->host_env, c->name, status, category, message);
}

/* resources URI -> path: file:///a/b, file:/a/b, file://localhost/a/b, with %XX decoding; some
 * hosts pass nothing: <fmu>/binaries/linux64/../../resources */
static char *resources_path(const char *uri) {
    if (!uri || !uri[0]) return dfmi_default_resources();
    const char *p = uri;
    if (!strncmp(p, "file://localhost/", 17)) p += 16;
    else if (!strncmp(p, "file:///", 8)) p += 7;
    else if (!strncmp(p, "file:/", 6)) p += 5;
    char *path = malloc(strlen(p) + 1), *q = path;
    if (!path) return NULL;
    for (; *p; p++) {
        if (p[0] == '%' && p[1] && p[2]) {
            char hex[3] = {p[1], p[2], 0};
            *q++ = (char)strtol(hex, NULL, 16);
            p += 2;
        } else {
            *q++ = *p;
        }
    }
    *q = 0;
    size_t n = strlen(path);
    while (n > 1 && path[n - 1] == '/') path[--n] = 0;
    return path;
}

/* ---------------------------------------------------------------------------------------- */
/* common functions                                                                          */

const char *fmi2GetTypesPlatform(void) { return fmi2TypesPlatform; }
const char *fmi2GetVersion(void) { return fmi2Version; }

fmi2Component fmi2Instantiate(fmi2String instanceName, fmi2Type fmuType, fmi2String fmuGUID,
                              fmi2String fmuResourceLocation, const fmi2CallbackFunctions *functions,
                              fmi2Boolean visible, fmi2Boolean loggingOn) {
    (void)visible;
    if (!functions || !functions->logger) return NULL; /* FMI 2.0 requires a logger: errors would be silent */
    if (!instanceName || !instanceName[0]) {
        emit2(functions->logger, functions->componentEnvironment, "", fmi2Error, "logStatusError",
              "fmi2Instantiate: missing instance name");
        return NULL;
    }
    if (fmuType != fmi2ModelExchange && fmuType != fmi2CoSimulation) {
        emit2(functions->logger, functions->componentEnvironment, instanceName, fmi2Error, "logStatusError",
              "fmi2Instantiate: unknown fmuType");
        return NULL;
    }
    void (*logger)(void);
    memcpy(&logger, &functions->logger, sizeof logger);
    Instance *c = dfmi_new_instance(instanceName, 2, fmuType == fmi2ModelExchange ? DFMI_MODEL_EXCHANGE
                                    : DFMI_CO_SIMULATION, emit_instance, functions->componentEnvironment,
                                    logger, loggingOn);
    if (!c) return NULL;
    char *resources = resources_path(fmuResourceLocation);
    int connected = dfmi_connect(c, resources, fmuGUID);
    free(resources);
    if (connected != 0) {
        dfmi_free_instance(c);
        return NULL;
    }
    return c;
}

void fmi2FreeInstance(fmi2Component component) { dfmi_free_instance(component); }

fmi2Status fmi2SetDebugLogging(fmi2Component component, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    Instance *c = component;
    CHECK("fmi2SetDebugLogging", ANY_INSTANCE);
    return (fmi2Status)dfmi_set_debug_logging(c, "fmi2SetDebugLogging", loggingOn, nCategories, categories);
}

fmi2Status fmi2SetupExperiment(fmi2Component component, fmi2Boolean toleranceDefined, fmi2Real tolerance,
                               fmi2Real startTime, fmi2Boolean stopTimeDefined, fmi2Real stopTime) {
    Instance *c = component;
    CHECK("fmi2SetupExperiment", Instantiated);
    c->tolerance_defined = toleranceDefined;
    c->tolerance = tolerance;
    c->start_time = startTime;
    c->stop_defined = stopTimeDefined;
    c->stop_time = stopTime;
    c->time = startTime;
    return fmi2OK;
}

fmi2Status fmi2EnterInitializationMode(fmi2Component component) {
    Instance *c = component;
    CHECK("fmi2EnterInitializationMode", Instantiated);
    return (fmi2Status)dfmi_enter_initialization(c);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component component) {
    Instance *c = component;
    CHECK("fmi2ExitInitializationMode", InitializationMode);
    return (fmi2Status)dfmi_exit_initialization(c, c->interface == DFMI_MODEL_EXCHANGE ? EventMode : StepComplete);
}

fmi2Status fmi2Terminate(fmi2Component component) {
    Instance *c = component;
    CHECK("fmi2Terminate", EventMode | ContinuousTimeMode | StepComplete | StepFailed);
    return (fmi2Status)dfmi_terminate(c);
}

fmi2Status fmi2Reset(fmi2Component component) {
    Instance *c = component;
    CHECK("fmi2Reset", ANY_INSTANCE);
    return (fmi2Status)dfmi_reset(c);
}

/* ---------------------------------------------------------------------------------------- */
/* values                                                                                    */

fmi2Status fmi2GetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *c = component;
    CHECK("fmi2GetReal", MASK_GET);
    CHECK_ARRAYS("fmi2GetReal");
    int derivatives = 0;
    for (size_t i = 0; i < nvr && !derivatives; i++) derivatives = dfmi_is_derivative(c, vr[i], 1);
    if (nvr && dfmi_ensure_values(c, derivatives) >= fmi2Error) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= c->L.n_real)
            return (fmi2Status)dfmi_fail(c, "fmi2GetReal: %u is not the value reference of a Real", vr[i]);
        value[i] = c->L.real[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *c = component;
    CHECK("fmi2SetReal", MASK_SET);
    CHECK_ARRAYS("fmi2SetReal");
    const int bit = dfmi_setter_bit(c);
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= c->L.n_real)
            return (fmi2Status)dfmi_fail(c, "fmi2SetReal: %u is not the value reference of a Real", vr[i]);
        if (!dfmi_settable(c, "fmi2SetReal", vr[i], bit)) return fmi2Error;
    }
    for (size_t i = 0; i < nvr; i++) c->L.real[vr[i]] = value[i];
    dfmi_values_changed(c);
    return fmi2OK;
}

/* Integer and Boolean share the int buffer; value references continue after the reals. */
static fmi2Status get_ints(Instance *c, const char *function, int boolean, const fmi2ValueReference vr[],
                           size_t nvr, int value[]) {
    CHECK_ARRAYS(function);
    if (nvr && dfmi_ensure_values(c, 0) >= fmi2Error) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        if (!dfmi_is_int(c, vr[i], boolean))
            return (fmi2Status)dfmi_fail(c, "%s: %u is not the value reference of %s", function, vr[i],
                                         boolean ? "a Boolean" : "an Integer");
        value[i] = c->L.ints[vr[i] - c->L.n_real];
    }
    return fmi2OK;
}

static fmi2Status set_ints(Instance *c, const char *function, int boolean, const fmi2ValueReference vr[],
                           size_t nvr, const int value[]) {
    CHECK_ARRAYS(function);
    const int bit = dfmi_setter_bit(c);
    for (size_t i = 0; i < nvr; i++) {
        if (!dfmi_is_int(c, vr[i], boolean))
            return (fmi2Status)dfmi_fail(c, "%s: %u is not the value reference of %s", function, vr[i],
                                         boolean ? "a Boolean" : "an Integer");
        if (!dfmi_settable(c, function, vr[i], bit)) return fmi2Error;
    }
    for (size_t i = 0; i < nvr; i++) c->L.ints[vr[i] - c->L.n_real] = boolean ? (value[i] != 0) : value[i];
    dfmi_values_changed(c);
    return fmi2OK;
}

fmi2Status fmi2GetInteger(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, fmi2Integer value[]) {
    Instance *c = component;
    CHECK("fmi2GetInteger", MASK_GET);
    return get_ints(c, "fmi2GetInteger", 0, vr, nvr, value);
}

fmi2Status fmi2SetInteger(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, const fmi2Integer value[]) {
    Instance *c = component;
    CHECK("fmi2SetInteger", MASK_SET);
    return set_ints(c, "fmi2SetInteger", 0, vr, nvr, value);
}

fmi2Status fmi2GetBoolean(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, fmi2Boolean value[]) {
    Instance *c = component;
    CHECK("fmi2GetBoolean", MASK_GET);
    return get_ints(c, "fmi2GetBoolean", 1, vr, nvr, value);
}

fmi2Status fmi2SetBoolean(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, const fmi2Boolean value[]) {
    Instance *c = component;
    CHECK("fmi2SetBoolean", MASK_SET);
    return set_ints(c, "fmi2SetBoolean", 1, vr, nvr, value);
}

fmi2Status fmi2GetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    Instance *c = component;
    CHECK("fmi2GetString", MASK_GET);
    CHECK_ARRAYS("fmi2GetString");
    for (size_t i = 0; i < nvr; i++)
        if (dfmi_get_string(c, "fmi2GetString", vr[i], &value[i]) >= fmi2Error) return fmi2Error;
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    Instance *c = component;
    CHECK("fmi2SetString", MASK_SET);
    CHECK_ARRAYS("fmi2SetString");
    for (size_t i = 0; i < nvr; i++)
        if (dfmi_set_string(c, "fmi2SetString", vr[i], value[i]) >= fmi2Error) return fmi2Error;
    return fmi2OK;
}

/* ---------------------------------------------------------------------------------------- */
/* FMU state                                                                                 */

fmi2Status fmi2GetFMUstate(fmi2Component component, fmi2FMUstate *FMUstate) {
    Instance *c = component;
    CHECK("fmi2GetFMUstate", ANY_INSTANCE);
    return (fmi2Status)dfmi_get_fmu_state(c, "fmi2GetFMUstate", FMUstate);
}

fmi2Status fmi2SetFMUstate(fmi2Component component, fmi2FMUstate FMUstate) {
    Instance *c = component;
    CHECK("fmi2SetFMUstate", ANY_INSTANCE);
    return (fmi2Status)dfmi_set_fmu_state(c, "fmi2SetFMUstate", FMUstate);
}

fmi2Status fmi2FreeFMUstate(fmi2Component component, fmi2FMUstate *FMUstate) {
    Instance *c = component;
    CHECK("fmi2FreeFMUstate", ANY_INSTANCE);
    return (fmi2Status)dfmi_free_fmu_state(c, "fmi2FreeFMUstate", FMUstate);
}

fmi2Status fmi2SerializedFMUstateSize(fmi2Component component, fmi2FMUstate FMUstate, size_t *size) {
    Instance *c = component;
    CHECK("fmi2SerializedFMUstateSize", ANY_INSTANCE);
    return (fmi2Status)dfmi_serialized_size(c, "fmi2SerializedFMUstateSize", FMUstate, size);
}

fmi2Status fmi2SerializeFMUstate(fmi2Component component, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    Instance *c = component;
    CHECK("fmi2SerializeFMUstate", ANY_INSTANCE);
    return (fmi2Status)dfmi_serialize(c, "fmi2SerializeFMUstate", FMUstate, (unsigned char *)serializedState, size);
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component component, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    Instance *c = component;
    CHECK("fmi2DeSerializeFMUstate", ANY_INSTANCE);
    return (fmi2Status)dfmi_deserialize(c, "fmi2DeSerializeFMUstate", (const unsigned char *)serializedState, size,
                                        FMUstate);
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component component, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    Instance *c = component;
    CHECK("fmi2GetDirectionalDerivative", MASK_GET);
    if ((nUnknown && (!vUnknown_ref || !dvUnknown)) || (nKnown && (!vKnown_ref || !dvKnown)))
        return (fmi2Status)dfmi_fail(c, "fmi2GetDirectionalDerivative: NULL array argument");
    if (!nUnknown) return fmi2OK;
    /* the model reads the states and inputs straight from its buffers; the values it computes on
     * the way are restored, so the dirty flags stay true */
    return (fmi2Status)dfmi_settle(c, bridge_directional_derivative(c->py, "fmi2GetDirectionalDerivative", c->time,
                                                                    vUnknown_ref, nUnknown, vKnown_ref, nKnown, dvKnown,
                                                                    dvUnknown));
}

/* ---------------------------------------------------------------------------------------- */
/* Model Exchange                                                                            */

fmi2Status fmi2EnterEventMode(fmi2Component component) {
    Instance *c = component;
    CHECK("fmi2EnterEventMode", EventMode | ContinuousTimeMode);
    c->state = EventMode;
    return fmi2OK;
}

fmi2Status fmi2NewDiscreteStates(fmi2Component component, fmi2EventInfo *eventInfo) {
    Instance *c = component;
    CHECK("fmi2NewDiscreteStates", EventMode);
    if (!eventInfo) return (fmi2Status)dfmi_fail(c, "fmi2NewDiscreteStates: NULL eventInfo");
    int flags[5];
    double next;
    int status = dfmi_update_discrete_states(c, flags, &next);
    /* the FMU owns fmi2EventInfo: every field is written, whatever happened */
    eventInfo->newDiscreteStatesNeeded = flags[0] ? fmi2True : fmi2False;
    eventInfo->terminateSimulation = flags[1] ? fmi2True : fmi2False;
    eventInfo->nominalsOfContinuousStatesChanged = flags[2] ? fmi2True : fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = flags[3] ? fmi2True : fmi2False;
    eventInfo->nextEventTimeDefined = flags[4] ? fmi2True : fmi2False;
    eventInfo->nextEventTime = next;
    return (fmi2Status)status;
}

fmi2Status fmi2EnterContinuousTimeMode(fmi2Component component) {
    Instance *c = component;
    CHECK("fmi2EnterContinuousTimeMode", EventMode);
    c->state = ContinuousTimeMode;
    return fmi2OK;
}

fmi2Status fmi2CompletedIntegratorStep(fmi2Component component, fmi2Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi2Boolean *enterEventMode, fmi2Boolean *terminateSimulation) {
    Instance *c = component;
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK("fmi2CompletedIntegratorStep", ContinuousTimeMode);
    if (!enterEventMode || !terminateSimulation)
        return (fmi2Status)dfmi_fail(c, "fmi2CompletedIntegratorStep: NULL argument");
    int enter, terminate;
    int status = dfmi_completed_integrator_step(c, &enter, &terminate);
    *enterEventMode = enter ? fmi2True : fmi2False;
    *terminateSimulation = terminate ? fmi2True : fmi2False;
    return (fmi2Status)status;
}

fmi2Status fmi2SetTime(fmi2Component component, fmi2Real time) {
    Instance *c = component;
    CHECK("fmi2SetTime", EventMode | ContinuousTimeMode);
    c->time = time;
    dfmi_values_changed(c);
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component component, const fmi2Real x[], size_t nx) {
    Instance *c = component;
    CHECK("fmi2SetContinuousStates", ContinuousTimeMode);
    return (fmi2Status)dfmi_set_continuous_states(c, "fmi2SetContinuousStates", x, nx);
}

fmi2Status fmi2GetDerivatives(fmi2Component component, fmi2Real derivatives[], size_t nx) {
    Instance *c = component;
    CHECK("fmi2GetDerivatives", MASK_ME_GET);
    return (fmi2Status)dfmi_get_derivatives(c, "fmi2GetDerivatives", derivatives, nx);
}

fmi2Status fmi2GetEventIndicators(fmi2Component component, fmi2Real eventIndicators[], size_t ni) {
    Instance *c = component;
    CHECK("fmi2GetEventIndicators", MASK_ME_GET);
    return (fmi2Status)dfmi_get_event_indicators(c, "fmi2GetEventIndicators", eventIndicators, ni);
}

fmi2Status fmi2GetContinuousStates(fmi2Component component, fmi2Real x[], size_t nx) {
    Instance *c = component;
    CHECK("fmi2GetContinuousStates", MASK_ME_GET);
    return (fmi2Status)dfmi_get_continuous_states(c, "fmi2GetContinuousStates", x, nx);
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component component, fmi2Real x_nominal[], size_t nx) {
    Instance *c = component;
    CHECK("fmi2GetNominalsOfContinuousStates", Instantiated | EventMode | ContinuousTimeMode | Terminated | Error);
    return (fmi2Status)dfmi_get_nominals(c, "fmi2GetNominalsOfContinuousStates", x_nominal, nx);
}

/* ---------------------------------------------------------------------------------------- */
/* Co-Simulation                                                                             */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    Instance *c = component;
    (void)vr; (void)nvr; (void)order; (void)value;
    CHECK("fmi2SetRealInputDerivatives", Instantiated | InitializationMode | StepComplete);
    return (fmi2Status)dfmi_fail(c, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs=false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    Instance *c = component;
    (void)vr; (void)nvr; (void)order; (void)value;
    CHECK("fmi2GetRealOutputDerivatives", StepComplete | StepFailed | StepCanceled | Terminated | Error);
    return (fmi2Status)dfmi_fail(c, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder=0)");
}

fmi2Status fmi2DoStep(fmi2Component component, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *c = component;
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK("fmi2DoStep", StepComplete);
    int status = dfmi_do_step(c, "fmi2DoStep", currentCommunicationPoint, communicationStepSize,
                              DFMI_EVENTS_INSIDE);
    if (status >= fmi2Error) return (fmi2Status)dfmi_settle(c, status);
    int ended = dfmi_terminated(c);
    if (ended && status < fmi2Discard) status = fmi2Discard; /* a component that steps itself ended it */
    if (status == fmi2OK || status == fmi2Warning) {
        c->time = currentCommunicationPoint + communicationStepSize;
        c->last_successful_time = c->time;
        c->dirty = c->outputs_dirty = 0;
    } else if (status == fmi2Discard) {
        c->state = StepFailed;
        if (ended) { /* fmi2Terminated; fmi2LastSuccessfulTime is where the component ended it */
            double reached = c->L.control[1];
            c->terminated_by_model = 1;
            c->time = c->last_successful_time =
                isnan(reached) ? currentCommunicationPoint + communicationStepSize : reached;
        }
    }
    return (fmi2Status)dfmi_settle(c, status);
}

fmi2Status fmi2CancelStep(fmi2Component component) {
    Instance *c = component;
    CHECK("fmi2CancelStep", StepInProgress);
    return fmi2Error; /* unreachable: steps are synchronous */
}

#define MASK_STATUS (StepComplete | StepInProgress | StepFailed | Terminated)

fmi2Status fmi2GetStatus(fmi2Component component, const fmi2StatusKind s, fmi2Status *value) {
    Instance *c = component;
    CHECK("fmi2GetStatus", MASK_STATUS);
    (void)s;
    if (value) *value = fmi2OK;
    dfmi_logf(c, fmi2Discard, "logStatusDiscard", "fmi2GetStatus: steps are synchronous, nothing is pending");
    return fmi2Discard;
}

fmi2Status fmi2GetRealStatus(fmi2Component component, const fmi2StatusKind s, fmi2Real *value) {
    Instance *c = component;
    CHECK("fmi2GetRealStatus", MASK_STATUS);
    if (s != fmi2LastSuccessfulTime || !value) return fmi2Discard;
    *value = c->last_successful_time;
    return fmi2OK;
}

fmi2Status fmi2GetIntegerStatus(fmi2Component component, const fmi2StatusKind s, fmi2Integer *value) {
    Instance *c = component;
    (void)s; (void)value;
    CHECK("fmi2GetIntegerStatus", MASK_STATUS);
    return fmi2Discard;
}

fmi2Status fmi2GetBooleanStatus(fmi2Component component, const fmi2StatusKind s, fmi2Boolean *value) {
    Instance *c = component;
    CHECK("fmi2GetBooleanStatus", MASK_STATUS);
    if (s != fmi2Terminated || !value) return fmi2Discard;
    *value = c->terminated_by_model ? fmi2True : fmi2False;
    return fmi2OK;
}

fmi2Status fmi2GetStringStatus(fmi2Component component, const fmi2StatusKind s, fmi2String *value) {
    Instance *c = component;
    (void)s; (void)value;
    CHECK("fmi2GetStringStatus", MASK_STATUS);
    return fmi2Discard;
}
