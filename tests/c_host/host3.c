/* A minimal FMI 3.0 importer in plain C, used by the tests: no Python in this process.
 *
 *   host3 <unzipdir> <identifier> <token> cs        <stop> <step> <var>...  Co-Simulation, prints t,values
 *   host3 <unzipdir> <identifier> <token> cs-events <stop> <step> <var>...  with eventModeUsed and early return
 *   host3 <unzipdir> <identifier> <token> me        <stop> <step> <var>...  explicit Euler + event handling
 *   host3 <unzipdir> <identifier> <token> se <clock vr> <ticks> <inputs.txt> <in var>... -- <out var>...
 *                                                                       Scheduled Execution (below)
 *
 * <var> is a Float64 value reference, or vr:n for an array variable of n elements. Rows are
 * "t,v1,v2,..." on the output grid; cs-events also prints "event,<t>" where fmi3DoStep asked
 * for event handling, me "event,<t>" at each state or time event. A component that ends the
 * simulation gets its last row printed and "terminated,<time>". HOST_NULL_RESOURCES=1 passes
 * resourcePath = NULL (the FMU finds its resources from its binary).
 *
 * se: as a scheduler would, the host asks in Initialization Mode for the Clock's interval and shift
 * (printed "interval,<s>,<qualifier>" and "shift,<s>"), then at each of <ticks> ticks
 * t_k = shift + k * interval sets the Float64 inputs from line k of <inputs.txt> (all their values,
 * whitespace-separated, in the order of the <in> variables), calls fmi3ActivateModelPartition(clock,
 * t_k) and prints "t_k,outputs...", finally "clock_updates,<n>" (calls of the FMU's clockUpdate).
 * HOST_PARAM=vr=value sets one Float64 parameter before initialization.
 */
#include <dlfcn.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fmi3Functions.h"

#define LOAD(name) name##TYPE *name = (name##TYPE *)dlsym(lib, #name); \
    if (!name) { fprintf(stderr, "missing %s\n", #name); exit(2); }
#define OK(call) do { fmi3Status s_ = (call); if (s_ > fmi3Warning) { \
    fprintf(stderr, "%s failed with status %d\n", #call, s_); exit(3); } } while (0)

/* The event iteration: fmi3UpdateDiscreteStates until no update is needed or the FMU ends the run. */
static void update_discrete_states(fmi3UpdateDiscreteStatesTYPE *fmi3UpdateDiscreteStates, fmi3Instance c,
                                   fmi3Boolean *terminate, fmi3Boolean *values_changed, fmi3Boolean *next_defined,
                                   fmi3Float64 *next_time) {
    fmi3Boolean need_update = fmi3True, nominals_changed;
    while (need_update && !*terminate)
        OK(fmi3UpdateDiscreteStates(c, &need_update, terminate, &nominals_changed, values_changed, next_defined,
                                    next_time));
}

static void log_message(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    fprintf(stderr, "[%d|%s] %s\n", status, category, message);
}

static void print_row(double t, const double *values, size_t n) {
    printf("%.17g", t);
    for (size_t i = 0; i < n; i++) printf(",%.17g", values[i]);
    printf("\n");
}

/* "vr:n" or "vr" arguments from argv[first] up to "--" or the end: their number, *total values */
static int parse_variables(char **argv, int first, int argc, fmi3ValueReference *vrs, size_t *total) {
    int n = 0;
    *total = 0;
    for (int i = first; i < argc && strcmp(argv[i], "--") != 0; i++, n++) {
        char *colon = strchr(argv[i], ':');
        vrs[n] = (fmi3ValueReference)atol(argv[i]);
        *total += colon ? (size_t)atol(colon + 1) : 1;
    }
    return n;
}

static int clock_updates; /* the FMU asks for none: it has no countdown or output Clocks */
static void clock_update(fmi3InstanceEnvironment env) { (void)env; clock_updates++; }
static void lock_preemption(void) {}
static void unlock_preemption(void) {}

static int scheduled(void *lib, const char *resources, const char *token, int argc, char **argv) {
    LOAD(fmi3InstantiateScheduledExecution) LOAD(fmi3EnterInitializationMode) LOAD(fmi3ExitInitializationMode)
    LOAD(fmi3GetFloat64) LOAD(fmi3SetFloat64) LOAD(fmi3GetIntervalDecimal) LOAD(fmi3GetShiftDecimal)
    LOAD(fmi3ActivateModelPartition) LOAD(fmi3Terminate) LOAD(fmi3FreeInstance)
    if (argc < 8) {
        fprintf(stderr, "usage: host3 <unzipdir> <identifier> <token> se <clock vr> <ticks> <inputs.txt> ...\n");
        return 2;
    }
    fmi3ValueReference clock = (fmi3ValueReference)atol(argv[5]), in[256], out[256];
    long ticks = atol(argv[6]);
    FILE *inputs = fopen(argv[7], "r");
    if (!inputs || argc - 8 > 256) {
        fprintf(stderr, "cannot open %s, or too many variables\n", argv[7]);
        return 2;
    }
    size_t n_in_values, n_out_values = 0;
    int n_in = parse_variables(argv, 8, argc, in, &n_in_values), separator = 8 + n_in;
    int n_out = separator < argc ? parse_variables(argv, separator + 1, argc, out, &n_out_values) : 0;
    double *in_values = calloc(n_in_values + 1, sizeof(double)), *out_values = calloc(n_out_values + 1, sizeof(double));
    fmi3Instance c = fmi3InstantiateScheduledExecution("host3", token, resources, fmi3False, fmi3False, NULL,
                                                       log_message, clock_update, lock_preemption, unlock_preemption);
    if (!c) {
        fprintf(stderr, "fmi3InstantiateScheduledExecution failed\n");
        return 4;
    }
    const char *param = getenv("HOST_PARAM");
    if (param && strchr(param, '=')) {
        fmi3ValueReference vr = (fmi3ValueReference)atol(param);
        double value = atof(strchr(param, '=') + 1);
        OK(fmi3SetFloat64(c, &vr, 1, &value, 1));
    }
    OK(fmi3EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3False, 0.0));
    fmi3Float64 interval, shift;
    fmi3IntervalQualifier qualifier;
    OK(fmi3GetIntervalDecimal(c, &clock, 1, &interval, &qualifier));
    OK(fmi3GetShiftDecimal(c, &clock, 1, &shift));
    printf("interval,%.17g,%d\nshift,%.17g\n", interval, (int)qualifier, shift);
    OK(fmi3ExitInitializationMode(c));
    for (long k = 0; k < ticks; k++) {
        for (size_t i = 0; i < n_in_values; i++)
            if (fscanf(inputs, "%lf", &in_values[i]) != 1) {
                fprintf(stderr, "%s: too few input values for tick %ld\n", argv[7], k);
                return 5;
            }
        double t = shift + (double)k * interval;
        if (n_in) OK(fmi3SetFloat64(c, in, (size_t)n_in, in_values, n_in_values));
        OK(fmi3ActivateModelPartition(c, clock, t));
        if (n_out) OK(fmi3GetFloat64(c, out, (size_t)n_out, out_values, n_out_values));
        print_row(t, out_values, n_out_values);
    }
    OK(fmi3Terminate(c));
    fmi3FreeInstance(c);
    printf("clock_updates,%d\n", clock_updates);
    fclose(inputs);
    free(in_values);
    free(out_values);
    return 0;
}

int main(int argc, char **argv) {
    if (argc < 7) {
        fprintf(stderr, "usage: host3 <unzipdir> <identifier> <token> cs|cs-events|me <stop> <step> <var>...\n"
                        "       host3 <unzipdir> <identifier> <token> se <clock vr> <ticks> <inputs.txt> <in var>... "
                        "-- <out var>...\n");
        return 2;
    }
    const char *dir = argv[1], *identifier = argv[2], *token = argv[3], *mode = argv[4];
    char path[4096], resources[4200];
    snprintf(path, sizeof path, "%s/binaries/x86_64-linux/%s.so", dir, identifier);
    snprintf(resources, sizeof resources, "%s/resources/", dir);
    const char *null_resources = getenv("HOST_NULL_RESOURCES");
    const char *resource_path = null_resources && !strcmp(null_resources, "1") ? NULL : resources;
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
    if (!strcmp(mode, "se")) return scheduled(lib, resource_path, token, argc, argv);
    LOAD(fmi3InstantiateModelExchange) LOAD(fmi3InstantiateCoSimulation) LOAD(fmi3EnterInitializationMode)
    LOAD(fmi3ExitInitializationMode) LOAD(fmi3GetFloat64) LOAD(fmi3DoStep) LOAD(fmi3Terminate)
    LOAD(fmi3FreeInstance) LOAD(fmi3UpdateDiscreteStates) LOAD(fmi3EnterContinuousTimeMode)
    LOAD(fmi3EnterEventMode) LOAD(fmi3EnterStepMode) LOAD(fmi3GetContinuousStateDerivatives)
    LOAD(fmi3GetEventIndicators) LOAD(fmi3SetTime) LOAD(fmi3GetContinuousStates) LOAD(fmi3SetContinuousStates)
    LOAD(fmi3CompletedIntegratorStep) LOAD(fmi3GetNumberOfContinuousStates) LOAD(fmi3GetNumberOfEventIndicators)

    int me = !strcmp(mode, "me"), events = !strcmp(mode, "cs-events");
    fmi3Instance c = me ? fmi3InstantiateModelExchange("host3", token, resource_path, fmi3False, fmi3False, NULL,
                                                        log_message)
                        : fmi3InstantiateCoSimulation("host3", token, resource_path, fmi3False, fmi3False, events,
                                                       events, NULL, 0, NULL, log_message, NULL);
    if (!c) {
        fprintf(stderr, "fmi3Instantiate failed\n");
        return 4;
    }
    double stop = atof(argv[5]), h = atof(argv[6]);
    int nv = argc - 7;
    fmi3ValueReference *vrs = malloc(sizeof *vrs * (nv ? nv : 1));
    size_t n_values = 0;
    for (int i = 0; i < nv; i++) {
        char *colon = strchr(argv[7 + i], ':');
        vrs[i] = (fmi3ValueReference)atol(argv[7 + i]);
        n_values += colon ? (size_t)atol(colon + 1) : 1;
    }
    double *values = malloc(sizeof *values * (n_values ? n_values : 1));
    double t = 0.0;
    long steps = (long)llround(stop / h);

    OK(fmi3EnterInitializationMode(c, fmi3False, 0.0, 0.0, fmi3True, stop));
    OK(fmi3ExitInitializationMode(c));
    fmi3Boolean terminate = fmi3False, values_changed = fmi3False, next_defined = fmi3False;
    double next_time = 0.0;
    if (me || events) { /* both start in Event Mode */
        update_discrete_states(fmi3UpdateDiscreteStates, c, &terminate, &values_changed, &next_defined, &next_time);
        OK(me ? fmi3EnterContinuousTimeMode(c) : fmi3EnterStepMode(c));
    }
    OK(fmi3GetFloat64(c, vrs, nv, values, n_values));
    print_row(t, values, n_values);
    if (terminate) {
        printf("terminated,%.17g\n", t);
        steps = 0;
    }

    if (!me) {
        for (long k = 1; k <= steps;) {
            fmi3Boolean event = fmi3False, early = fmi3False;
            double reached = t;
            OK(fmi3DoStep(c, t, k * h - t, fmi3True, &event, &terminate, &early, &reached));
            t = reached;
            if (terminate) {
                OK(fmi3GetFloat64(c, vrs, nv, values, n_values));
                print_row(t, values, n_values);
                printf("terminated,%.17g\n", t);
                break;
            }
            if (event) {
                printf("event,%.17g\n", t);
                OK(fmi3EnterEventMode(c));
                update_discrete_states(fmi3UpdateDiscreteStates, c, &terminate, &values_changed, &next_defined,
                                       &next_time);
                if (terminate) {
                    OK(fmi3GetFloat64(c, vrs, nv, values, n_values));
                    print_row(t, values, n_values);
                    printf("terminated,%.17g\n", t);
                    break;
                }
                OK(fmi3EnterStepMode(c));
            }
            if (!early) { /* rows only on the output grid */
                OK(fmi3GetFloat64(c, vrs, nv, values, n_values));
                print_row(t, values, n_values);
                k++;
            }
        }
    } else {
        size_t nx, nz;
        OK(fmi3GetNumberOfContinuousStates(c, &nx));
        OK(fmi3GetNumberOfEventIndicators(c, &nz));
        double *x = calloc(nx + 1, sizeof *x), *dx = calloc(nx + 1, sizeof *dx);
        double *z = calloc(nz + 1, sizeof *z), *z_prev = calloc(nz + 1, sizeof *z_prev);
        OK(fmi3GetContinuousStates(c, x, nx));
        OK(fmi3GetEventIndicators(c, z_prev, nz));
        long k = 1;
        while (k <= steps) {
            double t_grid = k * h, t_next = t_grid;
            int time_event = next_defined && next_time <= t_grid;
            if (time_event) t_next = next_time;
            OK(fmi3GetContinuousStateDerivatives(c, dx, nx));
            for (size_t i = 0; i < nx; i++) x[i] += (t_next - t) * dx[i];
            t = t_next;
            OK(fmi3SetTime(c, t));
            OK(fmi3SetContinuousStates(c, x, nx));
            OK(fmi3GetEventIndicators(c, z, nz));
            int state_event = 0;
            for (size_t i = 0; i < nz; i++) state_event |= (z[i] > 0) != (z_prev[i] > 0);
            fmi3Boolean enter = fmi3False;
            OK(fmi3CompletedIntegratorStep(c, fmi3True, &enter, &terminate));
            if (!terminate && (state_event || time_event || enter)) {
                printf("event,%.17g\n", t);
                OK(fmi3EnterEventMode(c));
                update_discrete_states(fmi3UpdateDiscreteStates, c, &terminate, &values_changed, &next_defined,
                                       &next_time);
                if (!terminate) OK(fmi3EnterContinuousTimeMode(c));
                if (values_changed) OK(fmi3GetContinuousStates(c, x, nx));
                OK(fmi3GetEventIndicators(c, z, nz));
            }
            memcpy(z_prev, z, nz * sizeof(double));
            if (terminate) {
                OK(fmi3GetFloat64(c, vrs, nv, values, n_values));
                print_row(t, values, n_values);
                printf("terminated,%.17g\n", t);
                break;
            }
            if (t == t_grid) {
                OK(fmi3GetFloat64(c, vrs, nv, values, n_values));
                print_row(t, values, n_values);
                k++;
            }
        }
    }
    OK(fmi3Terminate(c));
    fmi3FreeInstance(c);
    return 0;
}
