/* An FMI 3.0 Co-Simulation importer in plain C with the standard's event mode and early return,
 * stepping as the Reference FMUs' fmusim does (no Python in this process):
 *
 *   fmi3_cs_events <unzipdir> <identifier> <token> <eventModeUsed 0|1> <earlyReturnAllowed 0|1>
 *                  <stop> <step> <var>...
 *
 * <var> is a Float64 value reference, or i<vr> for an Int32 one (values printed in that order).
 * The communication points are start + k * step. After each fmi3DoStep the host continues from
 * lastSuccessfulTime where the FMU returned early (earlyReturn), else from the communication
 * point, and prints
 *     step,<t>,<eventHandlingNeeded>,<earlyReturn>,<values>...
 * With eventModeUsed, where the FMU asked for event handling, it runs Event Mode at that time
 * (fmi3EnterEventMode, fmi3UpdateDiscreteStates until no update is needed, fmi3EnterStepMode)
 * and prints the values after it:
 *     event,<t>,<values>...
 * It does the same after fmi3ExitInitializationMode (the FMU is in Event Mode then) without a
 * row. A component that ends the simulation: "terminated,<t>". An FMU that returns early
 * although early return was not allowed fails the run (exit 5), as fmusim does.
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

static void log_message(fmi3InstanceEnvironment env, fmi3Status status, fmi3String category, fmi3String message) {
    (void)env;
    fprintf(stderr, "[%d|%s] %s\n", status, category, message);
}

typedef struct {
    fmi3GetFloat64TYPE *get_float64;
    fmi3GetInt32TYPE *get_int32;
    fmi3ValueReference *vrs;
    int *is_int, n;
} Outputs;

static void print_values(fmi3Instance c, const Outputs *o) {
    for (int i = 0; i < o->n; i++) {
        if (o->is_int[i]) {
            fmi3Int32 v;
            OK(o->get_int32(c, &o->vrs[i], 1, &v, 1));
            printf(",%d", (int)v);
        } else {
            fmi3Float64 v;
            OK(o->get_float64(c, &o->vrs[i], 1, &v, 1));
            printf(",%.17g", v);
        }
    }
    printf("\n");
}

/* Event Mode's iteration: fmi3UpdateDiscreteStates until the FMU needs no more updates. */
static fmi3Boolean update_discrete_states(fmi3UpdateDiscreteStatesTYPE *update, fmi3Instance c) {
    fmi3Boolean need_update = fmi3True, terminate = fmi3False, nominals_changed, values_changed, next_defined;
    fmi3Float64 next_time;
    while (need_update && !terminate)
        OK(update(c, &need_update, &terminate, &nominals_changed, &values_changed, &next_defined, &next_time));
    return terminate;
}

int main(int argc, char **argv) {
    if (argc < 8) {
        fprintf(stderr, "usage: fmi3_cs_events <unzipdir> <identifier> <token> <eventModeUsed 0|1> "
                        "<earlyReturnAllowed 0|1> <stop> <step> <var>...\n");
        return 2;
    }
    const char *dir = argv[1], *identifier = argv[2], *token = argv[3];
    fmi3Boolean event_mode_used = atoi(argv[4]) != 0, early_return_allowed = atoi(argv[5]) != 0;
    double stop = atof(argv[6]), step = atof(argv[7]), start = 0.0;
    char path[4096], resources[4200];
    snprintf(path, sizeof path, "%s/binaries/x86_64-linux/%s.so", dir, identifier);
    snprintf(resources, sizeof resources, "%s/resources/", dir);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
    LOAD(fmi3InstantiateCoSimulation) LOAD(fmi3EnterInitializationMode) LOAD(fmi3ExitInitializationMode)
    LOAD(fmi3GetFloat64) LOAD(fmi3GetInt32) LOAD(fmi3DoStep) LOAD(fmi3Terminate) LOAD(fmi3FreeInstance)
    LOAD(fmi3UpdateDiscreteStates) LOAD(fmi3EnterEventMode) LOAD(fmi3EnterStepMode)

    Outputs out = {fmi3GetFloat64, fmi3GetInt32, NULL, NULL, argc - 8};
    out.vrs = malloc(sizeof *out.vrs * (out.n ? out.n : 1));
    out.is_int = malloc(sizeof *out.is_int * (out.n ? out.n : 1));
    for (int i = 0; i < out.n; i++) {
        const char *arg = argv[8 + i];
        out.is_int[i] = arg[0] == 'i';
        out.vrs[i] = (fmi3ValueReference)atol(arg + out.is_int[i]);
    }

    fmi3Instance c = fmi3InstantiateCoSimulation("fmi3_cs_events", token, resources, fmi3False, fmi3False,
                                                 event_mode_used, early_return_allowed, NULL, 0, NULL,
                                                 log_message, NULL);
    if (!c) {
        fprintf(stderr, "fmi3InstantiateCoSimulation failed\n");
        return 4;
    }
    OK(fmi3EnterInitializationMode(c, fmi3False, 0.0, start, fmi3True, stop));
    OK(fmi3ExitInitializationMode(c));
    if (event_mode_used) { /* the FMU is in Event Mode after initialization */
        if (update_discrete_states(fmi3UpdateDiscreteStates, c)) {
            printf("terminated,%.17g\n", start);
            goto done;
        }
        OK(fmi3EnterStepMode(c));
    }
    printf("step,%.17g,0,0", start);
    print_values(c, &out);

    double time = start;
    long n_steps = 0;
    while (time < stop && fabs(time - stop) > 1e-12 * fmax(1.0, fabs(stop))) {
        double next_regular_point = start + (n_steps + 1) * step;
        fmi3Boolean event = fmi3False, terminate = fmi3False, early = fmi3False;
        fmi3Float64 last_successful_time = time;
        OK(fmi3DoStep(c, time, next_regular_point - time, fmi3True, &event, &terminate, &early,
                      &last_successful_time));
        if (early && !early_return_allowed) {
            fprintf(stderr, "the FMU returned early from fmi3DoStep, which was not allowed\n");
            return 5;
        }
        time = early && last_successful_time < next_regular_point ? last_successful_time : next_regular_point;
        if (time == next_regular_point) n_steps++;
        printf("step,%.17g,%d,%d", time, event != 0, early != 0);
        print_values(c, &out);
        if (terminate) {
            printf("terminated,%.17g\n", time);
            break;
        }
        if (event_mode_used && event) {
            OK(fmi3EnterEventMode(c));
            if (update_discrete_states(fmi3UpdateDiscreteStates, c)) {
                printf("terminated,%.17g\n", time);
                break;
            }
            OK(fmi3EnterStepMode(c));
            printf("event,%.17g", time);
            print_values(c, &out);
        }
    }
done:
    OK(fmi3Terminate(c));
    fmi3FreeInstance(c);
    free(out.vrs);
    free(out.is_int);
    return 0;
}
