/* The interface between the FMI loader and the Python bridge, two parts of one binary.
 *
 * The loader (core.c with fmi2.c or fmi3.c) implements the FMI functions and never touches
 * Python. Once libpython is in the process it starts the bridge (bridge.c), which reaches Python
 * only through the API table bound at run time (pyapi.h). Status codes are FMI status values (0 OK .. 3 error). */
#ifndef DELTAFMI_BRIDGE_H
#define DELTAFMI_BRIDGE_H

#include <stddef.h>
#include <stdint.h>

typedef void (*DfmiLogFn)(void *env, int status, const char *category, const char *message);
typedef int (*DfmiKernelFn)(const void *attributes, double time, double *real, int *ints, double *indicators);
typedef int (*DfmiStepFn)(void *attributes, double time, double h, double *real, int *ints);
typedef int (*DfmiUpdateFn)(void *attributes, double time, double *real, int *ints, double *next_event_time);

/* A Co-Simulation step taken in C (cs_step.c): what a step reads and writes between steps, and
 * the solver, shared field for field with the Python instance (deltafmi/runtime/cs_native.py
 * CsShared), which takes the steps the C layer leaves to it. */
typedef struct {
    void *mem;         /* CVODE's memory (NULL: no solver yet; Python makes it, DFMI_CS_PREPARE) */
    void *y;           /* CVODE's state vector (N_Vector) ... */
    double *x;         /* ... and its data (nx) */
    int (*cvode)(void *mem, double tout, void *y, double *tret, int itask);
    int (*set_stop_time)(void *mem, double tstop);
    int (*reinit)(void *mem, double t0, void *y0);
    int *quiet;        /* [0] nonzero: the solver's errors are kept, not logged (a retry follows) */
    const double *atol; /* nx */
    double rtol, jump_tolerance;
    double solver_t;   /* the time CVODE returned last (or restarted at) */
    double time;       /* the instance's time */
    double start_time, grid_step; /* the communication grid */
    double next_time_event;       /* NaN: none */
    double event_time;            /* where the solver last restarted at an event (NaN: none) */
    int restart_solver, jump_kept, after_valid, inputs_valid;
    double *after;     /* nx: the derivatives at the end of the last step (valid: after_valid) */
    double *inputs;    /* n_real_inputs + n_int_inputs: the inputs the last step saw (inputs_valid) */
    const int64_t *real_inputs, *int_inputs; /* their indices in the real and int buffers */
    int64_t n_real_inputs, n_int_inputs;
    int enabled;
    double *pre_indicators; /* nz: the event indicators where the last step or event left them,
                             * with the inputs of then (valid: pre_indicators_valid) */
    int pre_indicators_valid;
    int handled_reported; /* FMI 3.0, eventModeUsed without early return: the step handled events
                           * inside and reported them at its end; the importer's Event Mode that
                           * follows restarts the solver only where it changes something */
} DfmiCs;

/* Buffers owned by the Python instance and read/written in place by the loader. */
typedef struct {
    double *real;                 size_t n_real;
    int *ints;                    size_t n_int;
    const unsigned char *flags;   /* one per real and int scalar: setter rules, boolean bit */
    size_t n_str;
    size_t nx, x_offset, dx_offset;
    double *event_indicators;     size_t nz;
    const double *nominals;
    int watches_drift;            /* fmi2CompletedIntegratorStep asks the model (else: no event) */
    const double *control;        /* [0] nonzero: the component ended the simulation; [1] the time
                                   * it reached (NaN: the end of the step); [2] (FMI 3.0 event mode
                                   * only) nonzero: the step left an event pending at [1] for the
                                   * importer's Event Mode (the contract: core.h, DfmiStepEvents) */
    /* FMI 3.0 only (trailing fields of native_layout; NULL / 0 from a runtime without them): */
    const uint32_t *sizes3;       /* n_real + n_int + n_str entries: sizes3[v] = element count of the
                                   * FMI 3.0 variable whose value reference is v, 0 where v is not
                                   * the first scalar of a declaration */
    size_t n_clocks;              /* value references: n_total = time, then the clocks, then one
                                   * Float64 variable per event indicator */
    const int64_t *clock_period_index; /* n_clocks: index in `real` of the Clock's period Parameter,
                                        * -1 where the interval is a constant ... */
    const double *clock_interval;      /* ... given here (NaN otherwise) */
    /* The component's kernels compiled to C (deltafmi/builder/codegen/component_kernels.py; NULL:
     * none): derivatives into the derivative scalars, event indicators into theirs, outputs into
     * the outputs, an event update at time of a component without states (its next time event,
     * NaN for none; attributes in the struct), a step from time
     * over h (a component that steps itself: its outputs, and attributes in the struct), from the
     * buffers and the attributes' struct, which holds the model's current attributes while
     * *kernels_ready. 0 on success; else nothing was written (the Python method then runs). */
    DfmiKernelFn kernel_derivatives, kernel_indicators, kernel_outputs;
    DfmiStepFn kernel_step;
    DfmiUpdateFn kernel_update;
    void *kernel_attributes;
    const int *kernels_ready;
    /* The drift check of fmi2CompletedIntegratorStep compiled (NULL: none): writes nonzero to
     * its last argument when the states drifted (a step event), as needs_projection() says. */
    DfmiKernelFn kernel_drift;
    DfmiCs *cs; /* NULL: the Python instance takes every Co-Simulation step */
} DfmiLayout;

typedef enum {
    DFMI_ENTER_INITIALIZATION = 0, /* args: start, stop (NaN: undefined), tolerance (NaN: undefined) */
    DFMI_EXIT_INITIALIZATION,      /* args: none, or 1 (FMI 3.0 Co-Simulation with event mode used) */
    DFMI_EVALUATE,                 /* args: time; derivatives, event indicators and outputs */
    DFMI_DO_STEP,                  /* args: current communication point, step size[, FMI 3.0 event
                                    * mode: DfmiStepEvents EARLY_RETURN or AT_STEP_END (core.h); a
                                    * clock-driven component that steps itself then only moves time] */
    DFMI_TERMINATE,
    DFMI_RESET,
    DFMI_EVALUATE_DERIVATIVES,     /* args: time; derivatives and event indicators only */
    DFMI_EVALUATE_OUTPUTS,         /* args: time; outputs only (everything in initialization) */
    DFMI_ACTIVATE_MODEL_PARTITION, /* args: Clock index (0-based), activation time (Scheduled Execution) */
    DFMI_CS_PREPARE,               /* a step in C needs the solver: none */
    DFMI_CS_EVENT,                 /* a step in C reached an event at the time in DfmiCs: none */
    DFMI_CS_FAILED,                /* CVODE failed in a step in C: flag, time, retry allowed */
    DFMI_N_OPS
} DfmiOp;

/* The bridge's functions (bridge.c, compiled into the same binary as the loader). */

/* Bind the Python API in `python` (RTLD_DEFAULT or a libpython handle) and start (or attach to)
 * the interpreter; python_executable names it for sys.prefix. 0 on success. */
int bridge_start(void *python, const char *python_executable, char *error, size_t error_size);
/* Load the FMU's Python model and create one instance; NULL on failure (logged). fmi_version (2
 * or 3): the standard whose function names the instance's messages use. log_mask: the log
 * categories enabled (bits in the order of core.c's CATEGORY_NAMES). */
void *bridge_instantiate(const char *resources_dir, const char *instance_name, const char *guid,
                         int fmi_version, int fmu_type, unsigned log_mask, DfmiLogFn log, void *log_env,
                         DfmiLayout *layout);
/* Tell the instance which log categories are enabled (fmi2SetDebugLogging). */
int bridge_set_log_mask(void *instance, unsigned log_mask);
void bridge_free_instance(void *instance);
int bridge_call(void *instance, DfmiOp op, const double *args, int nargs);
/* A compiled step moved the instance to `time` without Python: the bridge tells Python before its
 * next call. */
void bridge_time_moved(void *instance, double time);
/* Model Exchange out of initialization: the component's derivatives (nx) and event indicators
 * (nz) at `time`, written into dx and z (the buffers of the layout). */
int bridge_derivatives(void *instance, double time, double *dx, size_t nx, double *z, size_t nz);
/* fmi2NewDiscreteStates: flags = newDiscreteStatesNeeded, terminateSimulation,
 * nominalsChanged, valuesOfContinuousStatesChanged, nextEventTimeDefined. */
int bridge_event_update(void *instance, double time, int flags[5], double *next_event_time);
/* fmi2CompletedIntegratorStep (only when the layout watches drift): may request event mode. */
int bridge_completed_step(void *instance, double time, int *enter_event_mode);
/* Returned string stays valid until the next get_string on this instance. */
int bridge_get_string(void *instance, size_t index, const char **value);
int bridge_set_string(void *instance, size_t index, const char *value);
int bridge_get_state(void *instance, void **state);       /* *state: new opaque snapshot */
int bridge_set_state(void *instance, void *state);
void bridge_free_state(void *state);
/* Serialize into a bridge-owned buffer valid until the next call on this instance. */
int bridge_serialize_state(void *instance, void *state, const char **bytes, size_t *size);
int bridge_deserialize_state(void *instance, const char *bytes, size_t size, void **state);
/* A directional derivative at `time`: out[i] = sum_j d unknown_i / d known_j seed[j]; function:
 * the FMI function called, for messages. */
int bridge_directional_derivative(void *instance, const char *function, double time, const unsigned int *unknowns,
                                  size_t n_unknown, const unsigned int *knowns, size_t n_known, const double *seed,
                                  double *out);

#endif
