/* The master's fixed-step communication loop in C: the same FMI 2.0 calls, in the same order and
 * with the same arguments, as the Python loop of deltafmi/master/master.py makes through fmpy's
 * ctypes bindings (fmi2Set/Get<Type> of each unit's batched value references, fmi2DoStep,
 * and for a Model Exchange unit on a fixed-step Runge-Kutta method its stages, fmi2SetTime,
 * fmi2SetContinuousStates and fmi2CompletedIntegratorStep), for a run of steps at once, with
 * the recorded rows gathered into a block. Anything else (a failure, an event, a termination)
 * stops the run and hands back to Python, which carries on exactly where this stopped.
 * FMI 3.0 units (Op.fmi3) make the FMI 3.0 calls instead: fmi3Set/GetFloat64, Int32 and Boolean
 * with nValues (whole arrays, the connected elements scattered to their positions), fmi3DoStep with
 * its outputs (any event, early return or termination hands back), fmi3CompletedIntegratorStep
 * with fmi3Boolean flags; before the fmi3DoStep of a unit with periodic input Clocks, their ticks
 * due at the step's start (CLOCK_TICK: fmi3EnterEventMode, fmi3SetClock, fmi3UpdateDiscreteStates
 * until done, fmi3EnterStepMode; a tick inside the step hands the step back). A paced run
 * (Plan.pace) waits at every communication point for its wall-clock time as
 * deltafmi/master/live/pacing.py's Pacer.wait does (sleep until shortly before, then poll the
 * clock), notes how late it came and writes the pacing measurements to the bus before the row is
 * recorded. Rows may go to a sink while the run goes on (Plan.sink_put: the CSV writer's thread of
 * C, deltafmi/master/results/native/csv_rows.c), every sink_every rows. Plain C, no Python.
 *
 * Parallel units (Plan.threads > 1): a run of consecutive DO_STEP operations of one group
 * (Op.group > 0: FMI 2.0 Co-Simulation units of one step that take no input from one another, whose
 * fmi2DoStep runs Python at most at events) is stepped by the plan's threads at once, the calling
 * thread among them; a calling thread that holds Python's lock (Plan.gil_released 0) lets go of it
 * meanwhile (PyEval_SaveThread), so that an FMU that takes it (at an event, or its logger calling
 * back) gets it instead of waiting for a thread that waits for it. A process without Python's
 * symbols steps the group one at a time. Each step has the arguments it has in turn; the statuses
 * are looked at in the group's order afterwards, so the first failing unit in stepping order is
 * the one reported (the others of its group have taken the step too).
 */
/* the oldest versions of what moved into libc in glibc 2.34 (dlsym, the pthreads), so that the
 * library loads on old systems and a wheel's prebuilt copy passes as manylinux2014 */
#if defined(__x86_64__) && defined(__linux__)
__asm__(".symver dlsym,dlsym@GLIBC_2.2.5");
__asm__(".symver pthread_create,pthread_create@GLIBC_2.2.5");
__asm__(".symver pthread_join,pthread_join@GLIBC_2.2.5");
#endif
#include <dlfcn.h>
#include <pthread.h>
#include <stdbool.h>
#include <math.h>
#include <stddef.h>
#include <stdint.h>
#include <stdlib.h>
#include <time.h>
#include <errno.h>
#include <limits.h>

typedef unsigned int fmi2ValueReference;
typedef int (*SetReal)(void *, const fmi2ValueReference *, size_t, const double *);
typedef int (*GetReal)(void *, const fmi2ValueReference *, size_t, double *);
typedef int (*SetInt)(void *, const fmi2ValueReference *, size_t, const int *);
typedef int (*GetInt)(void *, const fmi2ValueReference *, size_t, int *);
typedef int (*DoStep)(void *, double, double, int);
typedef int (*SetTime)(void *, double);
typedef int (*SetStates)(void *, const double *, size_t);
typedef int (*Completed)(void *, int, int *, int *);
typedef int (*GetIndicators)(void *, double *, size_t);
/* FMI 3.0 */
typedef int (*SetReal3)(void *, const fmi2ValueReference *, size_t, const double *, size_t);
typedef int (*GetReal3)(void *, const fmi2ValueReference *, size_t, double *, size_t);
typedef int (*SetInt3)(void *, const fmi2ValueReference *, size_t, const int *, size_t);
typedef int (*GetInt3)(void *, const fmi2ValueReference *, size_t, int *, size_t);
typedef int (*DoStep3)(void *, double, double, bool, bool *, bool *, bool *, double *);
typedef int (*Completed3)(void *, bool, bool *, bool *);
typedef int (*SetBool3)(void *, const fmi2ValueReference *, size_t, const bool *, size_t);
typedef int (*GetBool3)(void *, const fmi2ValueReference *, size_t, bool *, size_t);
typedef int (*ErkSteps)(const void *plan, double t, double h, int steps, double *x);
typedef int (*Instance3)(void *);
typedef int (*SetClock3)(void *, const fmi2ValueReference *, size_t, const bool *);
typedef int (*UpdateDiscrete3)(void *, bool *, bool *, bool *, bool *, bool *, double *);

enum { FMI2_WARNING = 1 };
/* operations */
enum { SET_REAL = 0, GET_REAL = 1, SET_INT = 2, GET_INT = 3, DO_STEP = 4, ME_STEP = 5,
       SET_BOOL3 = 6, GET_BOOL3 = 7, /* FMI 3.0 Booleans (one byte) to and from the int bus */
       CLOCK_TICK = 8 /* FMI 3.0 Co-Simulation: the input Clocks due at the step's start */ };
/* why a run stopped */
enum { RAN = 0, FAILED = 1, STEP_EVENT = 2, TERMINATED = 3, RK_FAILED = 4, ROWS_FULL = 5, STATE_EVENT = 6,
       STEP_RETURNED = 7, /* fmi3DoStep: an event, an early return or a termination (Op.flags) */
       CLOCK_INSIDE = 8, /* CLOCK_TICK: a tick inside the step; nothing done, Python takes the step */
       UNSETTLED = 9, /* CLOCK_TICK: fmi3UpdateDiscreteStates still asked for more after MAX_EVENT_ITERATIONS */
       BEHIND = 10, /* paced, Pace.stop_behind: a point came more than a paced step late (its row recorded) */
       LIVE = 11 /* paced, Pace.sample: the live sources need Python at the point reached (its row not recorded) */ };
enum { MAX_EVENT_ITERATIONS = 1000 }; /* fmi3_units._MAX_EVENT_ITERATIONS */
/* Op.flags after fmi3DoStep */
enum { EVENT_HANDLING_NEEDED = 1, TERMINATE_SIMULATION = 2, EARLY_RETURN = 4 };

typedef struct {
    int kind;
    int multiple;            /* runs at the steps k with k % multiple == 0 */
    void *function;          /* fmi2Set/Get<Type> or fmi2DoStep */
    void *component;
    const fmi2ValueReference *vrs;
    size_t n;
    void *values;            /* SET_*: the gathered values; GET_*: the bus slice read into */
    const void *bus;         /* SET_*: the bus gathered from; GET_BOOL3: the bus slice the values go to */
    const intptr_t *index;
    const double *factor;    /* SET_REAL: NULL when untransformed */
    const double *offset;
    int no_prior_state;
    /* ME_STEP */
    ErkSteps erk;
    const void *erk_plan;
    int *erk_current;        /* the plan's flag: the FMU holds the start time and states already */
    int holds_end;           /* 1 after this op set the step's end time and states (valid within a run) */
    double *x;
    size_t nx;
    double *t;               /* the solver's time */
    double max_step;
    SetTime set_time;
    SetStates set_states;
    Completed completed;     /* NULL: the FMU needs no fmi2CompletedIntegratorStep */
    /* ME_STEP with event indicators: compared after every Runge-Kutta step with the last ones */
    size_t nz;
    GetIndicators get_indicators;
    double *z;               /* nz: the indicators now */
    double *z_last;          /* nz: at the last step's end, valid when *z_valid */
    int *z_valid;
    double *x0;              /* nx: the states at the start of the step that crossed */
    /* FMI 3.0 */
    int fmi3;
    const intptr_t *positions; /* SET_*: where each gathered bus value goes in values */
    size_t n_index;          /* SET_*: the bus values gathered (n: the value references) */
    size_t n_values;         /* SET_*, GET_*: nValues, every element of the variables */
    int flags;               /* DO_STEP out: EVENT_HANDLING_NEEDED | TERMINATE_SIMULATION | EARLY_RETURN */
    int step_status;         /* DO_STEP out: the status of fmi3DoStep */
    double last_time;        /* DO_STEP out: lastSuccessfulTime */
    /* CLOCK_TICK: the n Clocks' value references in vrs, their ticks first + count * interval
     * (count advanced here: the arrays are the master's, see clocks.UnitClocks), fmi3SetClock in
     * function, the other calls below; due_vrs and on: room for n */
    const double *clock_first;
    int64_t *clock_count;
    const double *clock_interval;
    int64_t *clock_activated;
    fmi2ValueReference *due_vrs;
    bool *on;
    Instance3 enter_event_mode;
    UpdateDiscrete3 update_discrete_states;
    Instance3 enter_step_mode;
    /* parallel units */
    int group;               /* DO_STEP: > 0: stepped at once with the consecutive ops of this group */
    int group_status;        /* out: the status of its fmi2DoStep in the last group step */
} Op;

typedef struct {
    const void *bus;
    int is_int;
    size_t n;
    const intptr_t *index;
    const intptr_t *columns;
} RowPart;

/* Units that exchange no values with the others (a connected component of the plan's data flow):
 * its ops in stepping order, and the recorded values its GET ops write (see "blocks of steps") */
typedef struct {
    const long *ops;
    size_t n_ops;
    const RowPart *parts;
    size_t n_parts;
} Component;

/* A paced run's clock (Pacer's): point t is due at wall0 + (t - t0) / speed on CLOCK_MONOTONIC
 * (Python's time.perf_counter on Linux) */
typedef struct {
    double t0, wall0, speed, spin, period;
    double released;         /* in/out: wall time the last point was released */
    double *lateness;        /* out: how late each point came, from lateness[*count] on ... */
    long *count;
    long capacity;           /* ... while *count < capacity */
    double *late, *busy, *behind; /* NULL or the bus slots of the measurements (live.run._Measurements) */
    int stop_behind;         /* stop (BEHIND) after a point later than a whole paced step */
    double last_busy;        /* out: wall seconds from the release of the point before the last to its wait */
    double cpu, wall;        /* out, added up: this thread's CPU time and the wall time in paced runs of the loop */
    double polled;           /* out, added up: wall time spent polling the clock before deadlines */
    /* rows streamed (stream 1): the run's rows go round `rows` as a ring that another thread of the
     * caller empties while the run goes on (NativeLoop.run_streamed), so that no hand-back to
     * Python comes between two paced points; it asks the run to stop with stop_request */
    int stream;
    int stop_request;        /* in: stop after the point being released (a stop signal) */
    long published;          /* out: rows of this run written into the ring (release: the rows first) */
    long taken;              /* in: rows of this run the other thread has taken out of the ring */
    double lead;             /* wall seconds a point may be released before its deadline (pace_to) */
    /* NULL, or the live sources read at every point once it is released, before its row
     * (deltafmi/master/live/native/udp_reader.c); returns 1 when Python must sample them there */
    int (*sample)(void *context, double t);
    void *sample_context;
} Pace;

typedef struct {
    Op *ops;
    size_t n_ops;
    RowPart *parts;
    size_t n_parts;
    size_t width;            /* recorded columns after time */
    double start, h, stop;
    long n_steps, last, every;
    /* out: where and why the last run stopped */
    long op;                 /* the operation that stopped it */
    int status;              /* its fmi2Status */
    int call;                /* ME_STEP FAILED: 0 fmi2SetTime, 1 fmi2SetContinuousStates,
                              * 2 fmi2CompletedIntegratorStep, 3 fmi2GetEventIndicators;
                              * CLOCK_TICK FAILED: 0 fmi3EnterEventMode, 1 fmi3SetClock,
                              * 2 fmi3UpdateDiscreteStates, 3 fmi3EnterStepMode */
    double time;             /* ME_STEP: the time reached */
    double rk_time;          /* RK_FAILED, STATE_EVENT: the time its Runge-Kutta step started from */
    double rk_step;          /* STATE_EVENT: that step's size (the states it started from in op->x0) */
    double *op_seconds;      /* NULL, or per operation: wall seconds spent in it (benchmarks) */
    Pace *pace;              /* NULL: unpaced */
    int threads;             /* threads stepping a group (1: the calling thread only) */
    void *pool;              /* its worker threads, started by the first run that needs them and kept
                              * until deltafmi_fixed_steps_end: a thread that enters Python keeps the
                              * thread state it made there, so the threads are made once per plan */
    int gil_released;        /* called without Python's lock (ctypes.CDLL): nothing to let go of */
    double *step_start;      /* NULL, or a row: the recorded values at the start of each step
                              * (what an event row inside the step shows of the other units) */
    const Component *components; /* n_components > 1: every op belongs to one of them (blocks of steps) */
    size_t n_components;
    const RowPart *fixed_parts; /* with components: the recorded values no op writes */
    size_t n_fixed_parts;
    /* rows handed to a sink as they are recorded (sink_put NULL: the caller takes every row after
     * the run): every sink_every rows of a run, unpaced and not in blocks of steps, go to
     * sink_put(sink, first row, rows), which returns the number of blocks queued so far, and so
     * do the rows of a run that returns RAN or ROWS_FULL after the last of them; with
     * sink_finite only while every value of them is finite (a NaN or an infinity stops the
     * hand-over: the caller looks at the rest) */
    long (*sink_put)(void *sink, const double *rows, long n);
    void *sink;
    long sink_every;
    int sink_finite;
    long sink_rows;          /* out: the rows of the last run handed over, from its first on */
    long sink_queued;        /* out: sink_put's count after the last of them (0: none) */
    double deadline;         /* > 0, unpaced: the run returns (RAN) after the first step that ends past
                              * this CLOCK_MONOTONIC time (looked at every DEADLINE_STEPS steps) */
} Plan;

enum { DEADLINE_STEPS = 4 };

/* The rows [p->sink_rows, written) to the sink; 0 when they were not (a value not finite). */
static int hand_over(Plan *p, const double *rows, long written)
{
    const size_t stride = p->width + 1;
    const double *first = rows + p->sink_rows * (long)stride;
    long n = written - p->sink_rows;
    if (p->sink_finite) {
        double sum = 0.0; /* NaN or infinite when a value is (or the sum overflows: the caller looks) */
        for (size_t i = 0; i < (size_t)n * stride; i++) sum += first[i];
        if (!isfinite(sum)) return 0;
    }
    p->sink_queued = p->sink_put(p->sink, first, n);
    p->sink_rows = written;
    return 1;
}

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* sleep until wall time `until` (CLOCK_MONOTONIC seconds): an absolute deadline, so that the time
 * between reading the clock and going to sleep does not add to the wait */
static void sleep_until(double until)
{
    struct timespec ts;
    ts.tv_sec = (time_t)until;
    ts.tv_nsec = (long)((until - (double)ts.tv_sec) * 1e9);
    if (ts.tv_nsec >= 1000000000L) {
        ts.tv_sec++;
        ts.tv_nsec -= 1000000000L;
    }
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR) {
    }
}

/* Pacer.wait for point t, then the measurements on the bus; returns 1 when it came more than a
 * whole paced step late. A stop signal is looked at between calls (a call lasts about a
 * millisecond of wall time, see master.py). With a lead (Pace.lead > 0) a point due within the
 * lead is released at once, and one due later is waited for until half the lead is left: the
 * points go out in bursts up to the lead ahead of their deadlines, which absorb a stall of the
 * thread shorter than half the lead, and the waits are long enough to sleep through. */
static int pace_to(Pace *c, double t)
{
    double now_ = now();
    double busy = now_ - c->released;
    double deadline = c->wall0 + (t - c->t0) / c->speed;
    double wake = c->lead > 0.0 ? (now_ < deadline - c->lead ? deadline - c->lead / 2 : now_) : deadline;
    while (wake - now_ > c->spin + 1e-6) {
        double left = wake - now_ - c->spin;
        sleep_until(now_ + (left < 0.05 ? left : 0.05));
        now_ = now();
    }
    double polling = now_;
    while (now_ < wake) now_ = now();
    c->polled += now_ - polling;
    double late = now_ - deadline;
    c->released = now_;
    if (*c->count < c->capacity) { /* the lateness first: another thread may read up to the count */
        c->lateness[*c->count] = late;
        __atomic_store_n(c->count, *c->count + 1, __ATOMIC_RELEASE);
    }
    if (c->late) *c->late = late;
    c->last_busy = busy;
    if (c->busy) *c->busy = busy;
    if (c->behind) *c->behind = late > c->period ? 1.0 : 0.0;
    return late > c->period;
}

/* the event indicators at (t, x) into z (as the master's Python does: time, states, indicators) */
static int indicators(Plan *p, Op *o, double t, double *z)
{
    int status;
    p->call = 0;
    if ((status = o->set_time(o->component, t)) > FMI2_WARNING) return status;
    p->call = 1;
    if (o->nx && (status = o->set_states(o->component, o->x, o->nx)) > FMI2_WARNING) return status;
    p->call = 3;
    return o->get_indicators(o->component, z, o->nz);
}

/* Runge-Kutta steps to t_end with the indicators checked after each (ExplicitRungeKutta.advance) */
static int steps_with_indicators(Plan *p, Op *o, double t_end, double h, int n)
{
    int status;
    if (!*o->z_valid) {
        if ((status = indicators(p, o, *o->t, o->z_last)) > FMI2_WARNING) goto failed;
        *o->z_valid = 1;
    }
    for (int k = 0; k < n; k++) {
        double t0 = *o->t;
        for (size_t i = 0; i < o->nx; i++) o->x0[i] = o->x[i];
        status = o->erk(o->erk_plan, t0, h, 1, o->x);
        if (status > FMI2_WARNING) {
            p->status = status;
            p->rk_time = t0;
            return RK_FAILED;
        }
        *o->t = k == n - 1 ? t_end : t0 + h;
        if ((status = indicators(p, o, *o->t, o->z)) > FMI2_WARNING) goto failed;
        for (size_t i = 0; i < o->nz; i++) {
            if ((o->z[i] > 0) != (o->z_last[i] > 0)) {
                p->rk_time = t0;
                p->rk_step = h;
                return STATE_EVENT;
            }
        }
        for (size_t i = 0; i < o->nz; i++) o->z_last[i] = o->z[i];
    }
    return RAN;
failed:
    p->status = status;
    return FAILED;
}

static int me_step(Plan *p, Op *o, double t, double step)
{
    double t_end = t + step;
    double eps = 1e-12 * fmax(1.0, fabs(t_end));
    int status;
    if (t_end - *o->t > eps) {
        double span = t_end - *o->t;
        int n = 1;
        if (o->max_step > 0) {
            double c = ceil(span / o->max_step - 1e-9);
            n = c > 1.0 ? (int)c : 1;
        }
        /* since this op set them at the last step's end, the FMU got new inputs only */
        *o->erk_current = o->holds_end;
        o->holds_end = 0;
        if (o->nz) {
            int stop = steps_with_indicators(p, o, t_end, span / n, n);
            *o->erk_current = 0;
            if (stop != RAN) return stop;
        } else {
            status = o->erk(o->erk_plan, *o->t, span / n, n, o->x);
            *o->erk_current = 0;
            if (status > FMI2_WARNING) {
                p->status = status;
                p->rk_time = *o->t;
                return RK_FAILED;
            }
            *o->t = t_end;
        }
    }
    double reached = *o->t;
    p->time = reached;
    p->call = 0;
    if ((status = o->set_time(o->component, reached)) > FMI2_WARNING) goto failed;
    p->call = 1;
    if (o->nx && (status = o->set_states(o->component, o->x, o->nx)) > FMI2_WARNING) goto failed;
    o->holds_end = 1;
    if (o->completed) {
        int enter = 0, terminate = 0;
        p->call = 2;
        if (o->fmi3) {
            bool enter3 = false, terminate3 = false;
            status = ((Completed3)(void *)o->completed)(o->component, o->no_prior_state != 0, &enter3, &terminate3);
            enter = enter3, terminate = terminate3;
        } else {
            status = o->completed(o->component, o->no_prior_state, &enter, &terminate);
        }
        if (status > FMI2_WARNING)
            goto failed;
        if (terminate) return TERMINATED;
        if (enter) return STEP_EVENT;
    }
    return RAN;
failed:
    p->status = status;
    return FAILED;
}

static double tick_of(const Op *o, size_t i)
{
    return o->clock_first[i] + (double)o->clock_count[i] * o->clock_interval[i];
}

/* The unit's Clocks ticking at t (within round-off) activated in one Event Mode, as
 * CoSimulationUnit3.do_step does; a tick later inside the step [t, t + step) hands back first. */
static int clock_tick(Plan *p, Op *o, double t, double step)
{
    double end = t + step, now_eps = 1e-12 * fmax(1.0, fabs(t)), end_eps = 1e-12 * fmax(1.0, fabs(end));
    size_t n_due = 0;
    for (size_t i = 0; i < o->n; i++) { /* the first tick after those due now: inside the step? */
        int64_t count = o->clock_count[i];
        while (o->clock_first[i] + (double)count * o->clock_interval[i] <= t + now_eps) count++;
        if (o->clock_first[i] + (double)count * o->clock_interval[i] < end - end_eps) return CLOCK_INSIDE;
    }
    for (size_t i = 0; i < o->n; i++) {
        if (!(tick_of(o, i) <= t + now_eps)) continue;
        while (tick_of(o, i) <= t + now_eps) o->clock_count[i]++; /* more than one: missed ticks */
        o->clock_activated[i]++;
        o->due_vrs[n_due] = o->vrs[i];
        o->on[n_due++] = true;
    }
    if (!n_due) return RAN;
    int status;
    p->time = t;
    p->call = 0;
    if ((status = o->enter_event_mode(o->component)) > FMI2_WARNING) goto failed;
    p->call = 1;
    if ((status = ((SetClock3)o->function)(o->component, o->due_vrs, n_due, o->on)) > FMI2_WARNING) goto failed;
    p->call = 2;
    for (int round = 0;; round++) {
        bool update = false, terminate = false, nominals = false, values = false, defined = false;
        double next = 0.0;
        status = o->update_discrete_states(o->component, &update, &terminate, &nominals, &values, &defined, &next);
        if (status > FMI2_WARNING) goto failed;
        if (terminate) return TERMINATED;
        if (!update) break;
        if (round + 1 == MAX_EVENT_ITERATIONS) return UNSETTLED;
    }
    p->call = 3;
    if ((status = o->enter_step_mode(o->component)) > FMI2_WARNING) goto failed;
    return RAN;
failed:
    p->status = status;
    return FAILED;
}

static int run_op(Plan *p, Op *o, long k, double t)
{
    int status = 0;
    switch (o->kind) {
    case SET_REAL: {
        double *v = (double *)o->values;
        const double *bus = (const double *)o->bus;
        if (o->positions) {
            for (size_t i = 0; i < o->n_index; i++)
                v[o->positions[i]] = o->factor ? o->factor[i] * bus[o->index[i]] + o->offset[i] : bus[o->index[i]];
            status = ((SetReal3)o->function)(o->component, o->vrs, o->n, v, o->n_values);
            break;
        }
        for (size_t i = 0; i < o->n; i++) v[i] = bus[o->index[i]];
        if (o->factor) {
            for (size_t i = 0; i < o->n; i++) v[i] *= o->factor[i];
            for (size_t i = 0; i < o->n; i++) v[i] += o->offset[i];
        }
        status = ((SetReal)o->function)(o->component, o->vrs, o->n, v);
        break;
    }
    case GET_REAL:
        status = o->fmi3 ? ((GetReal3)o->function)(o->component, o->vrs, o->n, (double *)o->values, o->n_values)
                         : ((GetReal)o->function)(o->component, o->vrs, o->n, (double *)o->values);
        break;
    case SET_INT: {
        int *v = (int *)o->values;
        const int *bus = (const int *)o->bus;
        if (o->positions) {
            for (size_t i = 0; i < o->n_index; i++) v[o->positions[i]] = bus[o->index[i]];
            status = ((SetInt3)o->function)(o->component, o->vrs, o->n, v, o->n_values);
            break;
        }
        for (size_t i = 0; i < o->n; i++) v[i] = bus[o->index[i]];
        status = ((SetInt)o->function)(o->component, o->vrs, o->n, v);
        break;
    }
    case GET_INT:
        status = o->fmi3 ? ((GetInt3)o->function)(o->component, o->vrs, o->n, (int *)o->values, o->n_values)
                         : ((GetInt)o->function)(o->component, o->vrs, o->n, (int *)o->values);
        break;
    case SET_BOOL3: {
        bool *v = (bool *)o->values;
        const int *bus = (const int *)o->bus;
        for (size_t i = 0; i < o->n_index; i++) v[o->positions[i]] = bus[o->index[i]] != 0;
        status = ((SetBool3)o->function)(o->component, o->vrs, o->n, v, o->n_values);
        break;
    }
    case GET_BOOL3: {
        const bool *v = (const bool *)o->values;
        status = ((GetBool3)o->function)(o->component, o->vrs, o->n, (bool *)o->values, o->n_values);
        for (size_t i = 0; i < o->n_values; i++) ((int *)o->bus)[i] = v[i];
        break;
    }
    case DO_STEP:
    case ME_STEP:
    case CLOCK_TICK: {
        long m = o->multiple;
        double step = k + m < p->last ? (double)m * p->h : p->stop - t;
        if (o->kind == ME_STEP) return me_step(p, o, t, step);
        if (o->kind == CLOCK_TICK) return clock_tick(p, o, t, step);
        if (o->fmi3) {
            bool event = false, terminate = false, early = false;
            double last = t + step;
            status = ((DoStep3)o->function)(o->component, t, step, o->no_prior_state != 0, &event, &terminate, &early,
                                            &last);
            o->flags = (event ? EVENT_HANDLING_NEEDED : 0) | (terminate ? TERMINATE_SIMULATION : 0) |
                       (early ? EARLY_RETURN : 0);
            o->step_status = status;
            o->last_time = last;
            if (o->flags || status > FMI2_WARNING) return STEP_RETURNED; /* Python carries on */
            break;
        }
        status = ((DoStep)o->function)(o->component, t, step, o->no_prior_state);
        break;
    }
    }
    if (status > FMI2_WARNING) {
        p->status = status;
        return FAILED;
    }
    return RAN;
}

static void record_parts(const RowPart *parts, size_t n_parts, double *row)
{
    for (size_t j = 0; j < n_parts; j++) {
        const RowPart *part = &parts[j];
        if (part->is_int)
            for (size_t i = 0; i < part->n; i++)
                row[1 + part->columns[i]] = (double)((const int *)part->bus)[part->index[i]];
        else
            for (size_t i = 0; i < part->n; i++)
                row[1 + part->columns[i]] = ((const double *)part->bus)[part->index[i]];
    }
}

/* A component's recorded values, one after the other (stage_parts, unstage_parts) */
static size_t staged_width(const Component *comp)
{
    size_t n = 0;
    for (size_t j = 0; j < comp->n_parts; j++) n += comp->parts[j].n;
    return n;
}

static void stage_parts(const Component *comp, double *staged)
{
    for (size_t j = 0; j < comp->n_parts; j++) {
        const RowPart *part = &comp->parts[j];
        if (part->is_int)
            for (size_t i = 0; i < part->n; i++) *staged++ = (double)((const int *)part->bus)[part->index[i]];
        else
            for (size_t i = 0; i < part->n; i++) *staged++ = ((const double *)part->bus)[part->index[i]];
    }
}

static void unstage_parts(const Component *comp, const double *staged, double *row)
{
    for (size_t j = 0; j < comp->n_parts; j++) {
        const RowPart *part = &comp->parts[j];
        for (size_t i = 0; i < part->n; i++) row[1 + part->columns[i]] = *staged++;
    }
}

static void record(const Plan *p, double t, double *row)
{
    row[0] = t;
    record_parts(p->parts, p->n_parts, row);
}

/* --- parallel units --------------------------------------------------------------------------
 * A group step is a round: the calling thread publishes the ops [first, end) in contiguous blocks,
 * one per thread, each with a ticket (the round's number and the block's next op in one atomic
 * word), and every thread, the calling one too, claims ops one at a time (compare-and-swap: a claim
 * of a round already over fails), from its own block (the same units every step) and then from the
 * others, until none are left; the calling thread then waits for the ops claimed to finish, never for a
 * worker that has not woken yet (on a loaded machine it may not run for milliseconds: the calling
 * thread takes its share instead). A step of a compiled unit takes microseconds, less than a
 * condition variable's round trip, so a worker spins a while for the next round and the calling
 * thread for the last op, both bounded (SPIN_SECONDS: a spinning thread takes the core from the
 * other processes of a loaded machine), then sleep on the pool's condition variables; the one
 * who makes the other's condition true wakes it only when it sleeps.
 * Whether the threads pay is measured, not assumed: a round waits for the slowest thread, and on a
 * loaded machine a thread preempted in the middle of an op holds the round up for milliseconds. The
 * group steps take turns on the threads and on the calling thread alone (PROBE_STEPS each, after
 * WARM_STEPS on the threads), then go on the faster way for EXPLOIT_STEPS before measuring both
 * again. Either way each op takes the
 * step it takes in turn: the results are the same bit for bit. */
enum { MAX_THREADS = 256 };
static const double SPIN_SECONDS = 50e-6;
enum { WARM_STEPS = 8, PROBE_STEPS = 64, EXPLOIT_STEPS = 1024 };
enum { BLOCK_STEPS = 64, BLOCK_PROBE_STEPS = 64, BLOCK_EXPLOIT_STEPS = 4096 }; /* see "blocks of steps" */
typedef void *(*SaveThread)(void);
typedef void (*RestoreThread)(void *);
typedef int (*GilCheck)(void);
typedef void *(*ThisThreadState)(void);
typedef void (*GilRelease)(int);

/* A thread's share of a round: ops [.., end) claimed through ticket, (round << 32) | the next op. */
typedef struct {
    uint64_t ticket;         /* atomic */
    size_t end;              /* atomic */
    char pad[64 - sizeof(uint64_t) - sizeof(size_t)]; /* one cache line each */
} Block;

/* Which way rounds go, on the threads or on the calling thread alone (see choose()); counted in steps */
typedef struct {
    int threaded;            /* on the threads now (else on the calling thread alone) */
    long left;               /* steps left this way before the next decision */
    int probing;             /* 0: exploiting; 1, 2: the first, the second way measured */
    double spent[2];         /* seconds per step measured alone [0] and on the threads [1] */
    double window;           /* seconds of this probe so far */
    long probe, exploit;     /* steps measured each way; steps the faster way goes before measuring again */
} Choice;

typedef struct Pool Pool;
typedef struct {
    Pool *pool;
    int id;                  /* its block: 1, 2, ... (the calling thread's is 0) */
} Worker;

struct Pool {
    Plan *p;
    int n_workers;
    Worker worker_args[MAX_THREADS];
    pthread_t workers[MAX_THREADS];
    pthread_mutex_t lock;
    pthread_cond_t wake, done;
    unsigned long round;     /* atomic: one per group step; the workers wait for the next */
    Block blocks[MAX_THREADS + 1]; /* this round's ops, one block per thread (the calling thread's first) */
    int n_blocks;
    long k;                  /* written before the ticket is published, read after a claim */
    double t;
    size_t finished, total;  /* atomic: ops of this round done; how many it has */
    int sleepers;            /* atomic: workers asleep on `wake` */
    int waiting;             /* atomic: the calling thread asleep on `done` */
    int quit;                /* atomic */
    SaveThread save_thread;  /* Python's */
    RestoreThread restore_thread;
    Choice groups;           /* the group steps' way */
    Choice in_blocks;        /* the blocks of steps' way */
    /* blocks of steps (Plan.components): this round's kind and, for mode 1, its steps and rows */
    int mode;                /* 0: the ops [first, end) of a group at step k; 1: components through [k, k_end) */
    long k_end;
    double *rows;            /* the run's rows; row_of[j]: step k + j's row in them, -1: none */
    long row_of[BLOCK_STEPS];
    /* each component's recorded values of a block's steps (BLOCK_STEPS rows of its own values, a
     * cache line apart from the others'), copied into the rows by the calling thread after the
     * block: threads writing their columns into the same rows at every step slowed each other */
    double **staged;
    long stop_k;             /* atomic, written under lock: the first step a component stopped in (LONG_MAX: none) */
    long stop_op;            /* under lock: its op (the first in stepping order in that step) */
    int stop_why, stop_status;
    GilCheck gil_check;      /* PyGILState_Check */
    ThisThreadState this_thread_state; /* PyGILState_GetThisThreadState */
    GilRelease gil_release;  /* PyGILState_Release */
};

static inline void spin_pause(void)
{
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#elif defined(__aarch64__)
    __asm__ __volatile__("yield");
#endif
}

/* Op i of a group steps at step k (time t); its status into group_status. */
static void step_op(Plan *p, size_t i, long k, double t)
{
    Op *o = &p->ops[i];
    o->group_status = 0;
    if (k % o->multiple) return;
    double begin = p->op_seconds ? now() : 0.0;
    long m = o->multiple;
    double step = k + m < p->last ? (double)m * p->h : p->stop - t;
    o->group_status = ((DoStep)o->function)(o->component, t, step, o->no_prior_state);
    if (p->op_seconds) p->op_seconds[i] += now() - begin;
}

/* A component stopped (why, status) at op i of step k: kept when it is the first in stepping
 * order (the earliest step, then the earliest op), the stop the loop on one thread would meet. */
static void note_stop(Pool *pool, long k, long i, int why, int status)
{
    pthread_mutex_lock(&pool->lock);
    if (k < pool->stop_k || (k == pool->stop_k && i < pool->stop_op)) {
        pool->stop_op = i;
        pool->stop_why = why;
        pool->stop_status = status;
        __atomic_store_n(&pool->stop_k, k, __ATOMIC_SEQ_CST);
    }
    pthread_mutex_unlock(&pool->lock);
}

/* Component c through the round's steps [k, k_end): its ops in stepping order each step, then its
 * recorded values into the step's row; it goes no further than a step another one stopped in. */
static void component_steps(Pool *pool, size_t c)
{
    const Plan *p = pool->p;
    const Component *comp = &p->components[c];
    Plan local = *p; /* run_op notes a failure's status in its plan: this thread's own */
    const long k0 = pool->k;
    for (long k = k0; k < pool->k_end; k++) {
        if (k >= __atomic_load_n(&pool->stop_k, __ATOMIC_ACQUIRE)) return;
        double t = p->start + (double)k * p->h;
        for (size_t j = 0; j < comp->n_ops; j++) {
            long i = comp->ops[j];
            Op *o = &p->ops[i];
            if (k % o->multiple) continue;
            int why = run_op(&local, o, k, t);
            if (why != RAN) {
                note_stop(pool, k, i, why, local.status);
                return;
            }
        }
        if (pool->row_of[k - k0] >= 0) stage_parts(comp, pool->staged[comp - p->components] + (k - k0) * staged_width(comp));
    }
}

/* Claims and steps the ops of one block of the round until none is left (`round`: the round this
 * thread takes part in). */
static void take_block(Pool *pool, Block *b, unsigned long round)
{
    Plan *p = pool->p;
    uint64_t mine = (uint64_t)(uint32_t)round << 32;
    for (;;) {
        uint64_t ticket = __atomic_load_n(&b->ticket, __ATOMIC_ACQUIRE);
        if ((ticket & ~(uint64_t)UINT32_MAX) != mine) return; /* that round is over */
        size_t i = (size_t)(ticket & UINT32_MAX);
        if (i >= __atomic_load_n(&b->end, __ATOMIC_RELAXED)) return; /* (a newer round's end: the claim fails) */
        if (!__atomic_compare_exchange_n(&b->ticket, &ticket, ticket + 1, false, __ATOMIC_ACQ_REL,
                                         __ATOMIC_ACQUIRE))
            continue;
        size_t total = pool->total; /* the round stays until this op is finished */
        if (pool->mode)
            component_steps(pool, i);
        else
            step_op(p, i, pool->k, pool->t);
        if (__atomic_add_fetch(&pool->finished, 1, __ATOMIC_SEQ_CST) == total &&
            __atomic_load_n(&pool->waiting, __ATOMIC_SEQ_CST)) {
            pthread_mutex_lock(&pool->lock);
            pthread_cond_signal(&pool->done);
            pthread_mutex_unlock(&pool->lock);
        }
    }
}

/* This thread's own block first (the same units every step: their memory stays in its core's
 * cache), then what is left of the others' (a thread late to the round leaves its share). */
static void take_steps(Pool *pool, unsigned long round, int id)
{
    for (int j = 0; j < pool->n_blocks; j++) take_block(pool, &pool->blocks[(id + j) % pool->n_blocks], round);
}

static void *pool_worker(void *arg)
{
    Pool *pool = ((Worker *)arg)->pool;
    int id = ((Worker *)arg)->id;
    unsigned long seen = 0;
    for (;;) {
        unsigned long round = __atomic_load_n(&pool->round, __ATOMIC_ACQUIRE);
        if (round == seen && !__atomic_load_n(&pool->quit, __ATOMIC_ACQUIRE)) {
            double until = now() + SPIN_SECONDS;
            for (unsigned n = 1;; n++) {
                round = __atomic_load_n(&pool->round, __ATOMIC_ACQUIRE);
                if (round != seen || __atomic_load_n(&pool->quit, __ATOMIC_ACQUIRE)) break;
                spin_pause();
                if (n % 64 == 0 && now() > until) break;
            }
        }
        if (round == seen && !__atomic_load_n(&pool->quit, __ATOMIC_ACQUIRE)) {
            pthread_mutex_lock(&pool->lock);
            __atomic_add_fetch(&pool->sleepers, 1, __ATOMIC_SEQ_CST);
            while ((round = __atomic_load_n(&pool->round, __ATOMIC_SEQ_CST)) == seen &&
                   !__atomic_load_n(&pool->quit, __ATOMIC_SEQ_CST))
                pthread_cond_wait(&pool->wake, &pool->lock);
            __atomic_sub_fetch(&pool->sleepers, 1, __ATOMIC_SEQ_CST);
            pthread_mutex_unlock(&pool->lock);
        }
        if (__atomic_load_n(&pool->quit, __ATOMIC_ACQUIRE)) break;
        seen = round;
        take_steps(pool, round, id);
    }
    /* A worker that ran an FMU's Python has the thread state the FMU made for it and keeps for the
     * thread's life (its first PyGILState_Ensure, never released: bridge.c): give it back, or
     * every run would leave one per worker. (Not in the FMU: its library may be unloaded first.) */
    void *state = pool->this_thread_state && pool->gil_release ? pool->this_thread_state() : NULL;
    if (state) {
        pool->restore_thread(state);
        pool->gil_release(1 /* PyGILState_UNLOCKED: that Ensure found the lock not held */);
    }
    return NULL;
}

/* The plan's worker threads (threads - 1 of them; none when it has no group or one thread). */
static void pool_stop(Pool *pool);

static Pool *pool_start(Plan *p)
{
    int grouped = 0;
    for (size_t i = 0; i < p->n_ops; i++) grouped |= p->ops[i].group > 0;
    grouped |= p->n_components > 1;
    /* without Python's lock to let go of (a host that embeds Python and hides its symbols), one at a time:
     * an FMU of the group that takes the lock would wait for this thread, which waits for it */
    if (!grouped || p->threads < 2 || !dlsym(RTLD_DEFAULT, "PyEval_SaveThread")) return NULL;
    Pool *pool = calloc(1, sizeof *pool); /* one per run: runs of other masters may go on meanwhile */
    if (!pool) return NULL;                /* the group steps on the calling thread, one op at a time */
    pool->p = p;
    pool->save_thread = (SaveThread)dlsym(RTLD_DEFAULT, "PyEval_SaveThread");
    pool->restore_thread = (RestoreThread)dlsym(RTLD_DEFAULT, "PyEval_RestoreThread");
    pool->gil_check = (GilCheck)dlsym(RTLD_DEFAULT, "PyGILState_Check");
    pool->this_thread_state = (ThisThreadState)dlsym(RTLD_DEFAULT, "PyGILState_GetThisThreadState");
    pool->gil_release = (GilRelease)dlsym(RTLD_DEFAULT, "PyGILState_Release");
    pthread_mutex_init(&pool->lock, NULL);
    pthread_cond_init(&pool->wake, NULL);
    pthread_cond_init(&pool->done, NULL);
    /* first steps make the solvers (Python, milliseconds): not measured */
    pool->groups = (Choice){.threaded = 1, .left = WARM_STEPS, .probe = PROBE_STEPS, .exploit = EXPLOIT_STEPS};
    pool->in_blocks = (Choice){.threaded = 1, .left = BLOCK_STEPS, .probe = BLOCK_PROBE_STEPS,
                            .exploit = BLOCK_EXPLOIT_STEPS};
    int wanted = p->threads - 1 < MAX_THREADS ? p->threads - 1 : MAX_THREADS;
    for (int i = 0; i < wanted; i++) {
        Worker *w = &pool->worker_args[pool->n_workers];
        w->pool = pool;
        w->id = pool->n_workers + 1;
        if (pthread_create(&pool->workers[pool->n_workers], NULL, pool_worker, w) == 0) pool->n_workers++;
    }
    pool->n_blocks = pool->n_workers + 1;
    if (p->n_components > 1) {
        pool->staged = calloc(p->n_components, sizeof *pool->staged);
        for (size_t c = 0; pool->staged && c < p->n_components; c++) {
            size_t bytes = (BLOCK_STEPS * staged_width(&p->components[c]) * sizeof(double) + 63) / 64 * 64;
            if (posix_memalign((void **)&pool->staged[c], 64, bytes ? bytes : 64)) pool->staged[c] = NULL;
            if (!pool->staged[c]) {
                pool_stop(pool);
                return NULL;
            }
        }
        if (!pool->staged) {
            pool_stop(pool);
            return NULL;
        }
    }
    return pool; /* no worker started: the calling thread steps the group alone */
}

static void pool_stop(Pool *pool)
{
    if (!pool) return;
    pthread_mutex_lock(&pool->lock);
    __atomic_store_n(&pool->quit, 1, __ATOMIC_SEQ_CST);
    pthread_cond_broadcast(&pool->wake);
    pthread_mutex_unlock(&pool->lock);
    /* a worker that entered an FMU's Python gives its thread state back as it exits (bridge.c),
     * which takes Python's lock: not held here meanwhile */
    void *state = pool->gil_check && pool->gil_check() ? pool->save_thread() : NULL;
    for (int i = 0; i < pool->n_workers; i++) pthread_join(pool->workers[i], NULL);
    if (state) pool->restore_thread(state);
    pthread_cond_destroy(&pool->done);
    pthread_cond_destroy(&pool->wake);
    pthread_mutex_destroy(&pool->lock);
    if (pool->staged)
        for (size_t c = 0; c < pool->p->n_components; c++) free(pool->staged[c]);
    free(pool->staged);
    free(pool);
}

/* Steps ops [first, end) of one group at step k (time t) on the pool, the calling thread too;
 * the calling thread lets go of Python's lock meanwhile where it holds it (gil_held). */
static void threaded_step(Pool *pool, size_t first, size_t end, long k, double t, bool gil_held)
{
    /* the last round's ops are all finished: nobody reads these until the new ticket is out */
    unsigned long round = pool->round + 1;
    size_t n = end - first;
    pool->k = k;
    pool->t = t;
    pool->total = n;
    __atomic_store_n(&pool->finished, 0, __ATOMIC_RELAXED);
    for (int j = 0; j < pool->n_blocks; j++) { /* contiguous blocks, as even as they come */
        Block *b = &pool->blocks[j];
        __atomic_store_n(&b->end, first + n * (size_t)(j + 1) / (size_t)pool->n_blocks, __ATOMIC_RELAXED);
        __atomic_store_n(&b->ticket, ((uint64_t)(uint32_t)round << 32) | (first + n * (size_t)j / (size_t)pool->n_blocks),
                         __ATOMIC_RELEASE);
    }
    __atomic_store_n(&pool->round, round, __ATOMIC_SEQ_CST);
    if (__atomic_load_n(&pool->sleepers, __ATOMIC_SEQ_CST)) {
        pthread_mutex_lock(&pool->lock);
        pthread_cond_broadcast(&pool->wake);
        pthread_mutex_unlock(&pool->lock);
    }
    void *state = gil_held ? pool->save_thread() : NULL;
    take_steps(pool, round, 0);
    if (__atomic_load_n(&pool->finished, __ATOMIC_ACQUIRE) != pool->total) {
        /* a worker is on the last ops: they take microseconds, unless it was preempted */
        double until = now() + SPIN_SECONDS;
        for (unsigned n = 1; __atomic_load_n(&pool->finished, __ATOMIC_ACQUIRE) != pool->total; n++) {
            spin_pause();
            if (n % 64 == 0 && now() > until) break;
        }
        if (__atomic_load_n(&pool->finished, __ATOMIC_ACQUIRE) != pool->total) {
            pthread_mutex_lock(&pool->lock);
            __atomic_store_n(&pool->waiting, 1, __ATOMIC_SEQ_CST);
            while (__atomic_load_n(&pool->finished, __ATOMIC_SEQ_CST) != pool->total)
                pthread_cond_wait(&pool->done, &pool->lock);
            __atomic_store_n(&pool->waiting, 0, __ATOMIC_SEQ_CST);
            pthread_mutex_unlock(&pool->lock);
        }
    }
    if (gil_held) pool->restore_thread(state);
}

/* After a round of `steps` steps that took `seconds` the way c->threaded says: the way of the next
 * rounds (see the section's comment). */
static void choose(Choice *c, double seconds, long steps)
{
    if (c->probing) c->window += seconds;
    if ((c->left -= steps) > 0) return;
    if (c->probing) {
        c->spent[c->threaded] = c->window / (double)(c->probe - c->left);
        c->window = 0.0;
        if (c->probing == 1) { /* now the other way */
            c->probing = 2;
            c->threaded = !c->threaded;
            c->left = c->probe;
            return;
        }
        c->probing = 0;
        c->threaded = c->spent[1] < c->spent[0];
        c->left = c->exploit;
        return;
    }
    c->probing = 1; /* measure both again, the way taken now first */
    c->left = c->probe;
}

/* Steps ops [first, end) of one group at step k (time t): on the threads or on the calling thread
 * alone, whichever was faster when last measured (see the section's comment). */
static void group_step(Pool *pool, size_t first, size_t end, long k, double t, bool gil_held)
{
    double begin = now();
    pool->mode = 0;
    if (pool->groups.threaded) {
        threaded_step(pool, first, end, k, t, gil_held);
    } else {
        for (size_t i = first; i < end; i++) step_op(pool->p, i, k, t);
    }
    choose(&pool->groups, now() - begin, 1);
}

/* --- blocks of steps -----------------------------------------------------------------------
 * When the plan's units fall into components that exchange no values with one another
 * (Plan.components, all of them stepping on the threads: see c_loop.py), a component's steps need
 * nothing of the others: each thread takes whole components through a block of steps (BLOCK_STEPS)
 * (claimed as a group step's ops are, its own share first), every component's ops in their order at
 * each step and its recorded values into that step's row, and the threads meet once a block instead
 * of once a step. Each op makes the calls it makes with one thread, with the same arguments: the
 * results are the same bit for bit. The calling thread then writes each row's time and the recorded
 * values no op writes (unchanged within the run). A component that stops (a failure, a termination)
 * at some step leaves the rows before it complete: the others go on up to that step, and the stop
 * reported is the first in stepping order; a component further on when it stopped has taken those
 * steps too, as a group's units take the step one of them failed in. The blocks go on the threads
 * or on the calling thread alone as group steps do (the first block on the threads, then
 * BLOCK_PROBE_STEPS each way, then the faster for BLOCK_EXPLOIT_STEPS): on a loaded machine a
 * worker preempted in the middle of a component's block holds the block up. */
static int block_steps(Plan *p, Pool *pool, long k, long k_end, double *rows, long max_rows, long *k_done,
                       long *n_rows)
{
    long written = 0, *row_of = pool->row_of;
    const size_t stride = p->width + 1;
    pool->rows = rows;
    while (k < k_end) {
        long kb = k, count = 0; /* the block: steps [k, kb), its rows [written, written + count) */
        while (kb < k_end && kb - k < BLOCK_STEPS) {
            long next = kb + 1;
            int due = next % p->every == 0 || next == p->n_steps;
            if (due && written + count == max_rows) break;
            row_of[kb - k] = due ? written + count++ : -1;
            kb++;
        }
        if (kb == k) {
            *k_done = k;
            *n_rows = written;
            return ROWS_FULL;
        }
        pool->k_end = kb;
        pool->stop_k = LONG_MAX;
        pool->stop_op = LONG_MAX;
        pool->mode = 1;
        pool->k = k;
        double begin = now();
        if (pool->in_blocks.threaded) {
            threaded_step(pool, 0, p->n_components, k, p->start + (double)k * p->h, !p->gil_released);
        } else {
            for (size_t c = 0; c < p->n_components; c++) component_steps(pool, c);
        }
        choose(&pool->in_blocks, now() - begin, kb - k);
        long stop = __atomic_load_n(&pool->stop_k, __ATOMIC_ACQUIRE);
        long last = stop < kb ? stop : kb;
        for (long j = k; j < last; j++) { /* the rows of the steps completed */
            if (row_of[j - k] < 0) continue;
            long next = j + 1;
            double *row = rows + row_of[j - k] * (long)stride;
            row[0] = next < p->n_steps ? p->start + (double)next * p->h : p->stop;
            record_parts(p->fixed_parts, p->n_fixed_parts, row);
            for (size_t c = 0; c < p->n_components; c++) {
                const Component *comp = &p->components[c];
                unstage_parts(comp, pool->staged[c] + (j - k) * staged_width(comp), row);
            }
            written++;
        }
        if (stop < kb) {
            p->op = pool->stop_op;
            p->status = pool->stop_status;
            *k_done = stop;
            *n_rows = written;
            return pool->stop_why;
        }
        k = kb;
        if (p->deadline > 0.0 && now() > p->deadline) break;
    }
    *k_done = k;
    *n_rows = written;
    return RAN;
}

static int fixed_steps(Plan *p, long k_begin, long k_end, double *rows, long max_rows, long *k_done,
                       long *n_rows);

static double thread_cpu(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* Steps k_begin, k_begin + 1, ... before k_end, every recorded row into `rows` (room for
 * max_rows). Returns why it stopped (RAN: k_end reached; ROWS_FULL: no room for the next
 * step's row; else the stop of operation plan->op in step *k_done); *k_done is the first step
 * not completed and *n_rows the rows written. A paced run adds its CPU and wall time up (Pace). */
__attribute__((visibility("default")))
int deltafmi_fixed_steps(Plan *p, long k_begin, long k_end, double *rows, long max_rows, long *k_done,
                         long *n_rows)
{
    if (!p->pace) return fixed_steps(p, k_begin, k_end, rows, max_rows, k_done, n_rows);
    double cpu = thread_cpu(), wall = now();
    int why = fixed_steps(p, k_begin, k_end, rows, max_rows, k_done, n_rows);
    p->pace->cpu += thread_cpu() - cpu;
    p->pace->wall += now() - wall;
    return why;
}

static int fixed_steps(Plan *p, long k_begin, long k_end, double *rows, long max_rows, long *k_done,
                       long *n_rows)
{
    long k = k_begin, written = 0;
    int why = RAN;
    p->sink_rows = p->sink_queued = 0;
    for (size_t i = 0; i < p->n_ops; i++)
        p->ops[i].holds_end = 0; /* Python may have called the FMUs since the last run */
    if (!p->pool) p->pool = pool_start(p);
    Pool *pool = p->pool;
    if (pool && p->n_components > 1 && !p->pace && !p->step_start && !p->op_seconds)
        return block_steps(p, pool, k, k_end, rows, max_rows, k_done, n_rows);
    if (p->pace && *p->pace->count == 0) { /* Pacer.restart: the paced clock starts with the stepping */
        p->pace->wall0 = now();
        p->pace->released = p->pace->wall0;
    }
    Pace *stream = p->pace && p->pace->stream ? p->pace : NULL;
    int sink = p->sink_put && p->sink && !p->pace && p->sink_every > 0;
    int deadline = p->deadline > 0.0 && !p->pace;
    for (; k < k_end; k++) {
        long next = k + 1;
        int due = next % p->every == 0 || next == p->n_steps;
        if (due && written == max_rows && !stream) {
            why = ROWS_FULL;
            break;
        }
        double t = p->start + (double)k * p->h;
        if (p->step_start) record(p, t, p->step_start);
        for (size_t i = 0; i < p->n_ops; i++) {
            Op *o = &p->ops[i];
            if (pool && o->group > 0) { /* the group's ops, then their statuses in order */
                size_t end = i + 1;
                while (end < p->n_ops && p->ops[end].group == o->group) end++;
                group_step(pool, i, end, k, t, !p->gil_released);
                for (; i < end; i++) {
                    if (p->ops[i].group_status > FMI2_WARNING) {
                        p->status = p->ops[i].group_status;
                        p->op = (long)i;
                        *k_done = k;
                        *n_rows = written;
                        return FAILED;
                    }
                }
                i = end - 1;
                continue;
            }
            if (k % o->multiple) continue;
            double begin = p->op_seconds ? now() : 0.0;
            int stop = run_op(p, o, k, t);
            if (p->op_seconds) p->op_seconds[i] += now() - begin;
            if (stop != RAN) {
                p->op = (long)i;
                *k_done = k;
                *n_rows = written;
                return stop;
            }
        }
        double t_next = next < p->n_steps ? p->start + (double)next * p->h : p->stop;
        int late = p->pace ? pace_to(p->pace, t_next) : 0;
        if (p->pace && p->pace->sample && p->pace->sample(p->pace->sample_context, t_next)) {
            *k_done = next;
            *n_rows = written;
            return LIVE;
        }
        if (due && stream) { /* into the ring, once the other thread has made room */
            while (written - __atomic_load_n(&stream->taken, __ATOMIC_ACQUIRE) >= max_rows) {
                if (__atomic_load_n(&stream->stop_request, __ATOMIC_ACQUIRE)) {
                    *k_done = k;
                    *n_rows = written;
                    return RAN; /* the run ends (asked to), the units past its last row */
                }
                sleep_until(now() + 1e-4);
            }
            record(p, t_next, rows + (written % max_rows) * (long)(p->width + 1));
            __atomic_store_n(&stream->published, ++written, __ATOMIC_RELEASE);
        } else if (due) {
            record(p, t_next, rows + written * (long)(p->width + 1));
            written++;
            if (sink && written - p->sink_rows >= p->sink_every && !hand_over(p, rows, written)) sink = 0;
        }
        if (late && p->pace->stop_behind) {
            *k_done = next;
            *n_rows = written;
            return BEHIND;
        }
        if (stream && __atomic_load_n(&stream->stop_request, __ATOMIC_ACQUIRE)) {
            k++;
            break;
        }
        if (deadline && (next - k_begin) % DEADLINE_STEPS == 0 && now() > p->deadline) {
            k++;
            break;
        }
    }
    /* the run's last rows too (RAN or ROWS_FULL): the caller would hand them over itself */
    if (sink && written > p->sink_rows) hand_over(p, rows, written);
    *k_done = k;
    *n_rows = written;
    return why;
}

/* The plan's worker threads stopped and joined (call once its runs are over; again is harmless). */
__attribute__((visibility("default")))
void deltafmi_fixed_steps_end(Plan *p)
{
    pool_stop(p->pool);
    p->pool = NULL;
}
