/* Every fmi3 function for the FMI 3.0 models of tests/third_party (see plumbing.h): the FMI 3.0
 * front end of common.c. Model Exchange and Co-Simulation (with and without Event Mode, with
 * early return at events), with the Clocks a model lists (clockVariables(): fmi3SetClock and
 * fmi3GetClock in Event Mode, fmi3GetIntervalDecimal/fmi3GetShiftDecimal of periodic ones);
 * Scheduled Execution, other clock functions, configuration mode and partial derivatives are not
 * offered, and their functions return fmi3Error. Variable values are read and written through
 * the model's VARIABLES table, arrays serialized row-major. */
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "plumbing.h"

/* The log categories of the FMI 3.0 models' modelDescription.xml. */
static const char *const LOG_CATEGORIES[] = {"logEvents", "logStatusWarning", "logStatusError"};
#define N_CATEGORIES (sizeof(LOG_CATEGORIES) / sizeof(LOG_CATEGORIES[0]))
#define ALL_CATEGORIES ((1u << N_CATEGORIES) - 1)

/* The importer's logMessage, called with the FMI 3.0 signature as the logging settings allow:
 * nothing unless loggingOn, then the categories enabled (all unless fmi3SetDebugLogging names some). */
static void logFMI3(ModelInstance *comp, Status status, const char *category, const char *message) {
    if (!comp->loggingOn) return;
    for (size_t i = 0; i < N_CATEGORIES; i++) {
        if (strcmp(category, LOG_CATEGORIES[i]) == 0 && !(comp->categories & (1u << i))) return;
    }
    ((fmi3LogMessageCallback)comp->logger)(comp->environment, (fmi3Status)status, category, message);
}

#define CHECK(function, allowed)                                              \
    ModelInstance *comp = (ModelInstance *)instance;                          \
    if (invalidState(comp, function, allowed)) return fmi3Error;

#define UNSUPPORTED(function) return (fmi3Status)unsupported((ModelInstance *)instance, function)

#define INITIALIZED (STATE(InitializationMode) | STATE(EventMode) | STATE(ContinuousTimeMode) | \
                     STATE(StepMode) | STATE(StepDiscarded) | STATE(Terminated))

/* --- instances ------------------------------------------------------------------------------ */

const char *fmi3GetVersion(void) { return fmi3Version; }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    CHECK("fmi3SetDebugLogging", ANY_STATE)
    unsigned enabled = nCategories == 0 ? ALL_CATEGORIES : 0;
    for (size_t i = 0; i < nCategories; i++) {
        size_t k = 0;
        while (k < N_CATEGORIES && strcmp(categories[i], LOG_CATEGORIES[k]) != 0) k++;
        if (k == N_CATEGORIES) {
            logError(comp, "fmi3SetDebugLogging: '%s' is not a log category of this FMU", categories[i]);
            return fmi3Error;
        }
        enabled |= 1u << k;
    }
    comp->loggingOn = loggingOn;
    comp->categories = enabled;
    return fmi3OK;
}

static ModelInstance *instantiate(fmi3String instanceName, InterfaceType type, fmi3String instantiationToken,
                                  fmi3String resourcePath, fmi3Boolean loggingOn,
                                  fmi3InstanceEnvironment environment, fmi3LogMessageCallback logMessage) {
    if (instanceName == NULL || instantiationToken == NULL || strcmp(instantiationToken, MODEL_GUID) != 0) {
        if (logMessage != NULL && loggingOn) {
            logMessage(environment, fmi3Error, "logStatusError",
                       "fmi3Instantiate: the instantiationToken is not that of this FMU's modelDescription.xml");
        }
        return NULL;
    }
    char resources[sizeof(((ModelInstance *)0)->resourceDir)] = "";
    if (resourcePath != NULL && strlen(resourcePath) + 2 < sizeof(resources)) {
        strcpy(resources, resourcePath);
        size_t n = strlen(resources);
        if (n > 0 && resources[n - 1] != '/') strcat(resources, "/");
    }
    return newInstance(instanceName, type, loggingOn, logFMI3, (void (*)(void))logMessage, environment, resources);
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)visible;
    return instantiate(instanceName, ModelExchange, instantiationToken, resourcePath, loggingOn,
                       instanceEnvironment, logMessage);
}

fmi3Instance fmi3InstantiateCoSimulation(fmi3String instanceName, fmi3String instantiationToken,
                                         fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                         fmi3Boolean eventModeUsed, fmi3Boolean earlyReturnAllowed,
                                         const fmi3ValueReference requiredIntermediateVariables[],
                                         size_t nRequiredIntermediateVariables,
                                         fmi3InstanceEnvironment instanceEnvironment,
                                         fmi3LogMessageCallback logMessage,
                                         fmi3IntermediateUpdateCallback intermediateUpdate) {
    (void)visible, (void)requiredIntermediateVariables, (void)intermediateUpdate;
    ModelInstance *comp = instantiate(instanceName, CoSimulation, instantiationToken, resourcePath, loggingOn,
                                      instanceEnvironment, logMessage);
    if (comp == NULL) return NULL;
    if (nRequiredIntermediateVariables > 0) {
        logError(comp, "fmi3InstantiateCoSimulation: this FMU has no intermediate variables");
        freeInstance(comp);
        return NULL;
    }
    comp->eventModeUsed = eventModeUsed;
    comp->earlyReturnAllowed = earlyReturnAllowed;
    return comp;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage,
                                               fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    (void)instanceName, (void)instantiationToken, (void)resourcePath, (void)visible, (void)loggingOn;
    (void)clockUpdate, (void)lockPreemption, (void)unlockPreemption;
    if (logMessage != NULL && loggingOn) {
        logMessage(instanceEnvironment, fmi3Error, "logStatusError",
                   "fmi3InstantiateScheduledExecution: this FMU offers Model Exchange and Co-Simulation only");
    }
    return NULL;
}

void fmi3FreeInstance(fmi3Instance instance) { freeInstance((ModelInstance *)instance); }

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    CHECK("fmi3EnterInitializationMode", STATE(Instantiated))
    (void)toleranceDefined, (void)tolerance, (void)stopTimeDefined, (void)stopTime;
    comp->startTime = comp->time = startTime;
    comp->state = InitializationMode;
    return fmi3OK;
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    CHECK("fmi3ExitInitializationMode", STATE(InitializationMode))
    Status status = initialize(comp);
    if (status > Warning) {
        comp->state = ErrorState;
        return (fmi3Status)status;
    }
    if (comp->type == ModelExchange || comp->eventModeUsed) {
        comp->state = EventMode;  /* the importer runs the initial event iteration */
    } else {
        eventIteration(comp);
        comp->state = StepMode;
    }
    return (fmi3Status)calculateValues(comp);
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    CHECK("fmi3EnterEventMode", STATE(ContinuousTimeMode) | STATE(StepMode))
    if (comp->type == CoSimulation && !comp->eventModeUsed) {
        logError(comp, "fmi3EnterEventMode: the importer instantiated this FMU without Event Mode");
        return fmi3Error;
    }
    comp->state = EventMode;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    CHECK("fmi3Terminate", STATE(EventMode) | STATE(ContinuousTimeMode) | STATE(StepMode) | STATE(StepDiscarded))
    comp->state = Terminated;
    return fmi3OK;
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    CHECK("fmi3Reset", ANY_STATE)
    return (fmi3Status)resetInstance(comp);
}

/* --- variable values --------------------------------------------------------------------------- */

static const char *const TYPE_NAMES[] = {"Float32", "Float64", "Int8", "UInt8", "Int16", "UInt16", "Int32",
                                         "UInt32", "Int64", "UInt64", "Boolean", "String", "Binary"};

static size_t elementSize(VariableType type) {
    static const size_t sizes[] = {sizeof(float), sizeof(double), 1, 1, 2, 2, 4, 4, 8, 8, sizeof(bool),
                                   STRING_SIZE, sizeof(BinaryValue)};
    return sizes[type];
}

/* The variable `vr` when it is of `type` and its elements fit into values[index .. nValues - 1],
 * else NULL (logged). */
static const Variable *variable(ModelInstance *comp, const char *function, ValueReference vr, VariableType type,
                                size_t index, size_t nValues) {
    for (size_t i = 0; i < NUMBER_OF_VARIABLES; i++) {
        const Variable *v = &VARIABLES[i];
        if (v->vr != vr) continue;
        if (v->type != type) {
            logError(comp, "%s: %s (value reference %u) is a %s variable", function, v->name, vr, TYPE_NAMES[v->type]);
            return NULL;
        }
        if (index + v->size / elementSize(type) > nValues) {
            logError(comp, "%s: nValues = %zu is too few for the elements of these variables", function, nValues);
            return NULL;
        }
        return v;
    }
    logError(comp, "%s: no variable has value reference %u", function, vr);
    return NULL;
}

static void *address(ModelInstance *comp, const Variable *v) { return (char *)comp->data + v->offset; }

/* A copy of the model's data before values are set: a set that fails leaves the values as they were. */
static void *before(ModelInstance *comp) {
    void *copy = malloc(MODEL_DATA_SIZE);
    if (copy != NULL) memcpy(copy, comp->data, MODEL_DATA_SIZE);
    return copy;
}

/* The values set are checked by calculateValues(); when they fail, the former values come back. */
static fmi3Status finishSet(ModelInstance *comp, void *former, Status status) {
    if (status == OK) status = calculateValues(comp);
    if (status > Warning && former != NULL) memcpy(comp->data, former, MODEL_DATA_SIZE);
    free(former);
    return (fmi3Status)status;
}

static Status getNumbers(ModelInstance *comp, const char *function, VariableType type, const fmi3ValueReference vr[],
                         size_t nvr, void *values, size_t nValues) {
    if (nvr > 0 && calculateValues(comp) > Warning) return Error;
    size_t size = elementSize(type), index = 0;
    for (size_t i = 0; i < nvr; i++) {
        const Variable *v = variable(comp, function, vr[i], type, index, nValues);
        if (v == NULL) return Error;
        memcpy((char *)values + index * size, address(comp, v), v->size);
        index += v->size / size;
    }
    return wrongSize(comp, function, nValues, index) ? Error : OK;
}

static Status setNumbers(ModelInstance *comp, const char *function, VariableType type, const fmi3ValueReference vr[],
                         size_t nvr, const void *values, size_t nValues) {
    size_t size = elementSize(type), index = 0;
    for (size_t i = 0; i < nvr; i++) {
        const Variable *v = variable(comp, function, vr[i], type, index, nValues);
        if (v == NULL || checkSettable(comp, v->name, v->settable) != OK) return Error;
        memcpy(address(comp, v), (const char *)values + index * size, v->size);
        index += v->size / size;
    }
    return wrongSize(comp, function, nValues, index) ? Error : OK;
}

#define GET_SET(Type, TypeId)                                                                                \
    fmi3Status fmi3Get##Type(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3##Type values[], \
                             size_t nValues) {                                                               \
        CHECK("fmi3Get" #Type, INITIALIZED)                                                                  \
        return (fmi3Status)getNumbers(comp, "fmi3Get" #Type, TypeId, vr, nvr, values, nValues);              \
    }                                                                                                        \
    fmi3Status fmi3Set##Type(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,               \
                             const fmi3##Type values[], size_t nValues) {                                    \
        CHECK("fmi3Set" #Type, ANY_STATE)                                                                    \
        void *former = before(comp);                                                                         \
        return finishSet(comp, former, setNumbers(comp, "fmi3Set" #Type, TypeId, vr, nvr, values, nValues)); \
    }

GET_SET(Float32, Float32Type)
GET_SET(Float64, Float64Type)
GET_SET(Int8, Int8Type)
GET_SET(UInt8, UInt8Type)
GET_SET(Int16, Int16Type)
GET_SET(UInt16, UInt16Type)
GET_SET(Int32, Int32Type)
GET_SET(UInt32, UInt32Type)
GET_SET(Int64, Int64Type)
GET_SET(UInt64, UInt64Type)
GET_SET(Boolean, BooleanType)

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3String values[],
                         size_t nValues) {
    CHECK("fmi3GetString", INITIALIZED)
    if (nvr > 0 && calculateValues(comp) > Warning) return fmi3Error;
    size_t index = 0;
    for (size_t i = 0; i < nvr; i++) {
        const Variable *v = variable(comp, "fmi3GetString", vr[i], StringType, index, nValues);
        if (v == NULL) return fmi3Error;
        for (size_t j = 0; j < v->size / STRING_SIZE; j++) values[index++] = (char *)address(comp, v) + j * STRING_SIZE;
    }
    return wrongSize(comp, "fmi3GetString", nValues, index) ? fmi3Error : fmi3OK;
}

static Status setStrings(ModelInstance *comp, const fmi3ValueReference vr[], size_t nvr, const fmi3String values[],
                         size_t nValues) {
    size_t index = 0;
    for (size_t i = 0; i < nvr; i++) {
        const Variable *v = variable(comp, "fmi3SetString", vr[i], StringType, index, nValues);
        if (v == NULL || checkSettable(comp, v->name, v->settable) != OK) return Error;
        for (size_t j = 0; j < v->size / STRING_SIZE; j++) {
            if (copyString(comp, (char *)address(comp, v) + j * STRING_SIZE, values[index++]) != OK) return Error;
        }
    }
    return wrongSize(comp, "fmi3SetString", nValues, index) ? Error : OK;
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3String values[],
                         size_t nValues) {
    CHECK("fmi3SetString", ANY_STATE)
    void *former = before(comp);
    return finishSet(comp, former, setStrings(comp, vr, nvr, values, nValues));
}

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nValues) {
    CHECK("fmi3GetBinary", INITIALIZED)
    if (nvr > 0 && calculateValues(comp) > Warning) return fmi3Error;
    size_t index = 0;
    for (size_t i = 0; i < nvr; i++) {
        const Variable *v = variable(comp, "fmi3GetBinary", vr[i], BinaryType, index, nValues);
        if (v == NULL) return fmi3Error;
        BinaryValue *elements = address(comp, v);
        for (size_t j = 0; j < v->size / sizeof(BinaryValue); j++, index++) {
            valueSizes[index] = elements[j].size;
            values[index] = elements[j].bytes;
        }
    }
    return wrongSize(comp, "fmi3GetBinary", nValues, index) ? fmi3Error : fmi3OK;
}

static Status setBinaries(ModelInstance *comp, const fmi3ValueReference vr[], size_t nvr, const size_t valueSizes[],
                          const fmi3Binary values[], size_t nValues) {
    size_t index = 0;
    for (size_t i = 0; i < nvr; i++) {
        const Variable *v = variable(comp, "fmi3SetBinary", vr[i], BinaryType, index, nValues);
        if (v == NULL || checkSettable(comp, v->name, v->settable) != OK) return Error;
        BinaryValue *elements = address(comp, v);
        for (size_t j = 0; j < v->size / sizeof(BinaryValue); j++, index++) {
            if (valueSizes[index] > BINARY_SIZE || (valueSizes[index] > 0 && values[index] == NULL)) {
                logError(comp, "fmi3SetBinary: %s: a value of %zu bytes (at most %d)", v->name, valueSizes[index],
                         BINARY_SIZE);
                return Error;
            }
            elements[j].size = valueSizes[index];
            if (valueSizes[index] > 0) memcpy(elements[j].bytes, values[index], valueSizes[index]);
        }
    }
    return wrongSize(comp, "fmi3SetBinary", nValues, index) ? Error : OK;
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    CHECK("fmi3SetBinary", ANY_STATE)
    void *former = before(comp);
    return finishSet(comp, former, setBinaries(comp, vr, nvr, valueSizes, values, nValues));
}

/* --- clocks (a model's periodic input Clocks, see plumbing.h) ----------------------------------- */

/* The model's default: no clocks (a model with clocks defines its own). */
__attribute__((weak)) const ClockVariable *clockVariables(size_t *n) {
    *n = 0;
    return NULL;
}

__attribute__((weak)) Status clockTiming(ModelInstance *comp, size_t i, double *interval, double *shift) {
    (void)comp, (void)i, (void)interval, (void)shift;
    return Error;
}

__attribute__((weak)) bool outputClockTicks(ModelInstance *comp, size_t i) {
    (void)comp, (void)i;
    return false;
}

/* The index of Clock `vr` in clockVariables(), or -1 (logged). */
static long clockIndex(ModelInstance *comp, const char *function, ValueReference vr) {
    size_t n;
    const ClockVariable *clocks = clockVariables(&n);
    for (size_t i = 0; i < n; i++) {
        if (clocks[i].vr == vr) return (long)i;
    }
    logError(comp, "%s: value reference %u is not a Clock of this FMU", function, vr);
    return -1;
}

fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[]) {
    CHECK("fmi3SetClock", STATE(EventMode))
    size_t n;
    const ClockVariable *clocks = clockVariables(&n);
    for (size_t i = 0; i < nvr; i++) {
        long k = clockIndex(comp, "fmi3SetClock", vr[i]);
        if (k < 0) return fmi3Error;
        if (clocks[k].output) {
            logError(comp, "fmi3SetClock: %s is an output Clock (the FMU activates it)", clocks[k].name);
            return fmi3Error;
        }
        if (values[i]) {
            comp->activeClocks |= 1u << k;
        } else {
            comp->activeClocks &= ~(1u << k);
        }
    }
    return fmi3OK;
}

fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[]) {
    CHECK("fmi3GetClock", STATE(EventMode))
    size_t n;
    const ClockVariable *clocks = clockVariables(&n);
    for (size_t i = 0; i < nvr; i++) {
        long k = clockIndex(comp, "fmi3GetClock", vr[i]);
        if (k < 0) return fmi3Error;
        values[i] = clocks[k].output ? outputClockTicks(comp, (size_t)k) : (comp->activeClocks >> k) & 1u;
    }
    return fmi3OK;
}

#define TIMING_STATES (STATE(InitializationMode) | STATE(EventMode))

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    CHECK("fmi3GetIntervalDecimal", TIMING_STATES)
    size_t n;
    const ClockVariable *clocks = clockVariables(&n);
    for (size_t i = 0; i < nvr; i++) {
        long k = clockIndex(comp, "fmi3GetIntervalDecimal", vr[i]);
        double shift;
        if (k < 0 || clockTiming(comp, (size_t)k, &intervals[i], &shift) > Warning) return fmi3Error;
        bool first = !clocks[k].constantInterval && comp->state == InitializationMode &&
                     !(comp->intervalsGiven & (1u << k));
        qualifiers[i] = first ? fmi3IntervalChanged : fmi3IntervalUnchanged;
        if (first) comp->intervalsGiven |= 1u << k;
    }
    return fmi3OK;
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               fmi3Float64 shifts[]) {
    CHECK("fmi3GetShiftDecimal", TIMING_STATES)
    for (size_t i = 0; i < nvr; i++) {
        long k = clockIndex(comp, "fmi3GetShiftDecimal", vr[i]);
        double interval;
        if (k < 0 || clockTiming(comp, (size_t)k, &interval, &shifts[i]) > Warning) return fmi3Error;
    }
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference vr, size_t *n) {
    (void)vr, (void)n;
    UNSUPPORTED("fmi3GetNumberOfVariableDependencies (see <ModelStructure>)");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    (void)dependent, (void)elementIndicesOfDependent, (void)independents, (void)elementIndicesOfIndependents;
    (void)dependencyKinds, (void)nDependencies;
    UNSUPPORTED("fmi3GetVariableDependencies (see <ModelStructure>)");
}

/* --- FMU state ------------------------------------------------------------------------------------ */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    CHECK("fmi3GetFMUState", ~STATE(ErrorState))
    return (fmi3Status)getSnapshot(comp, FMUState);
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    CHECK("fmi3SetFMUState", ~STATE(ErrorState))
    return (fmi3Status)setSnapshot(comp, FMUState);
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    CHECK("fmi3FreeFMUState", ANY_STATE)
    free(*FMUState);
    *FMUState = NULL;
    return fmi3OK;
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    CHECK("fmi3SerializedFMUStateSize", ANY_STATE)
    (void)FMUState;
    *size = snapshotSize();
    return fmi3OK;
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    CHECK("fmi3SerializeFMUState", ANY_STATE)
    if (FMUState == NULL || wrongSize(comp, "fmi3SerializeFMUState", size, snapshotSize())) return fmi3Error;
    memcpy(serializedState, FMUState, size);  /* a snapshot is plain data */
    return fmi3OK;
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    CHECK("fmi3DeserializeFMUState", ANY_STATE)
    if (wrongSize(comp, "fmi3DeserializeFMUState", size, snapshotSize())) return fmi3Error;
    void *s = *FMUState != NULL ? *FMUState : malloc(size);
    if (s == NULL) return fmi3Error;
    memcpy(s, serializedState, size);
    *FMUState = s;
    return fmi3OK;
}

/* --- what this FMU does not offer ------------------------------------------------------------------ */

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wunused-parameter"

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    UNSUPPORTED("fmi3GetDirectionalDerivative");
}

fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    UNSUPPORTED("fmi3GetAdjointDerivative");
}

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    UNSUPPORTED("fmi3EnterConfigurationMode (this FMU has no structural parameters)");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    UNSUPPORTED("fmi3ExitConfigurationMode (this FMU has no structural parameters)");
}

#define NO_CLOCKS(function, ...)                                                           \
    fmi3Status function(fmi3Instance instance, __VA_ARGS__) {                              \
        UNSUPPORTED(#function " (clocks: periodic input Clocks with the FMU's own intervals)"); \
    }

NO_CLOCKS(fmi3GetIntervalFraction, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 counters[],
          fmi3UInt64 resolutions[], fmi3IntervalQualifier qualifiers[])
NO_CLOCKS(fmi3GetShiftFraction, const fmi3ValueReference vr[], size_t nvr, fmi3UInt64 counters[],
          fmi3UInt64 resolutions[])
NO_CLOCKS(fmi3SetIntervalDecimal, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 intervals[])
NO_CLOCKS(fmi3SetIntervalFraction, const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 counters[],
          const fmi3UInt64 resolutions[])
NO_CLOCKS(fmi3SetShiftDecimal, const fmi3ValueReference vr[], size_t nvr, const fmi3Float64 shifts[])
NO_CLOCKS(fmi3SetShiftFraction, const fmi3ValueReference vr[], size_t nvr, const fmi3UInt64 counters[],
          const fmi3UInt64 resolutions[])
NO_CLOCKS(fmi3ActivateModelPartition, fmi3ValueReference clockReference, fmi3Float64 activationTime)

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    UNSUPPORTED("fmi3EvaluateDiscreteStates (Scheduled Execution is not offered)");
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    UNSUPPORTED("fmi3GetOutputDerivatives (maxOutputDerivativeOrder is 0)");
}

#pragma GCC diagnostic pop

/* --- events ------------------------------------------------------------------------------------ */

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    CHECK("fmi3UpdateDiscreteStates", STATE(EventMode))
    eventRound(comp);
    comp->activeClocks = 0;  /* the clocks set active are deactivated by this round */
    *discreteStatesNeedUpdate = comp->newDiscreteStatesNeeded;
    *terminateSimulation = comp->terminateSimulation;
    *nominalsOfContinuousStatesChanged = fmi3False;
    *valuesOfContinuousStatesChanged = comp->valuesOfContinuousStatesChanged;
    *nextEventTimeDefined = comp->nextEventTimeDefined;
    *nextEventTime = comp->nextEventTimeDefined ? comp->nextEventTime : 0.0;
    return (fmi3Status)calculateValues(comp);
}

/* --- Model Exchange ------------------------------------------------------------------------------ */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    CHECK("fmi3EnterContinuousTimeMode", STATE(EventMode))
    if (comp->type != ModelExchange) {
        logError(comp, "fmi3EnterContinuousTimeMode: a Co-Simulation instance leaves Event Mode with fmi3EnterStepMode");
        return fmi3Error;
    }
    comp->state = ContinuousTimeMode;
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    CHECK("fmi3CompletedIntegratorStep", STATE(ContinuousTimeMode))
    (void)noSetFMUStatePriorToCurrentPoint;
    *enterEventMode = fmi3False;
    *terminateSimulation = fmi3False;
    return fmi3OK;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    CHECK("fmi3SetTime", STATE(ContinuousTimeMode))
    comp->time = time;
    return fmi3OK;
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 x[], size_t nx) {
    CHECK("fmi3SetContinuousStates", STATE(ContinuousTimeMode))
    if (wrongSize(comp, "fmi3SetContinuousStates", nx, NUMBER_OF_STATES)) return fmi3Error;
    setContinuousStates(comp, x);
    return fmi3OK;
}

#define EVALUATED (STATE(InitializationMode) | STATE(EventMode) | STATE(ContinuousTimeMode) | STATE(Terminated))

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[], size_t nx) {
    CHECK("fmi3GetContinuousStateDerivatives", EVALUATED)
    if (wrongSize(comp, "fmi3GetContinuousStateDerivatives", nx, NUMBER_OF_STATES)) return fmi3Error;
    getDerivatives(comp, derivatives);
    return fmi3OK;
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t ni) {
    CHECK("fmi3GetEventIndicators", EVALUATED)
    if (wrongSize(comp, "fmi3GetEventIndicators", ni, NUMBER_OF_EVENT_INDICATORS)) return fmi3Error;
    getEventIndicators(comp, eventIndicators);
    return fmi3OK;
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 x[], size_t nx) {
    CHECK("fmi3GetContinuousStates", EVALUATED)
    if (wrongSize(comp, "fmi3GetContinuousStates", nx, NUMBER_OF_STATES)) return fmi3Error;
    getContinuousStates(comp, x);
    return fmi3OK;
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nx) {
    CHECK("fmi3GetNominalsOfContinuousStates", EVALUATED)
    if (wrongSize(comp, "fmi3GetNominalsOfContinuousStates", nx, NUMBER_OF_STATES)) return fmi3Error;
    for (size_t i = 0; i < nx; i++) nominals[i] = 1.0;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    CHECK("fmi3GetNumberOfEventIndicators", ~STATE(ErrorState))
    *nEventIndicators = NUMBER_OF_EVENT_INDICATORS;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    CHECK("fmi3GetNumberOfContinuousStates", ~STATE(ErrorState))
    *nContinuousStates = NUMBER_OF_STATES;
    return fmi3OK;
}

/* --- Co-Simulation ------------------------------------------------------------------------------- */

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    CHECK("fmi3EnterStepMode", STATE(EventMode))
    if (comp->type != CoSimulation) {
        logError(comp, "fmi3EnterStepMode: a Model Exchange instance has no Step Mode");
        return fmi3Error;
    }
    comp->state = StepMode;
    return fmi3OK;
}

fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    CHECK("fmi3DoStep", STATE(StepMode))
    (void)noSetFMUStatePriorToCurrentPoint;
    *eventHandlingNeeded = *terminateSimulation = *earlyReturn = fmi3False;
    *lastSuccessfulTime = comp->time;
    if (comp->terminateSimulation) {  /* the importer should have called fmi3Terminate */
        logWarning(comp, "fmi3DoStep: the FMU terminated the simulation at t = %.17g and stays there", comp->time);
        *terminateSimulation = fmi3True;
        *earlyReturn = comp->earlyReturnAllowed;
        return fmi3Warning;
    }
    Status status = checkStep(comp, "fmi3DoStep", currentCommunicationPoint, communicationStepSize);
    if (status == Discard) comp->state = StepDiscarded;
    if (status != OK) return (fmi3Status)status;
    /* Event Mode with early return: stop at each event for the importer to handle it; Event Mode
     * alone: handle the events inside the step here and leave one at its end to the importer. */
    EventHandling handling = !comp->eventModeUsed     ? HandleEvents
                             : comp->earlyReturnAllowed ? ReturnAtEvents
                                                        : ReturnAtLastEvent;
    const double t_end = currentCommunicationPoint + communicationStepSize;
    StepOutcome outcome = stepTo(comp, t_end, handling);
    *lastSuccessfulTime = comp->time;
    *eventHandlingNeeded = outcome == StoppedAtEvent;
    *terminateSimulation = outcome == StoppedTerminated;
    *earlyReturn = comp->earlyReturnAllowed && comp->time < t_end;
    return (fmi3Status)calculateValues(comp);
}
