/* deltafmi FMI 2.0 loader: the FMU's binary. Plain C, no Python symbols, no link to libpython.
 *
 * It exports every fmi2 function of Model Exchange and Co-Simulation, enforces the FMI 2.0 state
 * machine, and reads/writes the model's value buffers directly (the Python instance owns them and
 * hands over their addresses), so getters and setters never enter Python. Work that needs the
 * model goes through the Python bridge (bridge.c, linked into this binary), started once Python
 * is in the process: the host's when it already runs Python, otherwise the interpreter a portable
 * FMU carries, or the one named in resources/python.cfg at build time (python_start.c).
 *
 * Built with hidden visibility: the binary exports the fmi2 functions and nothing else, so it can
 * neither interpose on a host's symbols nor be interposed by them. */
#define _GNU_SOURCE
#include "glibc_floor.h"
#include <dlfcn.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi2Functions.h"
#include "bridge.h"
#include "process_lock.h"
#include "python_start.h"

/* setter rules per scalar, written by deltafmi/component/layout.py */
#define SET_INSTANTIATED 1
#define SET_INITIALIZATION 2
#define SET_EVENT 4
#define SET_CONTINUOUS 8
#define IS_BOOLEAN 16

typedef enum {
    StartAndEnd = 1 << 0, Instantiated = 1 << 1, InitializationMode = 1 << 2, EventMode = 1 << 3,
    ContinuousTimeMode = 1 << 4, StepComplete = 1 << 5, StepInProgress = 1 << 6,
    StepFailed = 1 << 7, StepCanceled = 1 << 8, Terminated = 1 << 9, Error = 1 << 10, Fatal = 1 << 11
} ModelState;

/* Allowed states per function, as in the FMI 2.0 state machines (sections 3.2.3 and 4.2.4). */
#define ANY_INSTANCE (Instantiated | InitializationMode | EventMode | ContinuousTimeMode | \
                      StepComplete | StepFailed | StepCanceled | Terminated | Error)
#define MASK_GET (InitializationMode | EventMode | ContinuousTimeMode | StepComplete | StepFailed | \
                  StepCanceled | Terminated | Error)
#define MASK_SET (Instantiated | InitializationMode | EventMode | ContinuousTimeMode | StepComplete)
#define MASK_ME_GET (InitializationMode | EventMode | ContinuousTimeMode | Terminated | Error)

typedef struct {
    char *name;
    fmi2Type type;
    fmi2CallbackFunctions cb;
    unsigned log_mask; /* enabled log categories: bit i is CATEGORY_NAMES[i] */
    int state;
    double time, start_time, stop_time, tolerance;
    int stop_defined, tolerance_defined;
    double last_successful_time;
    int terminated_by_model;
    int dirty;         /* inputs, states or time changed: derivatives and indicators are stale */
    int outputs_dirty; /* outputs are stale (a solver asking for derivatives does not need them) */
    DfmiLayout L;
    void *py;
} Instance;

typedef struct {
    uint32_t magic;
    void *py;
    double time;
    double last_successful_time;
} SavedState;

#define STATE_MAGIC 0x64666d69u /* "dfmi" */

static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;
static int g_bridge_started;

/* ---------------------------------------------------------------------------------------- */
/* logging                                                                                   */

static void emit(const fmi2CallbackFunctions *cb, const char *name, fmi2Status status,
                 const char *category, const char *message) {
    if (!cb || !cb->logger) return;
    /* the message is the logger's format string: escape '%' (some hosts, fmpy among them,
     * print it without formatting) */
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
    cb->logger(cb->componentEnvironment, name ? name : "", status, category, escaped);
    free(escaped);
}

/* The log categories of <LogCategories> (deltafmi/component/fmu_logging.py CATEGORIES, same order).
 * fmi2Instantiate with loggingOn = true enables all, with false the status categories (warnings,
 * discards, errors); fmi2SetDebugLogging changes them. Errors are always sent: FMI 2.0 has a
 * function that returns fmi2Error explain itself through the logger. */
static const char *const CATEGORY_NAMES[] = {"logEvents", "logComponent", "logSolver", "logStatusWarning",
                                             "logStatusDiscard", "logStatusError"};
#define N_CATEGORIES (sizeof CATEGORY_NAMES / sizeof *CATEGORY_NAMES)
#define ALL_CATEGORIES ((1u << N_CATEGORIES) - 1)
#define CATEGORY_COMPONENT 1
#define STATUS_CATEGORIES (1u << 3 | 1u << 4 | 1u << 5)

static int category_index(const char *name) {
    for (size_t i = 0; i < N_CATEGORIES; i++)
        if (!strcmp(name, CATEGORY_NAMES[i])) return (int)i;
    return -1;
}

static int wanted(const Instance *c, int status, const char *category) {
    if (status >= fmi2Error) return 1;
    int index = category ? category_index(category) : -1;
    return (c->log_mask >> (index < 0 ? CATEGORY_COMPONENT : index)) & 1u;
}

static void logf_(Instance *c, fmi2Status status, const char *category, const char *fmt, ...) {
    if (!wanted(c, status, category)) return;
    char buffer[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buffer, sizeof buffer, fmt, ap);
    va_end(ap);
    emit(&c->cb, c->name, status, category, buffer);
}

static void bridge_log(void *env, int status, const char *category, const char *message) {
    Instance *c = env;
    if (!wanted(c, status, category)) return;
    emit(&c->cb, c->name, (fmi2Status)status, category, message);
}

static const char *state_name(int state) {
    switch (state) {
    case Instantiated: return "instantiated";
    case InitializationMode: return "initialization mode";
    case EventMode: return "event mode";
    case ContinuousTimeMode: return "continuous-time mode";
    case StepComplete: return "step complete";
    case StepInProgress: return "step in progress";
    case StepFailed: return "step failed";
    case StepCanceled: return "step canceled";
    case Terminated: return "terminated";
    case Error: return "error";
    default: return "fatal";
    }
}

static int allowed(Instance *c, const char *function, int mask) {
    if (!c) return 0;
    if (c->state & mask) return 1;
    logf_(c, fmi2Error, "logStatusError", "%s must not be called in state '%s' (FMI 2.0 state machine)",
          function, state_name(c->state));
    c->state = Error;
    return 0;
}

#define CHECK(function, mask) \
    do { if (!allowed(c, function, mask)) return fmi2Error; } while (0)

static fmi2Status fail(Instance *c, const char *fmt, ...) {
    char buffer[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(buffer, sizeof buffer, fmt, ap);
    va_end(ap);
    emit(&c->cb, c->name, fmi2Error, "logStatusError", buffer);
    c->state = Error;
    return fmi2Error;
}

/* Whether the component ended the simulation (Component.terminate_simulation). */
static int terminated(const Instance *c) { return c->L.control && c->L.control[0] != 0.0; }

/* A bridge call's status: errors move the instance to the error state. */
static fmi2Status settle(Instance *c, int status) {
    if (status >= fmi2Error) c->state = Error;
    return (fmi2Status)status;
}

/* ---------------------------------------------------------------------------------------- */
/* finding Python and the bridge                                                             */

static void own_directory(char *out, size_t size) {
    Dl_info info;
    out[0] = 0;
    if (dladdr((void *)&fmi2Instantiate, &info) && info.dli_fname) {
        snprintf(out, size, "%s", info.dli_fname);
        char *slash = strrchr(out, '/');
        if (slash) *slash = 0;
    }
}

/* A start-up that takes longer than this is stuck: say so rather than hang the host. */
#define START_LOCK_TIMEOUT_S 120.0

/* Start the Python bridge once per binary; 0 on success, else -1 with the reason in error.
 * g_lock orders this binary's threads (and makes later calls a flag test). The process-wide lock
 * orders the binaries: one of them finds no interpreter and starts it, every later one (another
 * model, another deltafmi version, portable or not) finds it initialized and binds to it. The
 * process lock covers no Python call that needs the GIL, so a host thread that holds the GIL
 * while it calls fmi2Instantiate cannot deadlock with a thread that holds the lock. */
static int start_bridge(const char *resources, char *error, size_t size) {
    pthread_mutex_lock(&g_lock);
    if (!g_bridge_started) {
        int lock = dfmi_process_lock(START_LOCK_TIMEOUT_S, error, size);
        if (lock != DFMI_PROCESS_LOCK_TIMEOUT && dfmi_start_python(resources, error, size) == 0)
            g_bridge_started = 1;
        dfmi_process_unlock(lock);
    }
    int started = g_bridge_started;
    pthread_mutex_unlock(&g_lock);
    return started ? 0 : -1;
}

/* resources URI -> path: file:///a/b, file:/a/b, file://localhost/a/b, with %XX decoding */
static char *resources_path(const char *uri) {
    char directory[4096];
    if (!uri || !uri[0]) { /* some hosts pass nothing: use <fmu>/binaries/linux64/../../resources */
        own_directory(directory, sizeof directory);
        size_t n = strlen(directory) + 32;
        char *path = malloc(n);
        if (path) snprintf(path, n, "%s/../../resources", directory);
        return path;
    }
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
    if (!functions || !functions->logger) {
        /* FMI 2.0 requires a logger; without one errors would be silent */
        return NULL;
    }
    if (!instanceName || !instanceName[0]) {
        emit(functions, "", fmi2Error, "logStatusError", "fmi2Instantiate: missing instance name");
        return NULL;
    }
    if (fmuType != fmi2ModelExchange && fmuType != fmi2CoSimulation) {
        emit(functions, instanceName, fmi2Error, "logStatusError", "fmi2Instantiate: unknown fmuType");
        return NULL;
    }
    Instance *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->name = strdup(instanceName);
    c->type = fmuType;
    c->cb = *functions;
    c->log_mask = loggingOn ? ALL_CATEGORIES : STATUS_CATEGORIES;
    c->stop_time = NAN;
    c->tolerance = NAN;
    char *resources = resources_path(fmuResourceLocation);
    char error[2048] = "";
    if (!resources || start_bridge(resources, error, sizeof error) != 0) {
        emit(functions, instanceName, fmi2Error, "logStatusError", error[0] ? error : "out of memory");
    } else {
        c->py = bridge_instantiate(resources, instanceName, fmuGUID ? fmuGUID : "", (int)fmuType, c->log_mask,
                                   bridge_log, c, &c->L);
    }
    free(resources);
    if (!c->py) {
        free(c->name);
        free(c);
        return NULL;
    }
    c->state = Instantiated;
    c->dirty = c->outputs_dirty = 1;
    return c;
}

void fmi2FreeInstance(fmi2Component component) {
    Instance *c = component;
    if (!c) return;
    if (c->py) bridge_free_instance(c->py);
    free(c->name);
    free(c);
}

fmi2Status fmi2SetDebugLogging(fmi2Component component, fmi2Boolean loggingOn, size_t nCategories,
                               const fmi2String categories[]) {
    Instance *c = component;
    CHECK("fmi2SetDebugLogging", ANY_INSTANCE);
    /* FMI 2.0: no categories switches all of them; with categories, loggingOn = true enables
     * exactly those ("only debug messages according to the categories argument"), false disables
     * them. logAll names every category. An unknown name changes nothing and is an error. */
    unsigned named = 0;
    if (nCategories && !categories) {
        logf_(c, fmi2Error, "logStatusError", "fmi2SetDebugLogging: categories is NULL for %zu categories", nCategories);
        return fmi2Error;
    }
    for (size_t i = 0; i < nCategories; i++) {
        const char *name = categories[i];
        int index = name ? category_index(name) : -1;
        if (name && !strcmp(name, "logAll")) {
            named = ALL_CATEGORIES;
        } else if (index < 0) {
            char known[256] = "";
            for (size_t k = 0; k < N_CATEGORIES; k++) {
                strncat(known, CATEGORY_NAMES[k], sizeof known - strlen(known) - 1);
                strncat(known, ", ", sizeof known - strlen(known) - 1);
            }
            /* nothing changed: the instance goes on, unlike after a failed computation */
            logf_(c, fmi2Error, "logStatusError", "fmi2SetDebugLogging: unknown log category '%s' (this FMU's "
                  "categories: %slogAll)", name ? name : "(NULL)", known);
            return fmi2Error;
        } else {
            named |= 1u << index;
        }
    }
    unsigned mask = !nCategories ? (loggingOn ? ALL_CATEGORIES : 0u)
                    : loggingOn ? named : c->log_mask & ~named;
    c->log_mask = mask;
    return settle(c, bridge_set_log_mask(c->py, mask));
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
    double args[3] = {c->start_time, c->stop_defined ? c->stop_time : NAN,
                      c->tolerance_defined ? c->tolerance : NAN};
    int status = bridge_call(c->py, DFMI_ENTER_INITIALIZATION, args, 3);
    if (status < fmi2Error) {
        c->state = InitializationMode;
        c->time = c->start_time;
        c->dirty = c->outputs_dirty = 1;
    }
    return settle(c, status);
}

fmi2Status fmi2ExitInitializationMode(fmi2Component component) {
    Instance *c = component;
    CHECK("fmi2ExitInitializationMode", InitializationMode);
    int status = bridge_call(c->py, DFMI_EXIT_INITIALIZATION, NULL, 0);
    if (status < fmi2Error) {
        c->state = c->type == fmi2ModelExchange ? EventMode : StepComplete;
        c->last_successful_time = c->time;
        c->dirty = c->outputs_dirty = 0;
    }
    return settle(c, status);
}

fmi2Status fmi2Terminate(fmi2Component component) {
    Instance *c = component;
    CHECK("fmi2Terminate", EventMode | ContinuousTimeMode | StepComplete | StepFailed);
    int status = bridge_call(c->py, DFMI_TERMINATE, NULL, 0);
    if (status < fmi2Error) c->state = Terminated;
    return settle(c, status);
}

fmi2Status fmi2Reset(fmi2Component component) {
    Instance *c = component;
    CHECK("fmi2Reset", ANY_INSTANCE);
    int status = bridge_call(c->py, DFMI_RESET, NULL, 0);
    if (status < fmi2Error) {
        c->state = Instantiated;
        c->time = c->start_time = 0.0;
        c->stop_defined = c->tolerance_defined = 0;
        c->terminated_by_model = 0;
        c->dirty = c->outputs_dirty = 1;
    }
    return settle(c, status);
}

/* ---------------------------------------------------------------------------------------- */
/* values                                                                                    */

#define MASK_EVALUATE (InitializationMode | EventMode | ContinuousTimeMode | StepComplete)

/* Everything up to date, for getters of variable values. */
static fmi2Status ensure_evaluated(Instance *c) {
    if (!(c->dirty || c->outputs_dirty) || !(c->state & MASK_EVALUATE)) return fmi2OK;
    int status = bridge_call(c->py, DFMI_EVALUATE, &c->time, 1);
    if (status < fmi2Error) c->dirty = c->outputs_dirty = 0;
    return settle(c, status);
}

/* Derivatives and event indicators up to date: the integrator's hot path. */
static fmi2Status ensure_derivatives(Instance *c) {
    if (!c->dirty || !(c->state & MASK_EVALUATE)) return fmi2OK;
    int status = c->state & (EventMode | ContinuousTimeMode)
                     ? bridge_derivatives(c->py, c->time, c->L.real + c->L.dx_offset, c->L.nx,
                                          c->L.event_indicators, c->L.nz)
                     : bridge_call(c->py, DFMI_EVALUATE_DERIVATIVES, &c->time, 1);
    if (status < fmi2Error) c->dirty = 0; /* the outputs stay stale */
    return settle(c, status);
}

/* For getters: derivatives are recomputed only when asked for (or in initialization, where the
 * model initializes itself); an integrator that reads outputs after its last stage already has
 * the derivatives it needs, and outputs never depend on them. */
static fmi2Status ensure_values(Instance *c, const fmi2ValueReference vr[], size_t nvr) {
    if (!(c->state & MASK_EVALUATE)) return fmi2OK;
    int derivatives = c->state == InitializationMode;
    for (size_t i = 0; i < nvr && !derivatives; i++)
        derivatives = vr[i] >= c->L.dx_offset && vr[i] < c->L.dx_offset + c->L.nx;
    if (c->dirty && derivatives) return ensure_evaluated(c);
    if (!c->outputs_dirty) return fmi2OK;
    int status = bridge_call(c->py, DFMI_EVALUATE_OUTPUTS, &c->time, 1);
    if (status < fmi2Error) c->outputs_dirty = 0; /* the derivatives may stay stale */
    return settle(c, status);
}

static int setter_bit(int state) {
    switch (state) {
    case Instantiated: return SET_INSTANTIATED;
    case InitializationMode: return SET_INITIALIZATION;
    case EventMode: case StepComplete: return SET_EVENT;
    case ContinuousTimeMode: return SET_CONTINUOUS;
    default: return 0;
    }
}

#define CHECK_ARRAYS(function) \
    do { if (nvr > 0 && (!vr || !value)) return fail(c, "%s: NULL array argument", function); } while (0)

fmi2Status fmi2GetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, fmi2Real value[]) {
    Instance *c = component;
    CHECK("fmi2GetReal", MASK_GET);
    CHECK_ARRAYS("fmi2GetReal");
    if (nvr && ensure_values(c, vr, nvr) >= fmi2Error) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= c->L.n_real)
            return fail(c, "fmi2GetReal: %u is not the value reference of a Real", vr[i]);
        value[i] = c->L.real[vr[i]];
    }
    return fmi2OK;
}

fmi2Status fmi2SetReal(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, const fmi2Real value[]) {
    Instance *c = component;
    CHECK("fmi2SetReal", MASK_SET);
    CHECK_ARRAYS("fmi2SetReal");
    int bit = setter_bit(c->state);
    for (size_t i = 0; i < nvr; i++) {
        if (vr[i] >= c->L.n_real)
            return fail(c, "fmi2SetReal: %u is not the value reference of a Real", vr[i]);
        if (!(c->L.flags[vr[i]] & bit))
            return fail(c, "fmi2SetReal: the variable with value reference %u cannot be set in state '%s'",
                        vr[i], state_name(c->state));
    }
    for (size_t i = 0; i < nvr; i++) c->L.real[vr[i]] = value[i];
    c->dirty = c->outputs_dirty = 1;
    return fmi2OK;
}

/* Integer and Boolean share the int buffer; value references continue after the reals. */
static fmi2Status get_ints(Instance *c, const char *function, int boolean, const fmi2ValueReference vr[],
                           size_t nvr, int value[]) {
    if (nvr > 0 && (!vr || !value)) return fail(c, "%s: NULL array argument", function);
    if (nvr && ensure_values(c, NULL, 0) >= fmi2Error) return fmi2Error;
    for (size_t i = 0; i < nvr; i++) {
        size_t k = vr[i] - c->L.n_real;
        if (vr[i] < c->L.n_real || k >= c->L.n_int || !(c->L.flags[vr[i]] & IS_BOOLEAN) != !boolean)
            return fail(c, "%s: %u is not the value reference of %s", function, vr[i],
                        boolean ? "a Boolean" : "an Integer");
        value[i] = c->L.ints[k];
    }
    return fmi2OK;
}

static fmi2Status set_ints(Instance *c, const char *function, int boolean, const fmi2ValueReference vr[],
                           size_t nvr, const int value[]) {
    if (nvr > 0 && (!vr || !value)) return fail(c, "%s: NULL array argument", function);
    int bit = setter_bit(c->state);
    for (size_t i = 0; i < nvr; i++) {
        size_t k = vr[i] - c->L.n_real;
        if (vr[i] < c->L.n_real || k >= c->L.n_int || !(c->L.flags[vr[i]] & IS_BOOLEAN) != !boolean)
            return fail(c, "%s: %u is not the value reference of %s", function, vr[i],
                        boolean ? "a Boolean" : "an Integer");
        if (!(c->L.flags[vr[i]] & bit))
            return fail(c, "%s: the variable with value reference %u cannot be set in state '%s'",
                        function, vr[i], state_name(c->state));
    }
    for (size_t i = 0; i < nvr; i++)
        c->L.ints[vr[i] - c->L.n_real] = boolean ? (value[i] != 0) : value[i];
    c->dirty = c->outputs_dirty = 1;
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

static int string_index(Instance *c, fmi2ValueReference vr, size_t *index) {
    size_t first = c->L.n_real + c->L.n_int;
    if (vr < first || vr - first >= c->L.n_str) return 0;
    *index = vr - first;
    return 1;
}

fmi2Status fmi2GetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, fmi2String value[]) {
    Instance *c = component;
    CHECK("fmi2GetString", MASK_GET);
    CHECK_ARRAYS("fmi2GetString");
    for (size_t i = 0; i < nvr; i++) {
        size_t index;
        if (!string_index(c, vr[i], &index))
            return fail(c, "fmi2GetString: %u is not the value reference of a String", vr[i]);
        /* the bridge keeps each returned string alive until the next call for the same index */
        int status = bridge_get_string(c->py, index, &value[i]);
        if (status >= fmi2Error) return settle(c, status);
    }
    return fmi2OK;
}

fmi2Status fmi2SetString(fmi2Component component, const fmi2ValueReference vr[], size_t nvr, const fmi2String value[]) {
    Instance *c = component;
    CHECK("fmi2SetString", MASK_SET);
    CHECK_ARRAYS("fmi2SetString");
    int bit = setter_bit(c->state);
    for (size_t i = 0; i < nvr; i++) {
        size_t index;
        if (!string_index(c, vr[i], &index))
            return fail(c, "fmi2SetString: %u is not the value reference of a String", vr[i]);
        if (!(bit & (SET_INSTANTIATED | SET_INITIALIZATION)))
            return fail(c, "fmi2SetString: string parameters cannot be set in state '%s'", state_name(c->state));
        int status = bridge_set_string(c->py, index, value[i] ? value[i] : "");
        if (status >= fmi2Error) return settle(c, status);
    }
    c->dirty = c->outputs_dirty = 1;
    return fmi2OK;
}

/* ---------------------------------------------------------------------------------------- */
/* FMU state                                                                                 */

#define MASK_FMU_STATE ANY_INSTANCE

fmi2Status fmi2GetFMUstate(fmi2Component component, fmi2FMUstate *FMUstate) {
    Instance *c = component;
    CHECK("fmi2GetFMUstate", MASK_FMU_STATE);
    if (!FMUstate) return fail(c, "fmi2GetFMUstate: NULL argument");
    SavedState *saved = *FMUstate;
    if (saved && saved->magic == STATE_MAGIC) { /* the importer may hand back an old state to reuse */
        bridge_free_state(saved->py);
    } else {
        saved = calloc(1, sizeof *saved);
        if (!saved) return fail(c, "fmi2GetFMUstate: out of memory");
    }
    saved->magic = STATE_MAGIC;
    saved->time = c->time;
    saved->last_successful_time = c->last_successful_time;
    int status = bridge_get_state(c->py, &saved->py);
    if (status >= fmi2Error) {
        free(saved);
        *FMUstate = NULL;
        return settle(c, status);
    }
    *FMUstate = saved;
    return fmi2OK;
}

static SavedState *as_saved(fmi2FMUstate state) {
    SavedState *saved = state;
    return saved && saved->magic == STATE_MAGIC ? saved : NULL;
}

fmi2Status fmi2SetFMUstate(fmi2Component component, fmi2FMUstate FMUstate) {
    Instance *c = component;
    CHECK("fmi2SetFMUstate", MASK_FMU_STATE);
    SavedState *saved = as_saved(FMUstate);
    if (!saved) return fail(c, "fmi2SetFMUstate: not an FMU state of this FMU");
    int status = bridge_set_state(c->py, saved->py);
    if (status < fmi2Error) {
        c->time = saved->time;
        c->last_successful_time = saved->last_successful_time;
        c->dirty = c->outputs_dirty = 1;
        /* back before the component ended the simulation: stepping may go on */
        c->terminated_by_model = terminated(c);
        if (c->state == StepFailed && !c->terminated_by_model) c->state = StepComplete;
    }
    return settle(c, status);
}

fmi2Status fmi2FreeFMUstate(fmi2Component component, fmi2FMUstate *FMUstate) {
    Instance *c = component;
    CHECK("fmi2FreeFMUstate", MASK_FMU_STATE);
    if (!FMUstate || !*FMUstate) return fmi2OK;
    SavedState *saved = as_saved(*FMUstate);
    if (!saved) return fail(c, "fmi2FreeFMUstate: not an FMU state of this FMU");
    bridge_free_state(saved->py);
    saved->magic = 0;
    free(saved);
    *FMUstate = NULL;
    return fmi2OK;
}

/* serialized layout: magic, time, last successful time, then the bridge's bytes */
#define HEADER_SIZE (sizeof(uint32_t) + 2 * sizeof(double))

fmi2Status fmi2SerializedFMUstateSize(fmi2Component component, fmi2FMUstate FMUstate, size_t *size) {
    Instance *c = component;
    CHECK("fmi2SerializedFMUstateSize", MASK_FMU_STATE);
    SavedState *saved = as_saved(FMUstate);
    if (!saved || !size) return fail(c, "fmi2SerializedFMUstateSize: invalid argument");
    const char *bytes;
    size_t n;
    int status = bridge_serialize_state(c->py, saved->py, &bytes, &n);
    if (status >= fmi2Error) return settle(c, status);
    *size = HEADER_SIZE + n;
    return fmi2OK;
}

fmi2Status fmi2SerializeFMUstate(fmi2Component component, fmi2FMUstate FMUstate, fmi2Byte serializedState[],
                                 size_t size) {
    Instance *c = component;
    CHECK("fmi2SerializeFMUstate", MASK_FMU_STATE);
    SavedState *saved = as_saved(FMUstate);
    if (!saved || !serializedState) return fail(c, "fmi2SerializeFMUstate: invalid argument");
    const char *bytes;
    size_t n;
    int status = bridge_serialize_state(c->py, saved->py, &bytes, &n);
    if (status >= fmi2Error) return settle(c, status);
    if (size < HEADER_SIZE + n) return fail(c, "fmi2SerializeFMUstate: buffer of %zu bytes is too small", size);
    uint32_t magic = STATE_MAGIC;
    memcpy(serializedState, &magic, sizeof magic);
    memcpy(serializedState + sizeof magic, &saved->time, sizeof(double));
    memcpy(serializedState + sizeof magic + sizeof(double), &saved->last_successful_time, sizeof(double));
    memcpy(serializedState + HEADER_SIZE, bytes, n);
    return fmi2OK;
}

fmi2Status fmi2DeSerializeFMUstate(fmi2Component component, const fmi2Byte serializedState[], size_t size,
                                   fmi2FMUstate *FMUstate) {
    Instance *c = component;
    CHECK("fmi2DeSerializeFMUstate", MASK_FMU_STATE);
    uint32_t magic = 0;
    if (!serializedState || !FMUstate || size < HEADER_SIZE ||
        (memcpy(&magic, serializedState, sizeof magic), magic != STATE_MAGIC))
        return fail(c, "fmi2DeSerializeFMUstate: not a serialized state of a deltafmi FMU");
    SavedState *saved = calloc(1, sizeof *saved);
    if (!saved) return fail(c, "fmi2DeSerializeFMUstate: out of memory");
    saved->magic = STATE_MAGIC;
    memcpy(&saved->time, serializedState + sizeof magic, sizeof(double));
    memcpy(&saved->last_successful_time, serializedState + sizeof magic + sizeof(double), sizeof(double));
    int status = bridge_deserialize_state(c->py, serializedState + HEADER_SIZE, size - HEADER_SIZE, &saved->py);
    if (status >= fmi2Error) {
        free(saved);
        return settle(c, status);
    }
    *FMUstate = saved;
    return fmi2OK;
}

fmi2Status fmi2GetDirectionalDerivative(fmi2Component component, const fmi2ValueReference vUnknown_ref[],
                                        size_t nUnknown, const fmi2ValueReference vKnown_ref[], size_t nKnown,
                                        const fmi2Real dvKnown[], fmi2Real dvUnknown[]) {
    Instance *c = component;
    CHECK("fmi2GetDirectionalDerivative", MASK_GET);
    if ((nUnknown && (!vUnknown_ref || !dvUnknown)) || (nKnown && (!vKnown_ref || !dvKnown)))
        return fail(c, "fmi2GetDirectionalDerivative: NULL array argument");
    if (!nUnknown) return fmi2OK;
    /* the model reads the states and inputs straight from its buffers; the values it computes on
     * the way are restored, so the dirty flags stay true */
    return settle(c, bridge_directional_derivative(c->py, c->time, vUnknown_ref, nUnknown, vKnown_ref, nKnown,
                                                   dvKnown, dvUnknown));
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
    if (!eventInfo) return fail(c, "fmi2NewDiscreteStates: NULL eventInfo");
    int flags[5] = {0, 0, 0, 0, 0};
    double next = 0.0;
    int status = bridge_event_update(c->py, c->time, flags, &next);
    /* the FMU owns fmi2EventInfo: every field is written, whatever happened */
    eventInfo->newDiscreteStatesNeeded = flags[0] ? fmi2True : fmi2False;
    eventInfo->terminateSimulation = flags[1] ? fmi2True : fmi2False;
    eventInfo->nominalsOfContinuousStatesChanged = flags[2] ? fmi2True : fmi2False;
    eventInfo->valuesOfContinuousStatesChanged = flags[3] ? fmi2True : fmi2False;
    eventInfo->nextEventTimeDefined = flags[4] ? fmi2True : fmi2False;
    eventInfo->nextEventTime = next;
    if (status < fmi2Error) c->dirty = c->outputs_dirty = 0;
    return settle(c, status);
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
    if (!enterEventMode || !terminateSimulation) return fail(c, "fmi2CompletedIntegratorStep: NULL argument");
    *enterEventMode = fmi2False;
    int status = fmi2OK;
    if (c->L.watches_drift) {
        int enter = 0;
        status = bridge_completed_step(c->py, c->time, &enter);
        *enterEventMode = enter ? fmi2True : fmi2False;
    }
    /* the component may have ended the simulation in any evaluation since the last step */
    *terminateSimulation = terminated(c) ? fmi2True : fmi2False;
    return settle(c, status);
}

fmi2Status fmi2SetTime(fmi2Component component, fmi2Real time) {
    Instance *c = component;
    CHECK("fmi2SetTime", EventMode | ContinuousTimeMode);
    c->time = time;
    c->dirty = c->outputs_dirty = 1;
    return fmi2OK;
}

fmi2Status fmi2SetContinuousStates(fmi2Component component, const fmi2Real x[], size_t nx) {
    Instance *c = component;
    CHECK("fmi2SetContinuousStates", ContinuousTimeMode);
    if (nx != c->L.nx || (nx && !x)) return fail(c, "fmi2SetContinuousStates: expected %zu states, got %zu", c->L.nx, nx);
    memcpy(c->L.real + c->L.x_offset, x, nx * sizeof(double));
    c->dirty = c->outputs_dirty = 1;
    return fmi2OK;
}

fmi2Status fmi2GetDerivatives(fmi2Component component, fmi2Real derivatives[], size_t nx) {
    Instance *c = component;
    CHECK("fmi2GetDerivatives", MASK_ME_GET);
    if (nx != c->L.nx || (nx && !derivatives))
        return fail(c, "fmi2GetDerivatives: expected %zu derivatives, got %zu", c->L.nx, nx);
    if (ensure_derivatives(c) >= fmi2Error) return fmi2Error;
    memcpy(derivatives, c->L.real + c->L.dx_offset, nx * sizeof(double));
    return fmi2OK;
}

fmi2Status fmi2GetEventIndicators(fmi2Component component, fmi2Real eventIndicators[], size_t ni) {
    Instance *c = component;
    CHECK("fmi2GetEventIndicators", MASK_ME_GET);
    if (ni != c->L.nz || (ni && !eventIndicators))
        return fail(c, "fmi2GetEventIndicators: expected %zu event indicators, got %zu", c->L.nz, ni);
    if (ensure_derivatives(c) >= fmi2Error) return fmi2Error;
    memcpy(eventIndicators, c->L.event_indicators, ni * sizeof(double));
    return fmi2OK;
}

fmi2Status fmi2GetContinuousStates(fmi2Component component, fmi2Real x[], size_t nx) {
    Instance *c = component;
    CHECK("fmi2GetContinuousStates", MASK_ME_GET);
    if (nx != c->L.nx || (nx && !x)) return fail(c, "fmi2GetContinuousStates: expected %zu states, got %zu", c->L.nx, nx);
    if (c->state == InitializationMode && ensure_derivatives(c) >= fmi2Error) return fmi2Error;
    memcpy(x, c->L.real + c->L.x_offset, nx * sizeof(double));
    return fmi2OK;
}

fmi2Status fmi2GetNominalsOfContinuousStates(fmi2Component component, fmi2Real x_nominal[], size_t nx) {
    Instance *c = component;
    CHECK("fmi2GetNominalsOfContinuousStates", Instantiated | EventMode | ContinuousTimeMode | Terminated | Error);
    if (nx != c->L.nx || (nx && !x_nominal)) return fail(c, "fmi2GetNominalsOfContinuousStates: expected %zu, got %zu", c->L.nx, nx);
    memcpy(x_nominal, c->L.nominals, nx * sizeof(double));
    return fmi2OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Co-Simulation                                                                             */

fmi2Status fmi2SetRealInputDerivatives(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                                       const fmi2Integer order[], const fmi2Real value[]) {
    Instance *c = component;
    (void)vr; (void)nvr; (void)order; (void)value;
    CHECK("fmi2SetRealInputDerivatives", Instantiated | InitializationMode | StepComplete);
    return fail(c, "fmi2SetRealInputDerivatives: not supported (canInterpolateInputs=false)");
}

fmi2Status fmi2GetRealOutputDerivatives(fmi2Component component, const fmi2ValueReference vr[], size_t nvr,
                                        const fmi2Integer order[], fmi2Real value[]) {
    Instance *c = component;
    (void)vr; (void)nvr; (void)order; (void)value;
    CHECK("fmi2GetRealOutputDerivatives", StepComplete | StepFailed | StepCanceled | Terminated | Error);
    return fail(c, "fmi2GetRealOutputDerivatives: not supported (maxOutputDerivativeOrder=0)");
}

fmi2Status fmi2DoStep(fmi2Component component, fmi2Real currentCommunicationPoint, fmi2Real communicationStepSize,
                      fmi2Boolean noSetFMUStatePriorToCurrentPoint) {
    Instance *c = component;
    (void)noSetFMUStatePriorToCurrentPoint;
    CHECK("fmi2DoStep", StepComplete);
    if (!(communicationStepSize > 0.0))
        return fail(c, "fmi2DoStep: communicationStepSize must be > 0, got %g", communicationStepSize);
    if (fabs(currentCommunicationPoint - c->time) > 1e-9 * fmax(1.0, fabs(currentCommunicationPoint)))
        return fail(c, "fmi2DoStep: currentCommunicationPoint %.16g differs from the FMU time %.16g",
                    currentCommunicationPoint, c->time);
    double args[2] = {currentCommunicationPoint, communicationStepSize};
    int status = bridge_call(c->py, DFMI_DO_STEP, args, 2);
    int ended = terminated(c);
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
    return settle(c, status);
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
    logf_(c, fmi2Discard, "logStatusDiscard", "fmi2GetStatus: steps are synchronous, nothing is pending");
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
