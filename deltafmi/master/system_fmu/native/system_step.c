/* The doStep of a scenario exported as one FMU, taken in C: the master's fixed steps that make up
 * the communication step, run by its C loop (deltafmi/master/stepping/native/fixed_step.c, reached
 * through the address in SystemStep.run) straight from the FMU's C layer, which calls
 * dfmi_system_step as a compiled step (the layout's kernel_step) while Python armed it. It takes
 * the step only when the Python path would have nothing else to do: the step starts where the
 * master stands, spans whole master steps, an input the importer changed is set on its unit here
 * (one scalar, by the unit's FMI setter, as Python sets it), and the C loop runs every step
 * through with finite values and no message from a unit. Otherwise it
 * takes nothing (returns nonzero), or, once the C loop ran, leaves what it returned in the struct
 * (pending) for Python's doStep to finish exactly as the master's own loop does after a C run.
 * Plain C, no Python. */
#include <math.h>
#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define EXPORT __attribute__((visibility("default")))

typedef int (*FixedSteps)(void *plan, long k_begin, long k_end, double *rows, long max_rows, long *k_done,
                          long *n_rows);

enum { RAN = 0, ROWS_FULL = 5 }; /* fixed_step.c: why a run stopped */
/* how an input reaches its unit: the FMI setter called with one value */
enum { SET_PYTHON = 0, SET_REAL2 = 1, SET_INT2 = 2, SET_REAL3 = 3, SET_INT3 = 4, SET_BOOL3 = 5 };
typedef int (*SetReal2)(void *, const unsigned *, size_t, const double *);
typedef int (*SetInt2)(void *, const unsigned *, size_t, const int *);
typedef int (*SetReal3)(void *, const unsigned *, size_t, const double *, size_t);
typedef int (*SetInt3)(void *, const unsigned *, size_t, const int32_t *, size_t);
typedef int (*SetBool3)(void *, const unsigned *, size_t, const bool *, size_t);

/* Laid out field for field by deltafmi/master/system_fmu/direct.py (_SystemStep). */
typedef struct {
    FixedSteps run;          /* deltafmi_fixed_steps of the loaded C loop */
    void *plan;              /* its Plan for this master run */
    double *rows;            /* the C loop's row block: capacity rows of width + 1 */
    long capacity, width;
    long k;                  /* in/out: the master's steps taken */
    long n_steps;            /* the grid's steps */
    double start, h, stop;
    int check_finite;
    /* out, pending nonzero: a C run Python finishes (from step run_k, as the loop returned:
     * why, done, n_rows), then the master's steps up to k_end */
    int pending, why;
    long run_k, done, n_rows, k_end;
    double recorded_until;   /* out: the time of the last row recorded (NaN: none yet) */
    /* the FMU's inputs: index in its real (or, is_int, int) buffer, the value its unit has (in/out),
     * and how a new value reaches the unit: the setter (kind SET_*, SET_PYTHON: Python's step
     * sets it) of the unit's component, value reference vr */
    long n_inputs;
    const int64_t *input_index;
    const int32_t *input_is_int;
    double *applied;
    const int32_t *set_kind;
    void *const *setter;
    void *const *unit;
    const uint32_t *vr;
    /* the FMU's outputs: the bus slot read (a double, or an int where source_int) into the FMU's
     * real (or int, target_int) buffer at target */
    long n_outputs;
    const intptr_t *source;
    const int32_t *source_int;
    const int64_t *target;
    const int32_t *target_int;
    /* the values checked finite: the Real bus, and the recorded rows' Real columns */
    const double *real_bus;
    long n_real_bus;
    const int64_t *real_columns;
    long n_real_columns;
    /* the units' messages so far (the master's counter) and as of the last step */
    const int64_t *messages;
    int64_t messages_seen;
} SystemStep;

static void write_outputs(const SystemStep *s, double *real, int *ints) {
    for (long i = 0; i < s->n_outputs; i++) {
        double value = s->source_int[i] ? (double)*(const int *)s->source[i] : *(const double *)s->source[i];
        if (s->target_int[i]) ints[s->target[i]] = (int)value;
        else real[s->target[i]] = value;
    }
}

static int rows_finite(const SystemStep *s, long n_rows) {
    for (long r = 0; r < n_rows; r++) {
        const double *row = s->rows + r * (s->width + 1) + 1;
        for (long i = 0; i < s->n_real_columns; i++)
            if (!isfinite(row[s->real_columns[i]])) return 0;
    }
    return 1;
}

static int bus_finite(const SystemStep *s) {
    for (long i = 0; i < s->n_real_bus; i++)
        if (!isfinite(s->real_bus[i])) return 0;
    return 1;
}

/* A new value of input i to its unit, as Python's Unit.set_value sets it: 0 when set (else the
 * Python step sets it and says what failed). */
static int set_input(SystemStep *s, long i, double value) {
    const unsigned *vr = &s->vr[i];
    void *unit = s->unit[i];
    int status, as_int = (int)value;
    int32_t as_int32 = (int32_t)value;
    bool as_bool = value != 0.0;
    switch (s->set_kind[i]) {
    case SET_REAL2: status = ((SetReal2)s->setter[i])(unit, vr, 1, &value); break;
    case SET_INT2: status = ((SetInt2)s->setter[i])(unit, vr, 1, &as_int); break;
    case SET_REAL3: status = ((SetReal3)s->setter[i])(unit, vr, 1, &value, 1); break;
    case SET_INT3: status = ((SetInt3)s->setter[i])(unit, vr, 1, &as_int32, 1); break;
    case SET_BOOL3: status = ((SetBool3)s->setter[i])(unit, vr, 1, &as_bool, 1); break;
    default: return 1;
    }
    if (status > 1) return 1; /* above fmi2Warning */
    s->applied[i] = value;
    return 0;
}

/* The outputs from the buses into the FMU's buffers (the layout's kernel_outputs). */
EXPORT int dfmi_system_outputs(const void *attributes, double time, double *real, int *ints, double *indicators) {
    (void)time, (void)indicators;
    write_outputs(attributes, real, ints);
    return 0;
}

/* The FMU's doStep from t over h (the layout's kernel_step): 0 when taken here, else Python's doStep
 * takes it (from the start, or finishing the pending C run). */
EXPORT int dfmi_system_step(void *attributes, double t, double h, double *real, int *ints) {
    SystemStep *s = attributes;
    if (s->pending) return 1;
    long k = s->k;
    double at = k < s->n_steps ? s->start + (double)k * s->h : s->stop;
    if (fabs(t - at) > 1e-9 * fmax(1.0, fabs(t))) return 1;
    double n = nearbyint(h / s->h); /* Python's round(): half to even in the default rounding mode */
    if (n < 1.0 || fabs(n * s->h - h) > 1e-9 * s->h) return 1;
    for (long i = 0; i < s->n_inputs; i++) {
        double value = s->input_is_int[i] ? (double)ints[s->input_index[i]] : real[s->input_index[i]];
        if (!(value == s->applied[i]) && set_input(s, i, value) != 0) return 1; /* Python sets it */
    }
    long k_end = k + (long)n, target = k_end < s->n_steps ? k_end : s->n_steps;
    while (k < target) {
        long done = k, n_rows = 0;
        int why = s->run(s->plan, k, target, s->rows, s->capacity, &done, &n_rows);
        if (n_rows) s->recorded_until = s->rows[(n_rows - 1) * (s->width + 1)];
        int clean = (why == RAN || why == ROWS_FULL) && done > k;
        if (!clean || (s->check_finite && (!rows_finite(s, n_rows) || !bus_finite(s))) ||
            (done == target && *s->messages != s->messages_seen)) {
            s->pending = 1, s->why = why, s->run_k = k, s->done = done, s->n_rows = n_rows, s->k_end = k_end;
            s->k = k;
            return 1;
        }
        k = done;
    }
    s->k = k;
    write_outputs(s, real, ints);
    return 0;
}
