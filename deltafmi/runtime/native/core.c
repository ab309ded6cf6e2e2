/* The plumbing the FMI 2.0 and FMI 3.0 APIs share (see core.h). Plain C, no Python symbols, no
 * link to libpython: the model is reached through the Python bridge (bridge.c, linked into the
 * same binary), started once Python is in the process: the host's when it already runs Python,
 * otherwise the interpreter a portable FMU carries, or the one named in resources/python.cfg at
 * build time (python_start.c). Value getters and setters never enter Python: the Python instance
 * owns the value buffers and hands over their addresses. */
#define _GNU_SOURCE
#include "glibc_floor.h"
#include <dlfcn.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "core.h"
#include "cs_step.h"
#include "process_lock.h"
#include "python_start.h"

/* An FMU state: the model's (the bridge's) and the instance's own, its place in the state machine
 * included: setting it puts the instance back where it was taken (the Reference FMUs do the same) */
typedef struct {
    uint32_t magic;
    void *py;
    double time;
    double last_successful_time;
    int32_t state; /* the state machine's (a ModelState bit); 0: unknown, the state is left as it is */
    int32_t stop_defined, tolerance_defined;
    double start_time, stop_time, tolerance;
    uint64_t clocks_active;
} SavedState;

#define STATE_MAGIC 0x64666d69u /* "dfmi" */

static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;
static int g_bridge_started;

/* ---------------------------------------------------------------------------------------- */
/* logging                                                                                   */

/* The log categories of <LogCategories> (deltafmi/runtime/fmu_logging.py CATEGORIES, same order).
 * Instantiation with loggingOn = true enables all, with false the status categories (warnings,
 * discards, errors); SetDebugLogging changes them. Errors are always sent: a function that
 * returns an error explains itself through the logger. */
static const char *const CATEGORY_NAMES[] = {"logEvents", "logComponent", "logSolver", "logStatusWarning",
                                             "logStatusDiscard", "logStatusError"};
#define N_CATEGORIES (sizeof CATEGORY_NAMES / sizeof *CATEGORY_NAMES)
#define CATEGORY_COMPONENT 1

static int category_index(const char *name) {
    for (size_t i = 0; i < N_CATEGORIES; i++)
        if (!strcmp(name, CATEGORY_NAMES[i])) return (int)i;
    return -1;
}

static int wanted(const Instance *c, int status, const char *category) {
    if (status >= DFMI_ERROR) return 1;
    int index = category ? category_index(category) : -1;
    return (c->log_mask >> (index < 0 ? CATEGORY_COMPONENT : index)) & 1u;
}

static void vlog(Instance *c, int status, const char *category, const char *fmt, va_list ap) {
    char buffer[1024];
    vsnprintf(buffer, sizeof buffer, fmt, ap);
    c->emit(c, status, category, buffer);
}

void dfmi_logf(Instance *c, int status, const char *category, const char *fmt, ...) {
    if (!wanted(c, status, category)) return;
    va_list ap;
    va_start(ap, fmt);
    vlog(c, status, category, fmt, ap);
    va_end(ap);
}

int dfmi_fail(Instance *c, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vlog(c, DFMI_ERROR, "logStatusError", fmt, ap);
    va_end(ap);
    c->state = Error;
    return DFMI_ERROR;
}

static void bridge_log(void *env, int status, const char *category, const char *message) {
    Instance *c = env;
    if (wanted(c, status, category)) c->emit(c, status, category, message);
}

int dfmi_set_debug_logging(Instance *c, const char *function, int logging_on, size_t n, const char *const names[]) {
    /* no categories switches all of them; with categories, loggingOn = true enables exactly those
     * ("only debug messages according to the categories argument"), false disables them. logAll
     * names every category. An unknown name changes nothing and is an error. */
    unsigned named = 0;
    if (n && !names) {
        dfmi_logf(c, DFMI_ERROR, "logStatusError", "%s: categories is NULL for %zu categories", function, n);
        return DFMI_ERROR;
    }
    for (size_t i = 0; i < n; i++) {
        const char *name = names[i];
        int index = name ? category_index(name) : -1;
        if (name && !strcmp(name, "logAll")) {
            named = DFMI_ALL_CATEGORIES;
        } else if (index < 0) {
            char known[256] = "";
            for (size_t k = 0; k < N_CATEGORIES; k++) {
                strncat(known, CATEGORY_NAMES[k], sizeof known - strlen(known) - 1);
                strncat(known, ", ", sizeof known - strlen(known) - 1);
            }
            /* nothing changed: the instance goes on, unlike after a failed computation */
            dfmi_logf(c, DFMI_ERROR, "logStatusError", "%s: unknown log category '%s' (this FMU's categories: "
                      "%slogAll)", function, name ? name : "(NULL)", known);
            return DFMI_ERROR;
        } else {
            named |= 1u << index;
        }
    }
    c->log_mask = !n ? (logging_on ? DFMI_ALL_CATEGORIES : 0u) : logging_on ? named : c->log_mask & ~named;
    return dfmi_settle(c, bridge_set_log_mask(c->py, c->log_mask));
}

const char *dfmi_state_name(const Instance *c, int state) {
    int three = c && c->fmi_version == 3;
    switch (state) {
    case Instantiated: return "instantiated";
    case InitializationMode: return "initialization mode";
    case EventMode: return "event mode";
    case ContinuousTimeMode: return "continuous-time mode";
    case StepComplete: return three ? "step mode" : "step complete";
    case StepInProgress: return "step in progress";
    case StepFailed: return three ? "step discarded" : "step failed";
    case StepCanceled: return "step canceled";
    case Terminated: return "terminated";
    case ConfigurationMode: return "configuration mode";
    case ClockActivationMode: return "clock activation mode";
    case Error: return "error";
    default: return "fatal";
    }
}

int dfmi_refuse(Instance *c, const char *function) {
    if (!c) return 0;
    dfmi_logf(c, DFMI_ERROR, "logStatusError", "%s must not be called in state '%s' (FMI %s state machine)",
              function, dfmi_state_name(c, c->state), c->fmi_version == 3 ? "3.0" : "2.0");
    c->state = Error;
    return 0;
}

int dfmi_settle(Instance *c, int status) {
    if (status >= DFMI_ERROR) c->state = Error;
    return status;
}

/* ---------------------------------------------------------------------------------------- */
/* life cycle                                                                                */

Instance *dfmi_new_instance(const char *name, int fmi_version, int interface, DfmiEmitFn emit, void *host_env,
                            void (*host_logger)(void), int logging_on) {
    Instance *c = calloc(1, sizeof *c);
    if (!c || !(c->name = strdup(name))) {
        free(c);
        return NULL;
    }
    c->fmi_version = fmi_version;
    c->interface = interface;
    c->emit = emit;
    c->host_env = host_env;
    c->host_logger = host_logger;
    c->log_mask = logging_on ? DFMI_ALL_CATEGORIES : DFMI_STATUS_CATEGORIES;
    c->stop_time = NAN;
    c->tolerance = NAN;
    dfmi_reset_clocks(c);
    return c;
}

char *dfmi_default_resources(void) {
    Dl_info info;
    char directory[4096] = "";
    if (dladdr((void *)&dfmi_default_resources, &info) && info.dli_fname) {
        snprintf(directory, sizeof directory, "%s", info.dli_fname);
        char *slash = strrchr(directory, '/');
        if (slash) *slash = 0;
    }
    size_t n = strlen(directory) + 32;
    char *path = malloc(n);
    if (path) snprintf(path, n, "%s/../../resources", directory);
    return path;
}

/* A start-up that takes longer than this is stuck: say so rather than hang the host. */
#define START_LOCK_TIMEOUT_S 120.0

/* Start the Python bridge once per binary; 0 on success, else -1 with the reason in error.
 * g_lock orders this binary's threads (and makes later calls a flag test). The process-wide lock
 * orders the binaries: one of them finds no interpreter and starts it, every later one (another
 * model, another deltafmi version, portable or not) finds it initialized and binds to it. The
 * process lock covers no Python call that needs the GIL, so a host thread that holds the GIL
 * while it instantiates cannot deadlock with a thread that holds the lock. */
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

int dfmi_connect(Instance *c, const char *resources, const char *token) {
    char error[2048] = "";
    if (!resources || start_bridge(resources, error, sizeof error) != 0) {
        c->emit(c, DFMI_ERROR, "logStatusError", error[0] ? error : "out of memory");
        return -1;
    }
    c->py = bridge_instantiate(resources, c->name, token ? token : "", c->fmi_version, c->interface, c->log_mask,
                               bridge_log, c, &c->L);
    if (!c->py) return -1;
    c->state = Instantiated;
    c->dirty = c->outputs_dirty = 1;
    return 0;
}

void dfmi_free_instance(Instance *c) {
    if (!c) return;
    if (c->py) bridge_free_instance(c->py);
    free(c->name);
    free(c);
}

int dfmi_enter_initialization(Instance *c) {
    double args[3] = {c->start_time, c->stop_defined ? c->stop_time : NAN, c->tolerance_defined ? c->tolerance : NAN};
    int status = bridge_call(c->py, DFMI_ENTER_INITIALIZATION, args, 3);
    if (status < DFMI_ERROR) {
        c->state = InitializationMode;
        c->time = c->start_time;
        c->dirty = c->outputs_dirty = 1;
    }
    return dfmi_settle(c, status);
}

int dfmi_exit_initialization(Instance *c, int next_state) {
    /* in event mode the importer's event iteration follows, not the model's own */
    double event_mode = 1.0;
    int status = bridge_call(c->py, DFMI_EXIT_INITIALIZATION, &event_mode, c->event_mode_used ? 1 : 0);
    if (status < DFMI_ERROR) {
        c->state = next_state;
        c->last_successful_time = c->time;
        c->dirty = c->outputs_dirty = 0;
    }
    return dfmi_settle(c, status);
}

int dfmi_terminate(Instance *c) {
    int status = bridge_call(c->py, DFMI_TERMINATE, NULL, 0);
    if (status < DFMI_ERROR) c->state = Terminated;
    return dfmi_settle(c, status);
}

int dfmi_reset(Instance *c) {
    int status = bridge_call(c->py, DFMI_RESET, NULL, 0);
    if (status < DFMI_ERROR) {
        c->state = Instantiated;
        c->time = c->start_time = 0.0;
        c->stop_defined = c->tolerance_defined = 0;
        c->terminated_by_model = 0;
        c->dirty = c->outputs_dirty = 1;
        dfmi_reset_clocks(c);
    }
    return dfmi_settle(c, status);
}

/* ---------------------------------------------------------------------------------------- */
/* values                                                                                    */

#define MASK_EVALUATE (InitializationMode | EventMode | ContinuousTimeMode | StepComplete | ClockActivationMode)

/* What the component's compiled kernels can do now (outside initialization, where the model
 * initializes itself, and while its attributes are in their struct): 1 when they computed all that
 * was asked (derivatives: with the event indicators), 0 to leave it to Python. */
static int native_evaluate(Instance *c, int derivatives, int outputs) {
    const DfmiLayout *L = &c->L;
    if (!L->kernels_ready || !*L->kernels_ready || c->state == InitializationMode) return 0;
    int states = derivatives && L->nx, indicators = derivatives && L->nz;
    if ((states && !L->kernel_derivatives) || (indicators && !L->kernel_indicators) || (outputs && !L->kernel_outputs))
        return 0;
    const void *a = L->kernel_attributes;
    return (!states || L->kernel_derivatives(a, c->time, L->real, L->ints, L->event_indicators) == 0) &&
           (!indicators || L->kernel_indicators(a, c->time, L->real, L->ints, L->event_indicators) == 0) &&
           (!outputs || L->kernel_outputs(a, c->time, L->real, L->ints, L->event_indicators) == 0);
}

int dfmi_ensure_evaluated(Instance *c) {
    if (!(c->dirty || c->outputs_dirty) || !(c->state & MASK_EVALUATE)) return DFMI_OK;
    if (native_evaluate(c, c->dirty, c->outputs_dirty)) {
        c->dirty = c->outputs_dirty = 0;
        return DFMI_OK;
    }
    int status = bridge_call(c->py, DFMI_EVALUATE, &c->time, 1);
    if (status < DFMI_ERROR) c->dirty = c->outputs_dirty = 0;
    return dfmi_settle(c, status);
}

/* the integrator's hot path */
int dfmi_ensure_derivatives(Instance *c) {
    if (!c->dirty || !(c->state & MASK_EVALUATE)) return DFMI_OK;
    if (native_evaluate(c, 1, 0)) {
        c->dirty = 0;
        return DFMI_OK;
    }
    int status = c->state & (EventMode | ContinuousTimeMode)
                     ? bridge_derivatives(c->py, c->time, c->L.real + c->L.dx_offset, c->L.nx,
                                          c->L.event_indicators, c->L.nz)
                     : bridge_call(c->py, DFMI_EVALUATE_DERIVATIVES, &c->time, 1);
    if (status < DFMI_ERROR) c->dirty = 0; /* the outputs stay stale */
    return dfmi_settle(c, status);
}

/* Derivatives are recomputed only when asked for (or in initialization, where the model
 * initializes itself); an integrator that reads outputs after its last stage already has the
 * derivatives it needs, and outputs never depend on them. */
int dfmi_ensure_values(Instance *c, int derivatives) {
    if (!(c->state & MASK_EVALUATE)) return DFMI_OK;
    if (c->dirty && (derivatives || c->state == InitializationMode)) return dfmi_ensure_evaluated(c);
    if (!c->outputs_dirty) return DFMI_OK;
    if (native_evaluate(c, 0, 1)) {
        c->outputs_dirty = 0;
        return DFMI_OK;
    }
    int status = bridge_call(c->py, DFMI_EVALUATE_OUTPUTS, &c->time, 1);
    if (status < DFMI_ERROR) c->outputs_dirty = 0; /* the derivatives may stay stale */
    return dfmi_settle(c, status);
}

int dfmi_refuse_setting(Instance *c, const char *function, size_t vr) {
    dfmi_fail(c, "%s: the variable with value reference %zu cannot be set in state '%s'", function, vr,
              dfmi_state_name(c, c->state));
    return 0;
}

int dfmi_is_int(const Instance *c, size_t vr, int boolean) {
    return vr >= c->L.n_real && vr - c->L.n_real < c->L.n_int && !(c->L.flags[vr] & IS_BOOLEAN) == !boolean;
}

int dfmi_string_index(const Instance *c, size_t vr, size_t *index) {
    size_t first = c->L.n_real + c->L.n_int;
    if (vr < first || vr - first >= c->L.n_str) return 0;
    *index = vr - first;
    return 1;
}

int dfmi_get_string(Instance *c, const char *function, size_t vr, const char **value) {
    size_t index;
    if (!dfmi_string_index(c, vr, &index))
        return dfmi_fail(c, "%s: %zu is not the value reference of a String", function, vr);
    /* the bridge keeps each returned string alive until the next call for the same index */
    return dfmi_settle(c, bridge_get_string(c->py, index, value));
}

int dfmi_set_string(Instance *c, const char *function, size_t vr, const char *value) {
    size_t index;
    if (!dfmi_string_index(c, vr, &index))
        return dfmi_fail(c, "%s: %zu is not the value reference of a String", function, vr);
    if (!(dfmi_setter_bit(c) & (SET_INSTANTIATED | SET_INITIALIZATION)))
        return dfmi_fail(c, "%s: string parameters cannot be set in state '%s'", function,
                         dfmi_state_name(c, c->state));
    int status = bridge_set_string(c->py, index, value ? value : "");
    if (status < DFMI_ERROR) dfmi_values_changed(c);
    return dfmi_settle(c, status);
}

/* ---------------------------------------------------------------------------------------- */
/* FMU state                                                                                 */

int dfmi_get_fmu_state(Instance *c, const char *function, void **state) {
    if (!state) return dfmi_fail(c, "%s: NULL argument", function);
    SavedState *saved = *state;
    if (saved && saved->magic == STATE_MAGIC) { /* the importer may hand back an old state to reuse */
        bridge_free_state(saved->py);
    } else {
        saved = calloc(1, sizeof *saved);
        if (!saved) return dfmi_fail(c, "%s: out of memory", function);
    }
    saved->magic = STATE_MAGIC;
    saved->time = c->time;
    saved->last_successful_time = c->last_successful_time;
    saved->state = c->state;
    saved->start_time = c->start_time;
    saved->stop_time = c->stop_time;
    saved->tolerance = c->tolerance;
    saved->stop_defined = c->stop_defined;
    saved->tolerance_defined = c->tolerance_defined;
    saved->clocks_active = c->clocks_active;
    int status = bridge_get_state(c->py, &saved->py);
    if (status >= DFMI_ERROR) {
        free(saved);
        *state = NULL;
        return dfmi_settle(c, status);
    }
    *state = saved;
    return DFMI_OK;
}

static SavedState *as_saved(void *state) {
    SavedState *saved = state;
    return saved && saved->magic == STATE_MAGIC ? saved : NULL;
}

/* Whether an instance of c's interface can be in `state` (one state bit; 0: an older runtime's
 * state, which does not say): a state got from an instance of the other interface, or read from
 * damaged bytes, would leave c where none of its calls leads out. */
static int state_of_interface(const Instance *c, int state) {
    int common = Instantiated | InitializationMode | Terminated | Error;
    int own = c->interface == DFMI_MODEL_EXCHANGE ? EventMode | ContinuousTimeMode
              : c->interface == DFMI_CO_SIMULATION ? EventMode | StepComplete | StepFailed | StepCanceled
                                                   : ClockActivationMode;
    return state == 0 || ((state & (state - 1)) == 0 && (state & (common | own)) != 0);
}

static const char *interface_name(const Instance *c) {
    return c->interface == DFMI_MODEL_EXCHANGE ? "Model Exchange"
           : c->interface == DFMI_CO_SIMULATION ? "Co-Simulation"
                                                : "Scheduled Execution";
}

int dfmi_set_fmu_state(Instance *c, const char *function, void *state) {
    SavedState *saved = as_saved(state);
    if (!saved) return dfmi_fail(c, "%s: not an FMU state of this FMU", function);
    if (!state_of_interface(c, saved->state))
        return dfmi_fail(c, "%s: the FMU state was got in state '%s', which a %s instance is never in "
                         "(a state of the other interface's instance)", function, dfmi_state_name(c, saved->state),
                         interface_name(c));
    int status = bridge_set_state(c->py, saved->py);
    if (status < DFMI_ERROR) {
        c->time = saved->time;
        c->last_successful_time = saved->last_successful_time;
        dfmi_values_changed(c);
        /* back before the component ended the simulation: stepping may go on */
        c->terminated_by_model = dfmi_terminated(c);
        if (saved->state) { /* where it was taken: a state taken before fmiXTerminate steps on after it */
            c->state = saved->state;
            c->start_time = saved->start_time;
            c->stop_time = saved->stop_time;
            c->tolerance = saved->tolerance;
            c->stop_defined = saved->stop_defined;
            c->tolerance_defined = saved->tolerance_defined;
            c->clocks_active = saved->clocks_active;
        } else if (c->state & (Error | StepFailed | StepCanceled | Terminated)) {
            /* FMI 2.0, section 2.1.3: after an error (or a failed, cancelled or terminated run) the
             * simulation may go on from a state got before; a state serialized by an older runtime
             * does not say where it was got: the stepping state of the interface */
            int mode = c->interface == DFMI_MODEL_EXCHANGE       ? ContinuousTimeMode
                       : c->interface == DFMI_SCHEDULED_EXECUTION ? ClockActivationMode
                                                                  : StepComplete;
            if (!(mode == StepComplete && c->terminated_by_model)) c->state = mode;
        }
    }
    return dfmi_settle(c, status);
}

int dfmi_free_fmu_state(Instance *c, const char *function, void **state) {
    if (!state || !*state) return DFMI_OK;
    SavedState *saved = as_saved(*state);
    if (!saved) return dfmi_fail(c, "%s: not an FMU state of this FMU", function);
    bridge_free_state(saved->py);
    saved->magic = 0;
    free(saved);
    *state = NULL;
    return DFMI_OK;
}

/* serialized layout: magic, time, last successful time, [the instance's own: state, stop and
 * tolerance defined (int32 each), start, stop, tolerance (double each), active clocks (uint64)],
 * then the bridge's bytes; the bracketed part only after STATE_MAGIC2 (STATE_MAGIC: an older
 * runtime's state, whose state machine position is unknown) */
#define STATE_MAGIC2 0x32666d64u /* "dfm2" */
#define HEADER_SIZE (sizeof(uint32_t) + 2 * sizeof(double))
#define INSTANCE_SIZE (3 * sizeof(int32_t) + 3 * sizeof(double) + sizeof(uint64_t))
#define HEADER2_SIZE (HEADER_SIZE + INSTANCE_SIZE)

static void put_instance(unsigned char *out, const SavedState *saved) {
    int32_t ints[3] = {saved->state, saved->stop_defined, saved->tolerance_defined};
    double doubles[3] = {saved->start_time, saved->stop_time, saved->tolerance};
    memcpy(out, ints, sizeof ints);
    memcpy(out + sizeof ints, doubles, sizeof doubles);
    memcpy(out + sizeof ints + sizeof doubles, &saved->clocks_active, sizeof(uint64_t));
}

static void get_instance(const unsigned char *in, SavedState *saved) {
    int32_t ints[3];
    double doubles[3];
    memcpy(ints, in, sizeof ints);
    memcpy(doubles, in + sizeof ints, sizeof doubles);
    memcpy(&saved->clocks_active, in + sizeof ints + sizeof doubles, sizeof(uint64_t));
    saved->state = ints[0];
    saved->stop_defined = ints[1];
    saved->tolerance_defined = ints[2];
    saved->start_time = doubles[0];
    saved->stop_time = doubles[1];
    saved->tolerance = doubles[2];
}

int dfmi_serialized_size(Instance *c, const char *function, void *state, size_t *size) {
    SavedState *saved = as_saved(state);
    if (!saved || !size) return dfmi_fail(c, "%s: invalid argument", function);
    const char *bytes;
    size_t n;
    int status = bridge_serialize_state(c->py, saved->py, &bytes, &n);
    if (status >= DFMI_ERROR) return dfmi_settle(c, status);
    *size = HEADER2_SIZE + n;
    return DFMI_OK;
}

int dfmi_serialize(Instance *c, const char *function, void *state, unsigned char *out, size_t size) {
    SavedState *saved = as_saved(state);
    if (!saved || !out) return dfmi_fail(c, "%s: invalid argument", function);
    const char *bytes;
    size_t n;
    int status = bridge_serialize_state(c->py, saved->py, &bytes, &n);
    if (status >= DFMI_ERROR) return dfmi_settle(c, status);
    if (size < HEADER2_SIZE + n) return dfmi_fail(c, "%s: buffer of %zu bytes is too small", function, size);
    uint32_t magic = STATE_MAGIC2;
    memcpy(out, &magic, sizeof magic);
    memcpy(out + sizeof magic, &saved->time, sizeof(double));
    memcpy(out + sizeof magic + sizeof(double), &saved->last_successful_time, sizeof(double));
    put_instance(out + HEADER_SIZE, saved);
    memcpy(out + HEADER2_SIZE, bytes, n);
    return DFMI_OK;
}

int dfmi_deserialize(Instance *c, const char *function, const unsigned char *bytes, size_t size, void **state) {
    uint32_t magic = 0;
    if (bytes && size >= sizeof magic) memcpy(&magic, bytes, sizeof magic);
    size_t header = magic == STATE_MAGIC2 ? HEADER2_SIZE : HEADER_SIZE;
    if (!bytes || !state || size < header || (magic != STATE_MAGIC && magic != STATE_MAGIC2))
        return dfmi_fail(c, "%s: not a serialized state of a deltafmi FMU", function);
    SavedState *saved = calloc(1, sizeof *saved);
    if (!saved) return dfmi_fail(c, "%s: out of memory", function);
    saved->magic = STATE_MAGIC;
    memcpy(&saved->time, bytes + sizeof magic, sizeof(double));
    memcpy(&saved->last_successful_time, bytes + sizeof magic + sizeof(double), sizeof(double));
    if (magic == STATE_MAGIC2) get_instance(bytes + HEADER_SIZE, saved);
    if (!state_of_interface(c, saved->state)) {
        int got = saved->state;
        free(saved);
        if (got && (got & (got - 1)) == 0 && (got & ANY_INSTANCE))
            return dfmi_fail(c, "%s: the state was serialized in state '%s', which a %s instance is never in "
                             "(a state of the other interface's instance)", function, dfmi_state_name(c, got),
                             interface_name(c));
        return dfmi_fail(c, "%s: not a serialized state of a deltafmi FMU (its header is damaged)", function);
    }
    int status = bridge_deserialize_state(c->py, (const char *)bytes + header, size - header, &saved->py);
    if (status >= DFMI_ERROR) {
        free(saved);
        return dfmi_settle(c, status);
    }
    *state = saved;
    return DFMI_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Model Exchange                                                                            */

/* The event update of a component without states by its compiled kernel (1), or 0: Python's. */
static int native_update(Instance *c, int flags[5], double *next_event_time) {
    const DfmiLayout *L = &c->L;
    double next = NAN;
    if (!L->kernel_update || !*L->kernels_ready || c->state == InitializationMode ||
        L->kernel_update(L->kernel_attributes, c->time, L->real, L->ints, &next) != 0)
        return 0;
    flags[4] = !isnan(next);
    *next_event_time = flags[4] ? next : 0.0;
    bridge_time_moved(c->py, c->time);
    return 1;
}

int dfmi_update_discrete_states(Instance *c, int flags[5], double *next_event_time) {
    for (int i = 0; i < 5; i++) flags[i] = 0;
    *next_event_time = 0.0;
    if (native_update(c, flags, next_event_time)) {
        c->dirty = c->outputs_dirty = 0;
        return DFMI_OK;
    }
    int status = bridge_event_update(c->py, c->time, flags, next_event_time);
    if (status < DFMI_ERROR) c->dirty = c->outputs_dirty = 0;
    return dfmi_settle(c, status);
}

int dfmi_completed_integrator_step(Instance *c, int *enter_event_mode, int *terminate) {
    *enter_event_mode = 0;
    int status = DFMI_OK;
    const DfmiLayout *L = &c->L;
    double drifted = 0.0;
    if (L->watches_drift) {
        if (L->kernel_drift && *L->kernels_ready && c->state != InitializationMode &&
            L->kernel_drift(L->kernel_attributes, c->time, L->real, L->ints, &drifted) == 0)
            *enter_event_mode = drifted != 0.0; /* the compiled check: no Python */
        else
            status = bridge_completed_step(c->py, c->time, enter_event_mode);
    }
    /* the component may have ended the simulation in any evaluation since the last step */
    *terminate = dfmi_terminated(c);
    return dfmi_settle(c, status);
}

int dfmi_set_continuous_states(Instance *c, const char *function, const double *x, size_t nx) {
    if (nx != c->L.nx || (nx && !x)) return dfmi_fail(c, "%s: expected %zu states, got %zu", function, c->L.nx, nx);
    memcpy(c->L.real + c->L.x_offset, x, nx * sizeof(double));
    dfmi_values_changed(c);
    return DFMI_OK;
}

int dfmi_get_derivatives(Instance *c, const char *function, double *dx, size_t nx) {
    if (nx != c->L.nx || (nx && !dx))
        return dfmi_fail(c, "%s: expected %zu derivatives, got %zu", function, c->L.nx, nx);
    if (dfmi_ensure_derivatives(c) >= DFMI_ERROR) return DFMI_ERROR;
    memcpy(dx, c->L.real + c->L.dx_offset, nx * sizeof(double));
    return DFMI_OK;
}

int dfmi_get_event_indicators(Instance *c, const char *function, double *z, size_t nz) {
    if (nz != c->L.nz || (nz && !z))
        return dfmi_fail(c, "%s: expected %zu event indicators, got %zu", function, c->L.nz, nz);
    if (dfmi_ensure_derivatives(c) >= DFMI_ERROR) return DFMI_ERROR;
    memcpy(z, c->L.event_indicators, nz * sizeof(double));
    return DFMI_OK;
}

int dfmi_get_continuous_states(Instance *c, const char *function, double *x, size_t nx) {
    if (nx != c->L.nx || (nx && !x)) return dfmi_fail(c, "%s: expected %zu states, got %zu", function, c->L.nx, nx);
    if (c->state == InitializationMode && dfmi_ensure_derivatives(c) >= DFMI_ERROR) return DFMI_ERROR;
    memcpy(x, c->L.real + c->L.x_offset, nx * sizeof(double));
    return DFMI_OK;
}

int dfmi_get_nominals(Instance *c, const char *function, double *nominals, size_t nx) {
    if (nx != c->L.nx || (nx && !nominals)) return dfmi_fail(c, "%s: expected %zu, got %zu", function, c->L.nx, nx);
    memcpy(nominals, c->L.nominals, nx * sizeof(double));
    return DFMI_OK;
}

/* ---------------------------------------------------------------------------------------- */
/* Co-Simulation                                                                             */

/* ---------------------------------------------------------------------------------------- */
/* Clocks (FMI 3.0)                                                                          */

void dfmi_reset_clocks(Instance *c) {
    c->clocks_active = 0;
    for (size_t i = 0; i < DFMI_MAX_CLOCKS; i++) c->clock_reported[i] = c->clock_activated[i] = NAN;
}

double dfmi_clock_interval(const Instance *c, size_t i) {
    int64_t index = c->L.clock_period_index[i];
    return index >= 0 && (size_t)index < c->L.n_real ? c->L.real[index] : c->L.clock_interval[i];
}

int dfmi_activate_model_partition(Instance *c, const char *function, size_t i, double activation_time) {
    if (!isnan(c->clock_activated[i]) && !(activation_time > c->clock_activated[i]))
        return dfmi_fail(c, "%s: activationTime %.17g of Clock %u is not after its previous activation at %.17g "
                         "(activation times of a Clock must increase strictly)", function, activation_time,
                         (unsigned)(c->L.n_real + c->L.n_int + c->L.n_str + 1 + i), c->clock_activated[i]);
    double args[2] = {(double)i, activation_time}, previous = c->time, next;
    int flags[5] = {0};
    c->time = activation_time; /* the partition is the update at its tick: compiled where it can be */
    int status = native_update(c, flags, &next) ? DFMI_OK
                                                : bridge_call(c->py, DFMI_ACTIVATE_MODEL_PARTITION, args, 2);
    if (status < DFMI_ERROR) {
        c->clock_activated[i] = activation_time;
        c->dirty = c->outputs_dirty = 0; /* the partition evaluated what it computes */
    } else {
        c->time = previous;
    }
    return dfmi_settle(c, status);
}

int dfmi_do_step(Instance *c, const char *function, double t, double h, DfmiStepEvents events) {
    /* an infinite step never ends (a sampled component samples on for ever) */
    if (!(h > 0.0) || isinf(h))
        return dfmi_fail(c, "%s: communicationStepSize must be a finite number > 0, got %g", function, h);
    if (!(fabs(t - c->time) <= 1e-9 * fmax(1.0, fabs(t)))) /* NaN too */
        return dfmi_fail(c, "%s: currentCommunicationPoint %.16g differs from the FMU time %.16g", function, t,
                         c->time);
    const DfmiLayout *L = &c->L;
    if (events == DFMI_EVENTS_INSIDE && L->kernel_step && *L->kernels_ready &&
        L->kernel_step(L->kernel_attributes, t, h, L->real, L->ints) == 0) {
        bridge_time_moved(c->py, t + h); /* the compiled step took it: no Python */
        return DFMI_OK;
    }
    if (dfmi_cs_takes_step(c)) return dfmi_settle(c, dfmi_cs_step(c, t, h, events)); /* CVODE from C */
    double args[3] = {t, h, (double)events};
    return bridge_call(c->py, DFMI_DO_STEP, args, events == DFMI_EVENTS_INSIDE ? 2 : 3);
}
