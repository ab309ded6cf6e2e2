/* What the FMI 2.0 and FMI 3.0 APIs of a deltafmi binary share: one instance, its state machine
 * bits, logging by category, the Python bridge's start, the value buffers with their setter rules,
 * evaluation on demand, FMU state, and the steps of initialization, events and co-simulation.
 *
 * fmi2.c and fmi3.c are thin: they check arguments and states in their standard's terms, map their
 * types and call these functions. Neither includes the other's headers, so each binary exports only
 * its own version's functions. Status codes are the numbers both standards give (0 OK .. 4 fatal). */
#ifndef DELTAFMI_CORE_H
#define DELTAFMI_CORE_H

#include <stddef.h>
#include <stdint.h>

#include "bridge.h"

/* setter rules per scalar, written by deltafmi/runtime/layout.py */
#define SET_INSTANTIATED 1
#define SET_INITIALIZATION 2
#define SET_EVENT 4
#define SET_CONTINUOUS 8
#define IS_BOOLEAN 16
#define IS_ENUMERATION 32 /* an Enumeration: FMI 3.0 reads and sets it as Int64 */
/* Clocks an FMU may have: their activation is one 64-bit mask (layout.MAX_CLOCKS) */
#define DFMI_MAX_CLOCKS 64

enum { DFMI_OK = 0, DFMI_WARNING = 1, DFMI_DISCARD = 2, DFMI_ERROR = 3, DFMI_FATAL = 4 };
enum { DFMI_MODEL_EXCHANGE = 0, DFMI_CO_SIMULATION = 1, DFMI_SCHEDULED_EXECUTION = 2 };

/* One bit per state of either standard. FMI 3.0's Step Mode is FMI 2.0's step complete and its
 * Step Discarded FMI 2.0's step failed: the same rules hold for values and evaluation. */
typedef enum {
    StartAndEnd = 1 << 0, Instantiated = 1 << 1, InitializationMode = 1 << 2, EventMode = 1 << 3,
    ContinuousTimeMode = 1 << 4, StepComplete = 1 << 5, StepInProgress = 1 << 6,
    StepFailed = 1 << 7, StepCanceled = 1 << 8, Terminated = 1 << 9, Error = 1 << 10, Fatal = 1 << 11,
    ConfigurationMode = 1 << 12, ClockActivationMode = 1 << 13 /* FMI 3.0 Scheduled Execution */
} ModelState;
#define StepMode StepComplete
#define StepDiscarded StepFailed

#define ANY_INSTANCE (Instantiated | InitializationMode | EventMode | ContinuousTimeMode | StepComplete | \
                      StepFailed | StepCanceled | Terminated | Error | ConfigurationMode | ClockActivationMode)

typedef struct Instance Instance;
/* Hand one message to the host's logger (each API knows its logger's signature). */
typedef void (*DfmiEmitFn)(const Instance *c, int status, const char *category, const char *message);

struct Instance {
    char *name;
    int fmi_version;   /* 2 or 3: the names used in messages */
    int interface;     /* DFMI_MODEL_EXCHANGE or DFMI_CO_SIMULATION */
    DfmiEmitFn emit;
    void *host_env;          /* the host's environment pointer for its logger */
    void (*host_logger)(void); /* the host's logger, cast back by emit */
    unsigned log_mask; /* enabled log categories: bit i is the i-th of dfmi_category_names */
    int state;
    double time, start_time, stop_time, tolerance;
    int stop_defined, tolerance_defined;
    double last_successful_time;
    int terminated_by_model;
    int dirty;         /* inputs, states or time changed: derivatives and indicators are stale */
    int outputs_dirty; /* outputs are stale (a solver asking for derivatives does not need them) */
    int event_mode_used, early_return_allowed; /* FMI 3.0 Co-Simulation */
    /* FMI 3.0 Clocks (L.n_clocks <= DFMI_MAX_CLOCKS): bit i set while input Clock i is active (from fmi3SetClock
     * in Event Mode to fmi3UpdateDiscreteStates); the interval last reported per Clock by
     * fmi3GetIntervalDecimal (NaN: none yet); Scheduled Execution: the last activation time per Clock */
    uint64_t clocks_active;
    double clock_reported[DFMI_MAX_CLOCKS];
    double clock_activated[DFMI_MAX_CLOCKS];
    DfmiLayout L;
    void *py;
};

/* ---- logging ---- */
#define DFMI_ALL_CATEGORIES 0x3fu
#define DFMI_STATUS_CATEGORIES (1u << 3 | 1u << 4 | 1u << 5)
void dfmi_logf(Instance *c, int status, const char *category, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
/* An error message (always sent), the instance to the error state; returns DFMI_ERROR. */
int dfmi_fail(Instance *c, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
/* fmiXSetDebugLogging, the same in both standards. */
int dfmi_set_debug_logging(Instance *c, const char *function, int logging_on, size_t n, const char *const names[]);
const char *dfmi_state_name(const Instance *c, int state);
/* dfmi_allowed's refusal: an error naming `function` and the state (none without an instance), the
 * instance to the error state; returns 0. */
int dfmi_refuse(Instance *c, const char *function);
/* Whether `function` may be called in the instance's state; otherwise an error, state Error.
 * Inline (as the value helpers below): every FMI call passes here. */
static inline int dfmi_allowed(Instance *c, const char *function, int mask) {
    return c && (c->state & mask) ? 1 : dfmi_refuse(c, function);
}
/* A bridge call's status: errors move the instance to the error state. */
int dfmi_settle(Instance *c, int status);

/* ---- life cycle ---- */
/* A new instance (not yet connected to its model); NULL when out of memory. */
Instance *dfmi_new_instance(const char *name, int fmi_version, int interface, DfmiEmitFn emit, void *host_env,
                            void (*host_logger)(void), int logging_on);
/* <fmu>/resources found from this binary's location (binaries/<platform>/<id>.so). */
char *dfmi_default_resources(void);
/* Start Python and the model's instance from `resources` (a directory, no trailing slash);
 * 0 on success, else -1 (logged). */
int dfmi_connect(Instance *c, const char *resources, const char *token);
void dfmi_free_instance(Instance *c);
int dfmi_enter_initialization(Instance *c);
int dfmi_exit_initialization(Instance *c, int next_state);
int dfmi_terminate(Instance *c);
int dfmi_reset(Instance *c);

/* ---- values ---- */
int dfmi_ensure_evaluated(Instance *c);
int dfmi_ensure_derivatives(Instance *c);
/* Up to date for getters: outputs, and derivatives when asked for (`derivatives`). */
int dfmi_ensure_values(Instance *c, int derivatives);
/* Whether a derivative is among the scalars [first, first + n). */
static inline int dfmi_is_derivative(const Instance *c, size_t first, size_t n) {
    return n && first < c->L.dx_offset + c->L.nx && first + n > c->L.dx_offset;
}
/* The setter rule bit of the instance's state (0: nothing may be set). */
static inline int dfmi_setter_bit(const Instance *c) {
    switch (c->state) {
    case Instantiated: return SET_INSTANTIATED;
    case InitializationMode: return SET_INITIALIZATION;
    case EventMode: case StepComplete: case ClockActivationMode: return SET_EVENT;
    case ContinuousTimeMode: return SET_CONTINUOUS;
    default: return 0;
    }
}
/* dfmi_check_settable's refusal: an error naming `function`, vr and the state; returns 0. */
int dfmi_refuse_setting(Instance *c, const char *function, size_t vr);
/* Whether scalar vr may be set in a state of setter rule bit `bit` (dfmi_setter_bit, taken once by
 * a setter for all its scalars); else logs and fails. */
static inline int dfmi_settable(Instance *c, const char *function, size_t vr, int bit) {
    return (c->L.flags[vr] & bit) ? 1 : dfmi_refuse_setting(c, function, vr);
}
/* Whether scalar vr may be set now (its flags against the state); else logs and fails. */
static inline int dfmi_check_settable(Instance *c, const char *function, size_t vr) {
    return dfmi_settable(c, function, vr, dfmi_setter_bit(c));
}
/* Whether vr is a scalar of the int buffer of the kind asked for (boolean or not). */
int dfmi_is_int(const Instance *c, size_t vr, int boolean);
int dfmi_string_index(const Instance *c, size_t vr, size_t *index);
int dfmi_get_string(Instance *c, const char *function, size_t vr, const char **value);
int dfmi_set_string(Instance *c, const char *function, size_t vr, const char *value);
static inline void dfmi_values_changed(Instance *c) { c->dirty = c->outputs_dirty = 1; }

/* ---- FMU state ---- */
int dfmi_get_fmu_state(Instance *c, const char *function, void **state);
int dfmi_set_fmu_state(Instance *c, const char *function, void *state);
int dfmi_free_fmu_state(Instance *c, const char *function, void **state);
int dfmi_serialized_size(Instance *c, const char *function, void *state, size_t *size);
int dfmi_serialize(Instance *c, const char *function, void *state, unsigned char *out, size_t size);
int dfmi_deserialize(Instance *c, const char *function, const unsigned char *bytes, size_t size, void **state);

/* ---- Model Exchange ---- */
/* One discrete update: flags = discrete states need update, terminate, nominals changed, values
 * changed, next event time defined. */
int dfmi_update_discrete_states(Instance *c, int flags[5], double *next_event_time);
int dfmi_completed_integrator_step(Instance *c, int *enter_event_mode, int *terminate);
int dfmi_set_continuous_states(Instance *c, const char *function, const double *x, size_t nx);
int dfmi_get_derivatives(Instance *c, const char *function, double *dx, size_t nx);
int dfmi_get_event_indicators(Instance *c, const char *function, double *z, size_t nz);
int dfmi_get_continuous_states(Instance *c, const char *function, double *x, size_t nx);
int dfmi_get_nominals(Instance *c, const char *function, double *nominals, size_t nx);

/* ---- Clocks (FMI 3.0) ---- */
/* Forget the Clocks' history (a new instance, fmi3Reset). */
void dfmi_reset_clocks(Instance *c);
/* The current interval of Clock i (0-based): its period Parameter's value, or its constant. */
double dfmi_clock_interval(const Instance *c, size_t i);
/* Scheduled Execution: the partition of Clock i at activation_time (strictly after the last one). */
int dfmi_activate_model_partition(Instance *c, const char *function, size_t i, double activation_time);

/* ---- Co-Simulation ---- */
/* Whether the component ended the simulation (Component.terminate_simulation). */
static inline int dfmi_terminated(const Instance *c) { return c->L.control && c->L.control[0] != 0.0; }
/* What a Co-Simulation step does at a state or time event in (t, t + h] (the same numbers as
 * runtime/instance.py's EVENTS_*, FmuInstance.do_step's `events`):
 *   DFMI_EVENTS_INSIDE        handles each event inside the step and reaches t + h (FMI 2.0;
 *                             FMI 3.0 without eventModeUsed);
 *   DFMI_EVENTS_EARLY_RETURN  stops at the first event and leaves it pending (FMI 3.0 with
 *                             eventModeUsed and earlyReturnAllowed);
 *   DFMI_EVENTS_AT_STEP_END   reaches t + h, handling the events before it inside and reporting
 *                             them there, and leaves one at t + h itself pending (FMI 3.0 with
 *                             eventModeUsed only: the FMU may not return early, and an event
 *                             inside the step has passed).
 * The step reports through the layout's control array (whoever runs the loop, Python or C):
 *   control[0] nonzero: the component ended the simulation, at control[1];
 *   control[2] = 1: the step left an event pending at the time it reached, control[1]; the
 *                   importer's Event Mode handles it and the next step restarts the solver;
 *                   0 otherwise (cleared at each step's start);
 *   control[1] NaN: the step reached t + h.
 * In event mode (EARLY_RETURN or AT_STEP_END) a clock-driven component's events are its Clocks'
 * ticks, activated by the importer in Event Mode: its steps only move time. */
typedef enum { DFMI_EVENTS_INSIDE = 0, DFMI_EVENTS_EARLY_RETURN = 1, DFMI_EVENTS_AT_STEP_END = 2 } DfmiStepEvents;

/* The model's step from t to t + h (checked against the instance's time), treating events as
 * `events` says. Returns the bridge's status; the caller sets time and state. */
int dfmi_do_step(Instance *c, const char *function, double t, double h, DfmiStepEvents events);

#endif
