/* deltafmi's FMI 3.0 binary: every fmi3 function of the header, Model Exchange and Co-Simulation
 * served, over the shared plumbing of core.c (the same as the FMI 2.0 binary's).
 *
 * Value references (the contract with deltafmi/runtime/layout.py): a declaration, scalar or 1-D
 * array, is one FMI 3.0 variable whose value reference is its first scalar's, so element k of a
 * variable at v is the scalar v + k of the value buffers; sizes3[v] is its element count (0: v is
 * not the first scalar of a declaration). After the n_total = n_real + n_int + n_str scalars come
 * `time` (n_total), one value reference per Clock, then one Float64 variable per event indicator.
 * Types: the real buffer is Float64, the int buffer Int32, Boolean (flag IS_BOOLEAN) or
 * Enumeration (flag IS_ENUMERATION: fmi3Get/SetInt64, as the standard has it, stored as int32),
 * strings String; getters and setters of the other types fail, naming the reason.
 *
 * Built with hidden visibility: the binary exports the fmi3 functions and nothing else. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"
#include "core.h"

#define MASK_GET (InitializationMode | EventMode | ContinuousTimeMode | StepMode | StepDiscarded | \
                  ClockActivationMode | Terminated | Error)
#define MASK_SET_FLOAT (Instantiated | InitializationMode | EventMode | ContinuousTimeMode | StepMode | \
                        ClockActivationMode)
#define MASK_SET_DISCRETE (Instantiated | InitializationMode | EventMode | StepMode | ClockActivationMode)
#define MASK_ME_GET (InitializationMode | EventMode | ContinuousTimeMode | Terminated | Error)
#define MASK_TERMINATE (EventMode | ContinuousTimeMode | StepMode | StepDiscarded | ClockActivationMode)
/* where the importer may ask for a time-based Clock's interval and shift */
#define MASK_CLOCK_TIMING (InitializationMode | EventMode | ClockActivationMode)

#define CHECK(function, mask) \
    do { if (!dfmi_allowed(c, function, mask)) return fmi3Error; } while (0)
/* a function of one interface called on an instance of the other */
#define CHECK_INTERFACE(function, kind) \
    do { if (c->interface != (kind)) return (fmi3Status)dfmi_fail(c, "%s: not a function of %s (this instance is %s)", \
         function, interface_name(kind), interface_name(c->interface)); } while (0)
#define FAIL(...) return (fmi3Status)dfmi_fail(c, __VA_ARGS__)

static const char *interface_name(int kind) {
    return kind == DFMI_MODEL_EXCHANGE ? "Model Exchange" : kind == DFMI_CO_SIMULATION ? "Co-Simulation"
                                                                                       : "Scheduled Execution";
}

static void emit_instance(const Instance *c, int status, const char *category, const char *message) {
    fmi3LogMessageCallback logger;
    memcpy(&logger, &c->host_logger, sizeof logger);
    if (logger) logger(c->host_env, (fmi3Status)status, category, message); /* not a format: no escaping */
}

/* ---------------------------------------------------------------------------------------- */
/* value references                                                                          */

typedef enum { V_NONE, V_FLOAT64, V_INT32, V_BOOLEAN, V_ENUMERATION, V_STRING, V_TIME, V_CLOCK, V_INDICATOR } Kind;

static size_t n_total(const Instance *c) { return c->L.n_real + c->L.n_int + c->L.n_str; }

/* What vr names, and its element count (*n). */
static Kind kind_of(const Instance *c, fmi3ValueReference vr, size_t *n) {
    size_t total = n_total(c);
    *n = 1;
    if (vr < total) {
        *n = c->L.sizes3[vr];
        if (!*n) return V_NONE;
        if (vr < c->L.n_real) return V_FLOAT64;
        if (vr < c->L.n_real + c->L.n_int)
            return c->L.flags[vr] & IS_BOOLEAN ? V_BOOLEAN : c->L.flags[vr] & IS_ENUMERATION ? V_ENUMERATION : V_INT32;
        return V_STRING;
    }
    if (vr == total) return V_TIME;
    if (vr - total - 1 < c->L.n_clocks) return V_CLOCK;
    if (vr - total - 1 - c->L.n_clocks < c->L.nz) return V_INDICATOR;
    return V_NONE;
}

static const char *kind_name(Kind kind) {
    switch (kind) {
    case V_FLOAT64: case V_TIME: case V_INDICATOR: return "a Float64";
    case V_INT32: return "an Int32";
    case V_BOOLEAN: return "a Boolean";
    case V_ENUMERATION: return "an Enumeration (Int64)";
    case V_STRING: return "a String";
    case V_CLOCK: return "a Clock";
    default: return "no";
    }
}

/* Every vr of the kind `want` (Float64 reads also take `time` and the event indicators) and
 * nValues the sum of their element counts; *derivatives and *indicators say what must be up to
 * date. 1, or 0 after an error. */
static int measure(Instance *c, const char *function, const fmi3ValueReference vr[], size_t nvr, const void *values,
                   size_t n_values, Kind want, int reading, int *derivatives, int *indicators) {
    if (nvr && (!vr || (n_values && !values))) return dfmi_fail(c, "%s: NULL array argument", function), 0;
    size_t total = 0;
    *derivatives = *indicators = 0;
    for (size_t i = 0; i < nvr; i++) {
        size_t n;
        Kind kind = kind_of(c, vr[i], &n);
        int ok = kind == want || (reading && want == V_FLOAT64 && (kind == V_TIME || kind == V_INDICATOR));
        if (!ok) {
            if (want == V_FLOAT64 && kind == V_TIME)
                return dfmi_fail(c, "%s: %u is `time`, the independent variable: set it with fmi3SetTime "
                                 "(Model Exchange)", function, vr[i]), 0;
            if (want == V_FLOAT64 && kind == V_INDICATOR)
                return dfmi_fail(c, "%s: %u is an event indicator, calculated by the model: it cannot be set",
                                 function, vr[i]), 0;
            return dfmi_fail(c, "%s: %u is not the value reference of %s variable (it names %s variable)", function,
                             vr[i], kind_name(want), kind_name(kind)), 0;
        }
        if (kind == V_FLOAT64 && dfmi_is_derivative(c, vr[i], n)) *derivatives = 1;
        if (kind == V_INDICATOR) *indicators = 1;
        total += n;
    }
    if (total != n_values)
        return dfmi_fail(c, "%s: nValues is %zu, the variables have %zu values", function, n_values, total), 0;
    return 1;
}

/* Each scalar of the variables may be set now (their flags against the state). */
static int settable(Instance *c, const char *function, const fmi3ValueReference vr[], size_t nvr) {
    const int bit = dfmi_setter_bit(c);
    for (size_t i = 0; i < nvr; i++)
        for (size_t k = 0; k < c->L.sizes3[vr[i]]; k++)
            if (!dfmi_settable(c, function, vr[i] + k, bit)) return 0;
    return 1;
}

/* ---------------------------------------------------------------------------------------- */
/* common functions                                                                          */

const char *fmi3GetVersion(void) { return fmi3Version; }

static Instance *instantiate(fmi3String name, fmi3String token, fmi3String resource_path, fmi3Boolean logging_on,
                             int interface, fmi3InstanceEnvironment env, fmi3LogMessageCallback log) {
    void (*logger)(void);
    memcpy(&logger, &log, sizeof logger);
    const char *function = interface == DFMI_MODEL_EXCHANGE  ? "fmi3InstantiateModelExchange"
                           : interface == DFMI_CO_SIMULATION ? "fmi3InstantiateCoSimulation"
                                                             : "fmi3InstantiateScheduledExecution";
    if (!name || !name[0]) {
        if (log) log(env, fmi3Error, "logStatusError", "fmi3Instantiate: missing instance name");
        return NULL;
    }
    Instance *c = dfmi_new_instance(name, 3, interface, emit_instance, env, logger, logging_on);
    if (!c) return NULL;
    char *resources = NULL;
    if (!resource_path || !resource_path[0]) {
        resources = dfmi_default_resources(); /* NULL is allowed: <fmu>/resources from the binary's place */
    } else if ((resources = strdup(resource_path))) {
        size_t n = strlen(resources);
        while (n > 1 && resources[n - 1] == '/') resources[--n] = 0; /* a native path with its separator */
    }
    int connected = dfmi_connect(c, resources, token);
    free(resources);
    if (connected != 0 || !c->L.sizes3) {
        if (connected == 0)
            dfmi_logf(c, fmi3Error, "logStatusError", "%s: the model's runtime does not describe its FMI 3.0 "
                      "variables (native_layout without sizes3): rebuild the FMU with this deltafmi", function);
        dfmi_free_instance(c);
        return NULL;
    }
    return c;
}

fmi3Instance fmi3InstantiateModelExchange(fmi3String instanceName, fmi3String instantiationToken,
                                          fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                          fmi3InstanceEnvironment instanceEnvironment,
                                          fmi3LogMessageCallback logMessage) {
    (void)visible;
    return instantiate(instanceName, instantiationToken, resourcePath, loggingOn, DFMI_MODEL_EXCHANGE,
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
    (void)visible; (void)intermediateUpdate;
    (void)requiredIntermediateVariables;
    if (nRequiredIntermediateVariables) {
        if (logMessage)
            logMessage(instanceEnvironment, fmi3Error, "logStatusError", "fmi3InstantiateCoSimulation: this FMU "
                       "declares no intermediate variables (intermediateUpdate is not used)");
        return NULL;
    }
    Instance *c = instantiate(instanceName, instantiationToken, resourcePath, loggingOn, DFMI_CO_SIMULATION,
                              instanceEnvironment, logMessage);
    if (c) {
        c->event_mode_used = eventModeUsed;
        c->early_return_allowed = earlyReturnAllowed;
    }
    return c;
}

fmi3Instance fmi3InstantiateScheduledExecution(fmi3String instanceName, fmi3String instantiationToken,
                                               fmi3String resourcePath, fmi3Boolean visible, fmi3Boolean loggingOn,
                                               fmi3InstanceEnvironment instanceEnvironment,
                                               fmi3LogMessageCallback logMessage, fmi3ClockUpdateCallback clockUpdate,
                                               fmi3LockPreemptionCallback lockPreemption,
                                               fmi3UnlockPreemptionCallback unlockPreemption) {
    /* the model partitions neither tick output Clocks nor preempt one another: the callbacks are
     * not needed (the standard makes clockUpdate mandatory for FMUs that have such Clocks only) */
    (void)visible; (void)clockUpdate; (void)lockPreemption; (void)unlockPreemption;
    Instance *c = instantiate(instanceName, instantiationToken, resourcePath, loggingOn, DFMI_SCHEDULED_EXECUTION,
                              instanceEnvironment, logMessage);
    if (c && (!c->L.n_clocks || c->L.nx || c->L.nz || !c->L.clock_period_index)) {
        dfmi_logf(c, fmi3Error, "logStatusError", "fmi3InstantiateScheduledExecution: this FMU provides Model "
                  "Exchange and Co-Simulation, not Scheduled Execution (which needs a component with Clocks "
                  "and neither continuous states nor event indicators)");
        dfmi_free_instance(c);
        return NULL;
    }
    return c;
}

void fmi3FreeInstance(fmi3Instance instance) { dfmi_free_instance(instance); }

fmi3Status fmi3SetDebugLogging(fmi3Instance instance, fmi3Boolean loggingOn, size_t nCategories,
                               const fmi3String categories[]) {
    Instance *c = instance;
    CHECK("fmi3SetDebugLogging", ANY_INSTANCE);
    return (fmi3Status)dfmi_set_debug_logging(c, "fmi3SetDebugLogging", loggingOn, nCategories, categories);
}

fmi3Status fmi3EnterInitializationMode(fmi3Instance instance, fmi3Boolean toleranceDefined, fmi3Float64 tolerance,
                                       fmi3Float64 startTime, fmi3Boolean stopTimeDefined, fmi3Float64 stopTime) {
    Instance *c = instance;
    CHECK("fmi3EnterInitializationMode", Instantiated);
    c->tolerance_defined = toleranceDefined;
    c->tolerance = tolerance;
    c->start_time = c->time = startTime;
    c->stop_defined = stopTimeDefined;
    c->stop_time = stopTime;
    return (fmi3Status)dfmi_enter_initialization(c);
}

fmi3Status fmi3ExitInitializationMode(fmi3Instance instance) {
    Instance *c = instance;
    CHECK("fmi3ExitInitializationMode", InitializationMode);
    /* Model Exchange, and Co-Simulation with event mode, go on in Event Mode; Scheduled Execution
     * waits for its partitions' activations */
    int next = c->interface == DFMI_SCHEDULED_EXECUTION                        ? ClockActivationMode
               : c->interface == DFMI_MODEL_EXCHANGE || c->event_mode_used ? EventMode
                                                                           : StepMode;
    return (fmi3Status)dfmi_exit_initialization(c, next);
}

fmi3Status fmi3EnterEventMode(fmi3Instance instance) {
    Instance *c = instance;
    if (c && c->interface == DFMI_CO_SIMULATION) {
        CHECK("fmi3EnterEventMode", StepMode);
        if (!c->event_mode_used) FAIL("fmi3EnterEventMode: the instance was made with eventModeUsed = false");
    } else {
        CHECK("fmi3EnterEventMode", ContinuousTimeMode);
    }
    c->state = EventMode;
    return fmi3OK;
}

fmi3Status fmi3Terminate(fmi3Instance instance) {
    Instance *c = instance;
    CHECK("fmi3Terminate", MASK_TERMINATE);
    return (fmi3Status)dfmi_terminate(c);
}

fmi3Status fmi3Reset(fmi3Instance instance) {
    Instance *c = instance;
    CHECK("fmi3Reset", ANY_INSTANCE);
    return (fmi3Status)dfmi_reset(c);
}

/* ---------------------------------------------------------------------------------------- */
/* values                                                                                    */

fmi3Status fmi3GetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 values[],
                          size_t nValues) {
    Instance *c = instance;
    int derivatives, indicators;
    CHECK("fmi3GetFloat64", MASK_GET);
    if (!measure(c, "fmi3GetFloat64", vr, nvr, values, nValues, V_FLOAT64, 1, &derivatives, &indicators))
        return fmi3Error;
    if (nvr && dfmi_ensure_values(c, derivatives) >= fmi3Error) return fmi3Error;
    if (indicators && dfmi_ensure_derivatives(c) >= fmi3Error) return fmi3Error;
    size_t k = 0, total = n_total(c);
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] == total) {
            values[k++] = c->time;
        } else if (vr[i] > total) {
            values[k++] = c->L.event_indicators[vr[i] - total - 1 - c->L.n_clocks];
        } else {
            size_t n = c->L.sizes3[vr[i]];
            memcpy(values + k, c->L.real + vr[i], n * sizeof(double));
            k += n;
        }
    }
    return fmi3OK;
}

fmi3Status fmi3SetFloat64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Float64 values[], size_t nValues) {
    Instance *c = instance;
    int derivatives, indicators;
    CHECK("fmi3SetFloat64", MASK_SET_FLOAT);
    if (!measure(c, "fmi3SetFloat64", vr, nvr, values, nValues, V_FLOAT64, 0, &derivatives, &indicators) ||
        !settable(c, "fmi3SetFloat64", vr, nvr))
        return fmi3Error;
    for (size_t i = 0, k = 0; i < nvr; k += c->L.sizes3[vr[i]], i++)
        memcpy(c->L.real + vr[i], values + k, c->L.sizes3[vr[i]] * sizeof(double));
    if (nvr) dfmi_values_changed(c);
    return fmi3OK;
}

/* Int32, Boolean and Enumeration (Int64) share the int buffer (value references continue after
 * the reals): one getter and one setter for the three, converting element by element. */
static fmi3Status get_ints(Instance *c, const char *function, Kind kind, const fmi3ValueReference vr[], size_t nvr,
                           void *values, size_t nValues) {
    int derivatives, indicators;
    CHECK(function, MASK_GET);
    if (!measure(c, function, vr, nvr, values, nValues, kind, 1, &derivatives, &indicators)) return fmi3Error;
    if (nvr && dfmi_ensure_values(c, 0) >= fmi3Error) return fmi3Error;
    size_t k = 0;
    for (size_t i = 0; i < nvr; i++)
        for (size_t e = 0; e < c->L.sizes3[vr[i]]; e++, k++) {
            int v = c->L.ints[vr[i] - c->L.n_real + e];
            if (kind == V_INT32) ((fmi3Int32 *)values)[k] = v;
            else if (kind == V_ENUMERATION) ((fmi3Int64 *)values)[k] = v;
            else ((fmi3Boolean *)values)[k] = v != 0;
        }
    return fmi3OK;
}

static int64_t int_value(Kind kind, const void *values, size_t k) {
    if (kind == V_INT32) return ((const fmi3Int32 *)values)[k];
    if (kind == V_ENUMERATION) return ((const fmi3Int64 *)values)[k];
    return ((const fmi3Boolean *)values)[k] ? 1 : 0;
}

static fmi3Status set_ints(Instance *c, const char *function, Kind kind, const fmi3ValueReference vr[], size_t nvr,
                           const void *values, size_t nValues) {
    int derivatives, indicators;
    CHECK(function, MASK_SET_DISCRETE);
    if (!measure(c, function, vr, nvr, values, nValues, kind, 0, &derivatives, &indicators) ||
        !settable(c, function, vr, nvr))
        return fmi3Error;
    /* every value checked before any is stored: a failed call changes nothing */
    for (size_t i = 0, k = 0; i < nvr; i++)
        for (size_t e = 0; e < c->L.sizes3[vr[i]]; e++, k++) {
            int64_t v = int_value(kind, values, k);
            if (v < INT32_MIN || v > INT32_MAX)
                FAIL("%s: %lld (value %zu, the Enumeration at value reference %u) is out of this FMU's range "
                     "of Enumeration values [%d, %d]", function, (long long)v, k, vr[i], INT32_MIN, INT32_MAX);
        }
    for (size_t i = 0, k = 0; i < nvr; i++)
        for (size_t e = 0; e < c->L.sizes3[vr[i]]; e++, k++)
            c->L.ints[vr[i] - c->L.n_real + e] = (int)int_value(kind, values, k);
    if (nvr) dfmi_values_changed(c);
    return fmi3OK;
}

fmi3Status fmi3GetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Int32 values[],
                        size_t nValues) {
    return get_ints(instance, "fmi3GetInt32", V_INT32, vr, nvr, values, nValues);
}

fmi3Status fmi3SetInt32(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int32 values[],
                        size_t nValues) {
    return set_ints(instance, "fmi3SetInt32", V_INT32, vr, nvr, values, nValues);
}

fmi3Status fmi3GetInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Int64 values[],
                        size_t nValues) {
    return get_ints(instance, "fmi3GetInt64", V_ENUMERATION, vr, nvr, values, nValues);
}

fmi3Status fmi3SetInt64(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Int64 values[],
                        size_t nValues) {
    return set_ints(instance, "fmi3SetInt64", V_ENUMERATION, vr, nvr, values, nValues);
}

fmi3Status fmi3GetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Boolean values[],
                          size_t nValues) {
    return get_ints(instance, "fmi3GetBoolean", V_BOOLEAN, vr, nvr, values, nValues);
}

fmi3Status fmi3SetBoolean(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                          const fmi3Boolean values[], size_t nValues) {
    return set_ints(instance, "fmi3SetBoolean", V_BOOLEAN, vr, nvr, values, nValues);
}

fmi3Status fmi3GetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3String values[],
                         size_t nValues) {
    Instance *c = instance;
    int derivatives, indicators;
    CHECK("fmi3GetString", MASK_GET);
    if (!measure(c, "fmi3GetString", vr, nvr, values, nValues, V_STRING, 1, &derivatives, &indicators))
        return fmi3Error;
    size_t k = 0;
    for (size_t i = 0; i < nvr; i++)
        for (size_t e = 0; e < c->L.sizes3[vr[i]]; e++)
            if (dfmi_get_string(c, "fmi3GetString", vr[i] + e, &values[k++]) >= fmi3Error) return fmi3Error;
    return fmi3OK;
}

fmi3Status fmi3SetString(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3String values[],
                         size_t nValues) {
    Instance *c = instance;
    int derivatives, indicators;
    CHECK("fmi3SetString", MASK_SET_DISCRETE);
    if (!measure(c, "fmi3SetString", vr, nvr, values, nValues, V_STRING, 0, &derivatives, &indicators))
        return fmi3Error;
    size_t k = 0;
    for (size_t i = 0; i < nvr; i++)
        for (size_t e = 0; e < c->L.sizes3[vr[i]]; e++)
            if (dfmi_set_string(c, "fmi3SetString", vr[i] + e, values[k++]) >= fmi3Error) return fmi3Error;
    return fmi3OK;
}

/* The types this FMU has no variables of: nothing to get or set, an error naming why. */
static fmi3Status no_such_type(Instance *c, const char *function, const char *type, const fmi3ValueReference vr[],
                               size_t nvr, int mask) {
    CHECK(function, mask);
    if (!nvr) return fmi3OK;
    if (!vr) FAIL("%s: NULL array argument", function);
    size_t n;
    FAIL("%s: %u is not the value reference of %s variable (it names %s variable; this FMU's variables are "
         "Float64, Int32, Boolean, Enumeration (Int64) and String)", function, vr[0], type, kind_name(kind_of(c, vr[0], &n)));
}

#define UNSUPPORTED_TYPE(Type, article)                                                                        \
    fmi3Status fmi3Get##Type(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,                    \
                             fmi3##Type values[], size_t nValues) {                                              \
        (void)values; (void)nValues;                                                                            \
        return no_such_type(instance, "fmi3Get" #Type, article " " #Type, vr, nvr, MASK_GET);                   \
    }                                                                                                           \
    fmi3Status fmi3Set##Type(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,                    \
                             const fmi3##Type values[], size_t nValues) {                                        \
        (void)values; (void)nValues;                                                                            \
        return no_such_type(instance, "fmi3Set" #Type, article " " #Type, vr, nvr, MASK_SET_DISCRETE);          \
    }

UNSUPPORTED_TYPE(Float32, "a")
UNSUPPORTED_TYPE(Int8, "an")
UNSUPPORTED_TYPE(UInt8, "a")
UNSUPPORTED_TYPE(Int16, "an")
UNSUPPORTED_TYPE(UInt16, "a")
UNSUPPORTED_TYPE(UInt32, "a")
UNSUPPORTED_TYPE(UInt64, "a")

fmi3Status fmi3GetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, size_t valueSizes[],
                         fmi3Binary values[], size_t nValues) {
    (void)valueSizes; (void)values; (void)nValues;
    return no_such_type(instance, "fmi3GetBinary", "a Binary", vr, nvr, MASK_GET);
}

fmi3Status fmi3SetBinary(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const size_t valueSizes[],
                         const fmi3Binary values[], size_t nValues) {
    (void)valueSizes; (void)values; (void)nValues;
    return no_such_type(instance, "fmi3SetBinary", "a Binary", vr, nvr, MASK_SET_DISCRETE);
}

/* ---------------------------------------------------------------------------------------- */
/* clocks: periodic time-based input Clocks (Clock i at value reference time + 1 + i), each a
 * `fixed` Clock whose interval is a Parameter or a `constant` one; shift 0; supportsFraction false */

/* The index (0-based) of the Clock vr names into *i: 1, else 0 (and *i 0). */
static int clock_of(const Instance *c, fmi3ValueReference vr, size_t *i) {
    size_t n;
    *i = 0;
    if (kind_of(c, vr, &n) != V_CLOCK) return 0;
    *i = vr - n_total(c) - 1;
    return 1;
}

/* Every vr a Clock of this FMU (else an error naming the first that is not): 1, or 0 after an error. */
static int clocks_named(Instance *c, const char *function, const fmi3ValueReference vr[], size_t nvr,
                        const void *values) {
    if (nvr && (!vr || !values)) return dfmi_fail(c, "%s: NULL array argument", function), 0;
    for (size_t k = 0, i; k < nvr; k++)
        if (!clock_of(c, vr[k], &i)) {
            size_t n;
            if (!c->L.n_clocks || !c->L.clock_period_index)
                return dfmi_fail(c, "%s: %u is not a Clock (this FMU has no Clocks)", function, vr[k]), 0;
            return dfmi_fail(c, "%s: %u is not a Clock (it names %s variable; this FMU's Clocks are the value "
                             "references %zu to %zu)", function, vr[k], kind_name(kind_of(c, vr[k], &n)),
                             n_total(c) + 1, n_total(c) + c->L.n_clocks), 0;
        }
    return 1;
}

static int is_constant_clock(const Instance *c, size_t i) { return c->L.clock_period_index[i] < 0; }

/* The standard has fmi3GetClock for triggered output and local Clocks; ours are input Clocks,
 * whose activation is the importer's own (fmi3SetClock). */
fmi3Status fmi3GetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Clock values[]) {
    Instance *c = instance;
    CHECK("fmi3GetClock", ANY_INSTANCE);
    if (!clocks_named(c, "fmi3GetClock", vr, nvr, values)) return fmi3Error;
    if (!nvr) return fmi3OK;
    FAIL("fmi3GetClock: Clock %u is an input Clock, activated by the importer (fmi3SetClock); fmi3GetClock is for "
         "output and local Clocks", vr[0]);
}

/* The importer activates the Clock at its ticks; the component samples at the same instants,
 * which stay time events (fmi3UpdateDiscreteStates samples once, whether the Clock, the time
 * event or both brought the importer here, and deactivates the Clocks). canBeDeactivated is
 * false: an active Clock cannot be set inactive again. */
fmi3Status fmi3SetClock(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, const fmi3Clock values[]) {
    Instance *c = instance;
    if (c && c->interface == DFMI_SCHEDULED_EXECUTION)
        FAIL("fmi3SetClock: must not be called in Scheduled Execution; activate the Clock's model partition "
             "with fmi3ActivateModelPartition");
    CHECK("fmi3SetClock", EventMode);
    if (!clocks_named(c, "fmi3SetClock", vr, nvr, values)) return fmi3Error;
    fmi3Status status = fmi3OK;
    for (size_t k = 0, i; k < nvr; k++) {
        clock_of(c, vr[k], &i);
        if (!values[k]) {
            if ((c->clocks_active >> i) & 1u)
                FAIL("fmi3SetClock: Clock %u is active and cannot be deactivated (canBeDeactivated = false)", vr[k]);
            continue;
        }
        c->clocks_active |= UINT64_C(1) << i;
        double interval = dfmi_clock_interval(c, i), ticks = (c->time - c->start_time) / interval;
        if (fabs(ticks - nearbyint(ticks)) > 1e-6) { /* the component samples at its ticks only */
            dfmi_logf(c, DFMI_WARNING, "logStatusWarning", "fmi3SetClock: Clock %u activated at t = %.17g, "
                      "between its ticks (every %g s from %g): no sample is due", vr[k], c->time, interval,
                      c->start_time);
            status = fmi3Warning;
        }
    }
    return status;
}

fmi3Status fmi3GetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  fmi3Float64 intervals[], fmi3IntervalQualifier qualifiers[]) {
    Instance *c = instance;
    const char *function = "fmi3GetIntervalDecimal";
    CHECK(function, MASK_CLOCK_TIMING);
    if (nvr && !qualifiers) FAIL("%s: NULL array argument", function);
    if (!clocks_named(c, function, vr, nvr, intervals)) return fmi3Error;
    for (size_t k = 0, i; k < nvr; k++) {
        clock_of(c, vr[k], &i);
        double interval = dfmi_clock_interval(c, i);
        if (!(interval > 0.0))
            FAIL("%s: the interval of Clock %u is %g s, its period Parameter (value reference %lld) must be > 0",
                 function, vr[k], interval, (long long)c->L.clock_period_index[i]);
        intervals[k] = interval;
        /* a fixed Clock's interval comes from the FMU: new in Initialization Mode when it differs
         * from the one last reported; a constant Clock's is in modelDescription.xml */
        int changed = !is_constant_clock(c, i) && c->state == InitializationMode && interval != c->clock_reported[i];
        qualifiers[k] = changed ? fmi3IntervalChanged : fmi3IntervalUnchanged;
        c->clock_reported[i] = interval;
    }
    return fmi3OK;
}

fmi3Status fmi3GetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr, fmi3Float64 shifts[]) {
    Instance *c = instance;
    CHECK("fmi3GetShiftDecimal", MASK_CLOCK_TIMING);
    if (!clocks_named(c, "fmi3GetShiftDecimal", vr, nvr, shifts)) return fmi3Error;
    for (size_t k = 0; k < nvr; k++) shifts[k] = 0.0; /* the first tick is at the start time */
    return fmi3OK;
}

/* The fraction variants: supportsFraction is false (a period Parameter is a floating-point number). */
static fmi3Status no_fraction(Instance *c, const char *function, const fmi3ValueReference vr[], size_t nvr,
                              const void *values, int mask) {
    CHECK(function, mask);
    if (!clocks_named(c, function, vr, nvr, values)) return fmi3Error;
    if (!nvr) return fmi3OK;
    FAIL("%s: Clock %u has supportsFraction = false; use the Decimal variant", function, vr[0]);
}

fmi3Status fmi3GetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   fmi3UInt64 counters[], fmi3UInt64 resolutions[],
                                   fmi3IntervalQualifier qualifiers[]) {
    (void)resolutions; (void)qualifiers;
    return no_fraction(instance, "fmi3GetIntervalFraction", vr, nvr, counters, MASK_CLOCK_TIMING);
}

fmi3Status fmi3GetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                fmi3UInt64 counters[], fmi3UInt64 resolutions[]) {
    (void)resolutions;
    return no_fraction(instance, "fmi3GetShiftFraction", vr, nvr, counters, MASK_CLOCK_TIMING);
}

/* Setting an interval or a shift is for Clocks that declare intervalDecimal (or are tunable);
 * ours give theirs (a fixed Clock: its period Parameter; a constant one: modelDescription.xml). */
static fmi3Status not_settable(Instance *c, const char *function, const fmi3ValueReference vr[], size_t nvr,
                               const void *values, const char *what) {
    CHECK(function, ANY_INSTANCE);
    if (!clocks_named(c, function, vr, nvr, values)) return fmi3Error;
    if (!nvr) return fmi3OK;
    size_t i;
    clock_of(c, vr[0], &i);
    if (is_constant_clock(c, i))
        FAIL("%s: Clock %u is a constant Clock: its %s is given in modelDescription.xml and cannot be set",
             function, vr[0], what);
    FAIL("%s: Clock %u is a fixed Clock without intervalDecimal: the FMU gives its %s (%s); set its period "
         "Parameter (value reference %lld) before fmi3ExitInitializationMode instead", function, vr[0], what,
         what[0] == 'i' ? "fmi3GetIntervalDecimal" : "0, fmi3GetShiftDecimal", (long long)c->L.clock_period_index[i]);
}

fmi3Status fmi3SetIntervalDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                  const fmi3Float64 intervals[]) {
    return not_settable(instance, "fmi3SetIntervalDecimal", vr, nvr, intervals, "interval");
}

fmi3Status fmi3SetIntervalFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                   const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)resolutions;
    return not_settable(instance, "fmi3SetIntervalFraction", vr, nvr, counters, "interval");
}

fmi3Status fmi3SetShiftDecimal(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                               const fmi3Float64 shifts[]) {
    return not_settable(instance, "fmi3SetShiftDecimal", vr, nvr, shifts, "shift");
}

fmi3Status fmi3SetShiftFraction(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                const fmi3UInt64 counters[], const fmi3UInt64 resolutions[]) {
    (void)resolutions;
    return not_settable(instance, "fmi3SetShiftFraction", vr, nvr, counters, "shift");
}

fmi3Status fmi3ActivateModelPartition(fmi3Instance instance, fmi3ValueReference clockReference,
                                      fmi3Float64 activationTime) {
    Instance *c = instance;
    const char *function = "fmi3ActivateModelPartition";
    if (c && c->interface != DFMI_SCHEDULED_EXECUTION)
        FAIL("%s: a function of Scheduled Execution (this instance is %s)", function, interface_name(c->interface));
    CHECK(function, ClockActivationMode);
    if (!clocks_named(c, function, &clockReference, 1, &activationTime)) return fmi3Error;
    size_t i;
    clock_of(c, clockReference, &i);
    return (fmi3Status)dfmi_activate_model_partition(c, function, i, activationTime);
}

/* ---------------------------------------------------------------------------------------- */
/* configuration, dependencies                                                               */

fmi3Status fmi3EnterConfigurationMode(fmi3Instance instance) {
    Instance *c = instance;
    CHECK("fmi3EnterConfigurationMode", Instantiated | StepMode | EventMode);
    FAIL("fmi3EnterConfigurationMode: this FMU has no structural parameters");
}

fmi3Status fmi3ExitConfigurationMode(fmi3Instance instance) {
    Instance *c = instance;
    CHECK("fmi3ExitConfigurationMode", ConfigurationMode);
    FAIL("fmi3ExitConfigurationMode: this FMU has no structural parameters");
}

fmi3Status fmi3GetNumberOfVariableDependencies(fmi3Instance instance, fmi3ValueReference valueReference,
                                               size_t *nDependencies) {
    Instance *c = instance;
    (void)valueReference; (void)nDependencies;
    CHECK("fmi3GetNumberOfVariableDependencies", ANY_INSTANCE);
    FAIL("fmi3GetNumberOfVariableDependencies: not provided; the dependencies, fixed for this FMU (it has no "
         "structural parameters), are in modelDescription.xml <ModelStructure>");
}

fmi3Status fmi3GetVariableDependencies(fmi3Instance instance, fmi3ValueReference dependent,
                                       size_t elementIndicesOfDependent[], fmi3ValueReference independents[],
                                       size_t elementIndicesOfIndependents[], fmi3DependencyKind dependencyKinds[],
                                       size_t nDependencies) {
    Instance *c = instance;
    (void)dependent; (void)elementIndicesOfDependent; (void)independents; (void)elementIndicesOfIndependents;
    (void)dependencyKinds; (void)nDependencies;
    CHECK("fmi3GetVariableDependencies", ANY_INSTANCE);
    FAIL("fmi3GetVariableDependencies: not provided; the dependencies, fixed for this FMU (it has no structural "
         "parameters), are in modelDescription.xml <ModelStructure>");
}

/* ---------------------------------------------------------------------------------------- */
/* FMU state                                                                                 */

fmi3Status fmi3GetFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    Instance *c = instance;
    CHECK("fmi3GetFMUState", ANY_INSTANCE);
    return (fmi3Status)dfmi_get_fmu_state(c, "fmi3GetFMUState", FMUState);
}

fmi3Status fmi3SetFMUState(fmi3Instance instance, fmi3FMUState FMUState) {
    Instance *c = instance;
    CHECK("fmi3SetFMUState", ANY_INSTANCE);
    int status = dfmi_set_fmu_state(c, "fmi3SetFMUState", FMUState);
    /* back in time: the next activations of a Clock follow the restored state, not the last ones */
    if (status < DFMI_ERROR)
        for (size_t i = 0; i < DFMI_MAX_CLOCKS; i++) c->clock_activated[i] = NAN;
    return (fmi3Status)status;
}

fmi3Status fmi3FreeFMUState(fmi3Instance instance, fmi3FMUState *FMUState) {
    Instance *c = instance;
    CHECK("fmi3FreeFMUState", ANY_INSTANCE);
    return (fmi3Status)dfmi_free_fmu_state(c, "fmi3FreeFMUState", FMUState);
}

fmi3Status fmi3SerializedFMUStateSize(fmi3Instance instance, fmi3FMUState FMUState, size_t *size) {
    Instance *c = instance;
    CHECK("fmi3SerializedFMUStateSize", ANY_INSTANCE);
    return (fmi3Status)dfmi_serialized_size(c, "fmi3SerializedFMUStateSize", FMUState, size);
}

fmi3Status fmi3SerializeFMUState(fmi3Instance instance, fmi3FMUState FMUState, fmi3Byte serializedState[],
                                 size_t size) {
    Instance *c = instance;
    CHECK("fmi3SerializeFMUState", ANY_INSTANCE);
    return (fmi3Status)dfmi_serialize(c, "fmi3SerializeFMUState", FMUState, serializedState, size);
}

fmi3Status fmi3DeserializeFMUState(fmi3Instance instance, const fmi3Byte serializedState[], size_t size,
                                   fmi3FMUState *FMUState) {
    Instance *c = instance;
    CHECK("fmi3DeserializeFMUState", ANY_INSTANCE);
    return (fmi3Status)dfmi_deserialize(c, "fmi3DeserializeFMUState", serializedState, size, FMUState);
}

/* ---------------------------------------------------------------------------------------- */
/* partial derivatives                                                                       */

/* The Float64 variables' scalars, element by element, into a new array (*n of them); NULL after
 * an error. */
static unsigned int *scalars_of(Instance *c, const char *function, const fmi3ValueReference vr[], size_t nvr,
                                size_t *n) {
    *n = 0;
    for (size_t i = 0; i < nvr; i++) {
        size_t count;
        if (kind_of(c, vr[i], &count) != V_FLOAT64) {
            dfmi_fail(c, "%s: %u is not the value reference of a Float64 state, derivative, input or output",
                      function, vr[i]);
            return NULL;
        }
        *n += count;
    }
    unsigned int *out = malloc((*n ? *n : 1) * sizeof *out);
    if (!out) {
        dfmi_fail(c, "%s: out of memory", function);
        return NULL;
    }
    for (size_t i = 0, k = 0; i < nvr; i++)
        for (size_t e = 0; e < c->L.sizes3[vr[i]]; e++) out[k++] = (unsigned int)(vr[i] + e);
    return out;
}

/* unknowns and knowns as scalar lists; 1, or 0 after an error (nothing to free then) */
static int partials_arguments(Instance *c, const char *function, const fmi3ValueReference unknowns[],
                              size_t nUnknowns, const fmi3ValueReference knowns[], size_t nKnowns,
                              const void *seed, const void *sensitivity, unsigned int **u, size_t *nu,
                              unsigned int **k, size_t *nk) {
    if ((nUnknowns && (!unknowns || !sensitivity)) || (nKnowns && (!knowns || !seed)))
        return dfmi_fail(c, "%s: NULL array argument", function), 0;
    if (!(*u = scalars_of(c, function, unknowns, nUnknowns, nu))) return 0;
    if (!(*k = scalars_of(c, function, knowns, nKnowns, nk))) {
        free(*u);
        return 0;
    }
    return 1;
}

fmi3Status fmi3GetDirectionalDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                        const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                        size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    Instance *c = instance;
    const char *function = "fmi3GetDirectionalDerivative";
    CHECK(function, MASK_GET);
    unsigned int *u, *k;
    size_t nu, nk;
    if (!partials_arguments(c, function, unknowns, nUnknowns, knowns, nKnowns, seed, sensitivity, &u, &nu, &k, &nk))
        return fmi3Error;
    int status = DFMI_OK;
    if (nSeed != nk || nSensitivity != nu)
        status = dfmi_fail(c, "%s: nSeed %zu and nSensitivity %zu, the knowns have %zu values and the unknowns %zu",
                           function, nSeed, nSensitivity, nk, nu);
    else if (nu) /* the values the model computes on the way are restored: the dirty flags stay */
        status = dfmi_settle(c, bridge_directional_derivative(c->py, function, c->time, u, nu, k, nk, seed,
                                                              sensitivity));
    free(u);
    free(k);
    return (fmi3Status)status;
}

/* sensitivity_j = sum_i seed_i d unknown_i / d known_j: one exact directional derivative per
 * known scalar (a column of the Jacobian), then its product with the seed. */
fmi3Status fmi3GetAdjointDerivative(fmi3Instance instance, const fmi3ValueReference unknowns[], size_t nUnknowns,
                                    const fmi3ValueReference knowns[], size_t nKnowns, const fmi3Float64 seed[],
                                    size_t nSeed, fmi3Float64 sensitivity[], size_t nSensitivity) {
    Instance *c = instance;
    const char *function = "fmi3GetAdjointDerivative";
    CHECK(function, MASK_GET);
    unsigned int *u, *k;
    size_t nu, nk;
    if (!partials_arguments(c, function, unknowns, nUnknowns, knowns, nKnowns, seed, sensitivity, &u, &nu, &k, &nk))
        return fmi3Error;
    int status = DFMI_OK;
    double *unit = calloc(nk ? nk : 1, sizeof *unit), *column = calloc(nu ? nu : 1, sizeof *column);
    if (nSeed != nu || nSensitivity != nk)
        status = dfmi_fail(c, "%s: nSeed %zu and nSensitivity %zu, the unknowns have %zu values and the knowns %zu",
                           function, nSeed, nSensitivity, nu, nk);
    else if (!unit || !column)
        status = dfmi_fail(c, "%s: out of memory", function);
    for (size_t j = 0; j < nk && status < DFMI_ERROR; j++) {
        unit[j] = 1.0;
        status = dfmi_settle(c, bridge_directional_derivative(c->py, function, c->time, u, nu, k, nk, unit, column));
        unit[j] = 0.0;
        double sum = 0.0;
        for (size_t i = 0; i < nu; i++) sum += seed[i] * column[i];
        sensitivity[j] = sum;
    }
    free(unit);
    free(column);
    free(u);
    free(k);
    return (fmi3Status)status;
}

fmi3Status fmi3GetOutputDerivatives(fmi3Instance instance, const fmi3ValueReference vr[], size_t nvr,
                                    const fmi3Int32 orders[], fmi3Float64 values[], size_t nValues) {
    Instance *c = instance;
    (void)vr; (void)orders; (void)values; (void)nValues;
    CHECK("fmi3GetOutputDerivatives", StepMode | StepDiscarded | Terminated | Error);
    CHECK_INTERFACE("fmi3GetOutputDerivatives", DFMI_CO_SIMULATION);
    if (!nvr) return fmi3OK;
    FAIL("fmi3GetOutputDerivatives: not provided (maxOutputDerivativeOrder = 0)");
}

/* ---------------------------------------------------------------------------------------- */
/* events (Model Exchange, and Co-Simulation with event mode)                                */

fmi3Status fmi3EvaluateDiscreteStates(fmi3Instance instance) {
    Instance *c = instance;
    CHECK("fmi3EvaluateDiscreteStates", ANY_INSTANCE);
    FAIL("fmi3EvaluateDiscreteStates: not provided (providesEvaluateDiscreteStates = false); use event mode "
         "and fmi3UpdateDiscreteStates");
}

fmi3Status fmi3UpdateDiscreteStates(fmi3Instance instance, fmi3Boolean *discreteStatesNeedUpdate,
                                    fmi3Boolean *terminateSimulation, fmi3Boolean *nominalsOfContinuousStatesChanged,
                                    fmi3Boolean *valuesOfContinuousStatesChanged, fmi3Boolean *nextEventTimeDefined,
                                    fmi3Float64 *nextEventTime) {
    Instance *c = instance;
    CHECK("fmi3UpdateDiscreteStates", EventMode);
    if (!discreteStatesNeedUpdate || !terminateSimulation || !nominalsOfContinuousStatesChanged ||
        !valuesOfContinuousStatesChanged || !nextEventTimeDefined || !nextEventTime)
        FAIL("fmi3UpdateDiscreteStates: NULL argument");
    int flags[5];
    double next;
    int status = dfmi_update_discrete_states(c, flags, &next);
    c->clocks_active = 0; /* the Clocks' partitions ran: the next activation is the next tick's */
    /* every output is written, whatever happened */
    *discreteStatesNeedUpdate = flags[0];
    *terminateSimulation = flags[1];
    *nominalsOfContinuousStatesChanged = flags[2];
    *valuesOfContinuousStatesChanged = flags[3];
    *nextEventTimeDefined = flags[4];
    *nextEventTime = next;
    if (flags[1]) c->terminated_by_model = 1;
    return (fmi3Status)status;
}

/* ---------------------------------------------------------------------------------------- */
/* Model Exchange                                                                            */

fmi3Status fmi3EnterContinuousTimeMode(fmi3Instance instance) {
    Instance *c = instance;
    CHECK("fmi3EnterContinuousTimeMode", EventMode);
    CHECK_INTERFACE("fmi3EnterContinuousTimeMode", DFMI_MODEL_EXCHANGE);
    c->state = ContinuousTimeMode;
    c->clocks_active = 0; /* a Clock ticks for its event instant only */
    return fmi3OK;
}

fmi3Status fmi3CompletedIntegratorStep(fmi3Instance instance, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                                       fmi3Boolean *enterEventMode, fmi3Boolean *terminateSimulation) {
    Instance *c = instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK("fmi3CompletedIntegratorStep", ContinuousTimeMode);
    if (!enterEventMode || !terminateSimulation) FAIL("fmi3CompletedIntegratorStep: NULL argument");
    int enter, terminate;
    int status = dfmi_completed_integrator_step(c, &enter, &terminate);
    *enterEventMode = enter;
    *terminateSimulation = terminate;
    return (fmi3Status)status;
}

fmi3Status fmi3SetTime(fmi3Instance instance, fmi3Float64 time) {
    Instance *c = instance;
    CHECK("fmi3SetTime", EventMode | ContinuousTimeMode);
    CHECK_INTERFACE("fmi3SetTime", DFMI_MODEL_EXCHANGE);
    c->time = time;
    dfmi_values_changed(c);
    return fmi3OK;
}

fmi3Status fmi3SetContinuousStates(fmi3Instance instance, const fmi3Float64 continuousStates[],
                                   size_t nContinuousStates) {
    Instance *c = instance;
    CHECK("fmi3SetContinuousStates", ContinuousTimeMode);
    return (fmi3Status)dfmi_set_continuous_states(c, "fmi3SetContinuousStates", continuousStates, nContinuousStates);
}

fmi3Status fmi3GetContinuousStateDerivatives(fmi3Instance instance, fmi3Float64 derivatives[],
                                             size_t nContinuousStates) {
    Instance *c = instance;
    CHECK("fmi3GetContinuousStateDerivatives", MASK_ME_GET);
    CHECK_INTERFACE("fmi3GetContinuousStateDerivatives", DFMI_MODEL_EXCHANGE);
    return (fmi3Status)dfmi_get_derivatives(c, "fmi3GetContinuousStateDerivatives", derivatives, nContinuousStates);
}

fmi3Status fmi3GetEventIndicators(fmi3Instance instance, fmi3Float64 eventIndicators[], size_t nEventIndicators) {
    Instance *c = instance;
    CHECK("fmi3GetEventIndicators", MASK_ME_GET);
    CHECK_INTERFACE("fmi3GetEventIndicators", DFMI_MODEL_EXCHANGE);
    return (fmi3Status)dfmi_get_event_indicators(c, "fmi3GetEventIndicators", eventIndicators, nEventIndicators);
}

fmi3Status fmi3GetContinuousStates(fmi3Instance instance, fmi3Float64 continuousStates[], size_t nContinuousStates) {
    Instance *c = instance;
    CHECK("fmi3GetContinuousStates", MASK_ME_GET);
    CHECK_INTERFACE("fmi3GetContinuousStates", DFMI_MODEL_EXCHANGE);
    return (fmi3Status)dfmi_get_continuous_states(c, "fmi3GetContinuousStates", continuousStates, nContinuousStates);
}

fmi3Status fmi3GetNominalsOfContinuousStates(fmi3Instance instance, fmi3Float64 nominals[], size_t nContinuousStates) {
    Instance *c = instance;
    CHECK("fmi3GetNominalsOfContinuousStates", Instantiated | MASK_ME_GET);
    CHECK_INTERFACE("fmi3GetNominalsOfContinuousStates", DFMI_MODEL_EXCHANGE);
    return (fmi3Status)dfmi_get_nominals(c, "fmi3GetNominalsOfContinuousStates", nominals, nContinuousStates);
}

fmi3Status fmi3GetNumberOfEventIndicators(fmi3Instance instance, size_t *nEventIndicators) {
    Instance *c = instance;
    CHECK("fmi3GetNumberOfEventIndicators", ANY_INSTANCE);
    if (!nEventIndicators) FAIL("fmi3GetNumberOfEventIndicators: NULL argument");
    *nEventIndicators = c->L.nz;
    return fmi3OK;
}

fmi3Status fmi3GetNumberOfContinuousStates(fmi3Instance instance, size_t *nContinuousStates) {
    Instance *c = instance;
    CHECK("fmi3GetNumberOfContinuousStates", ANY_INSTANCE);
    if (!nContinuousStates) FAIL("fmi3GetNumberOfContinuousStates: NULL argument");
    *nContinuousStates = c->L.nx;
    return fmi3OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Co-Simulation                                                                             */

fmi3Status fmi3EnterStepMode(fmi3Instance instance) {
    Instance *c = instance;
    CHECK("fmi3EnterStepMode", EventMode);
    CHECK_INTERFACE("fmi3EnterStepMode", DFMI_CO_SIMULATION);
    c->state = StepMode;
    c->clocks_active = 0; /* a Clock ticks for its event instant only */
    return fmi3OK;
}

/* With eventModeUsed, a state or time event makes fmi3DoStep return eventHandlingNeeded and leaves
 * the event to the importer's Event Mode (fmi3EnterEventMode, fmi3UpdateDiscreteStates,
 * fmi3EnterStepMode):
 * - earlyReturnAllowed: the step stops at the first event, earlyReturn and lastSuccessfulTime
 *   say where (an event at the step's end is no early return);
 * - otherwise the FMU must reach the communication point. An event inside the step has passed
 *   when the step returns, and the importer could only handle it too late, so the FMU handles
 *   it inside, as without event mode, and returns eventHandlingNeeded at the communication
 *   point (the importer's Event Mode there finds it handled; the solver goes on unless that
 *   changes something); an event at the communication point itself (a time event there, a root
 *   found there) is left to the importer.
 * Without eventModeUsed every event is handled inside the step, as in FMI 2.0, whether or not
 * early return is allowed. A component that ended the simulation returns fmi3OK with
 * terminateSimulation = true and lastSuccessfulTime where it ended. */
fmi3Status fmi3DoStep(fmi3Instance instance, fmi3Float64 currentCommunicationPoint,
                      fmi3Float64 communicationStepSize, fmi3Boolean noSetFMUStatePriorToCurrentPoint,
                      fmi3Boolean *eventHandlingNeeded, fmi3Boolean *terminateSimulation, fmi3Boolean *earlyReturn,
                      fmi3Float64 *lastSuccessfulTime) {
    Instance *c = instance;
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK("fmi3DoStep", StepMode);
    CHECK_INTERFACE("fmi3DoStep", DFMI_CO_SIMULATION);
    if (!eventHandlingNeeded || !terminateSimulation || !earlyReturn || !lastSuccessfulTime)
        FAIL("fmi3DoStep: NULL argument");
    *eventHandlingNeeded = *terminateSimulation = *earlyReturn = fmi3False;
    *lastSuccessfulTime = c->time;
    double end = currentCommunicationPoint + communicationStepSize;
    DfmiStepEvents events = !c->event_mode_used        ? DFMI_EVENTS_INSIDE
                            : c->early_return_allowed ? DFMI_EVENTS_EARLY_RETURN
                                                      : DFMI_EVENTS_AT_STEP_END;
    int status = dfmi_do_step(c, "fmi3DoStep", currentCommunicationPoint, communicationStepSize, events);
    if (status >= fmi3Error) return (fmi3Status)dfmi_settle(c, status);
    int ended = dfmi_terminated(c);
    if (status == fmi3Discard && !ended) {
        c->state = StepDiscarded;
        return fmi3Discard;
    }
    double reached = end;
    if (ended) {
        c->terminated_by_model = *terminateSimulation = fmi3True;
        if (!isnan(c->L.control[1])) reached = c->L.control[1];
        status = status == fmi3Warning ? fmi3Warning : fmi3OK;
    } else if (events != DFMI_EVENTS_INSIDE && c->L.control[2] != 0.0) {
        *eventHandlingNeeded = fmi3True;
        if (!isnan(c->L.control[1])) reached = c->L.control[1];
    }
    if (fabs(reached - end) <= 1e-12 * fmax(1.0, fabs(end))) reached = end; /* round-off: the step's end */
    /* an end of the simulation is no early return, nor is an event at the communication point */
    *earlyReturn = *eventHandlingNeeded && reached < end;
    c->time = c->last_successful_time = *lastSuccessfulTime = reached;
    c->dirty = c->outputs_dirty = 0;
    return (fmi3Status)status;
}
