/* A minimal FMI 2.0 importer in plain C, used by the tests: no Python in this process.
 *
 *   host <unzipdir> <identifier> <guid> cs    <stop> <step> <vr>...   Co-Simulation, prints t,values
 *   host <unzipdir> <identifier> <guid> me    <stop> <step> <vr>...   explicit Euler + event handling
 *   host <unzipdir> <identifier> <guid> bench <n> <input vr> <output vr>  us per set/get/doStep call
 *   host <unzipdir> <identifier> <guid> error                         drive a failing instance
 *
 * Built with sundials_preload.c, it first solves an ODE with its own SUNDIALS (a hostile host).
 *
 * Logging: HOST_LOGGING_ON=1 instantiates with loggingOn = true; HOST_DEBUG_LOGGING="<0|1>:<a,b,...>"
 * then calls fmi2SetDebugLogging(loggingOn, categories) (no names: nCategories = 0). A component
 * that ends the simulation (cs: fmi2Discard + fmi2Terminated, me: terminateSimulation) gets its
 * last row printed and "terminated,<time>".
 */
#include <dlfcn.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"

#define LOAD(name) name##TYPE *name = (name##TYPE *)dlsym(lib, #name); \
    if (!name) { fprintf(stderr, "missing %s\n", #name); exit(2); }

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env;
    fprintf(stderr, "[%s|%d|%s] ", instance, status, category);
    va_list ap;
    va_start(ap, message);
    vfprintf(stderr, message, ap);
    va_end(ap);
    fputc('\n', stderr);
}

/* defined by sundials_preload.c in the hostile build; absent (NULL) otherwise */
void host_preload(void) __attribute__((weak));

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

#define OK(call) do { fmi2Status s_ = (call); if (s_ > fmi2Warning) { \
    fprintf(stderr, "%s failed with status %d\n", #call, s_); exit(3); } } while (0)

static void print_row(double t, const double *values, int n) {
    printf("%.17g", t);
    for (int i = 0; i < n; i++) printf(",%.17g", values[i]);
    printf("\n");
}

int main(int argc, char **argv) {
    if (argc < 5) {
        fprintf(stderr, "usage: host <unzipdir> <identifier> <guid> cs|me|restore|bench|error ...\n");
        return 2;
    }
    const char *dir = argv[1], *identifier = argv[2], *guid = argv[3], *mode = argv[4];
    char path[4096], uri[4200];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, identifier);
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    if (host_preload) host_preload();
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
    LOAD(fmi2Instantiate) LOAD(fmi2SetupExperiment) LOAD(fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationMode) LOAD(fmi2GetReal) LOAD(fmi2SetReal) LOAD(fmi2DoStep)
    LOAD(fmi2Terminate) LOAD(fmi2FreeInstance) LOAD(fmi2NewDiscreteStates) LOAD(fmi2EnterContinuousTimeMode)
    LOAD(fmi2EnterEventMode) LOAD(fmi2GetDerivatives) LOAD(fmi2GetEventIndicators) LOAD(fmi2SetTime)
    LOAD(fmi2GetContinuousStates) LOAD(fmi2SetContinuousStates) LOAD(fmi2CompletedIntegratorStep)
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    int me = !strcmp(mode, "me");
    const char *logging_on = getenv("HOST_LOGGING_ON"), *debug_logging = getenv("HOST_DEBUG_LOGGING");
    fmi2Component c = fmi2Instantiate("host", me ? fmi2ModelExchange : fmi2CoSimulation, guid, uri, &cb,
                                      fmi2False, logging_on && !strcmp(logging_on, "1"));
    if (!c) {
        fprintf(stderr, "fmi2Instantiate failed\n");
        return 4;
    }
    if (debug_logging && debug_logging[0] && debug_logging[1] == ':') {
        LOAD(fmi2SetDebugLogging)
        char names[1024];
        const char *categories[32];
        size_t n_categories = 0;
        snprintf(names, sizeof names, "%s", debug_logging + 2);
        for (char *name = strtok(names, ","); name && n_categories < 32; name = strtok(NULL, ","))
            categories[n_categories++] = name;
        printf("setDebugLogging=%d\n", fmi2SetDebugLogging(c, debug_logging[0] == '1', n_categories, categories));
    }

    if (!strcmp(mode, "error")) {
        /* wrong-state call, then a step whose Python code raises: both must return fmi2Error */
        double x;
        fmi2ValueReference vr0 = 0;
        printf("getReal_before_init=%d\n", fmi2GetReal(c, &vr0, 1, &x));
        fmi2FreeInstance(c);
        c = fmi2Instantiate("host2", fmi2CoSimulation, guid, uri, &cb, fmi2False, fmi2False);
        OK(fmi2SetupExperiment(c, fmi2False, 0, 0, fmi2False, 0));
        OK(fmi2EnterInitializationMode(c));
        OK(fmi2ExitInitializationMode(c));
        printf("doStep_negative=%d\n", fmi2DoStep(c, 0.0, -1.0, fmi2True));
        fmi2FreeInstance(c);
        printf("alive\n");
        return 0;
    }

    OK(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
    OK(fmi2EnterInitializationMode(c));
    OK(fmi2ExitInitializationMode(c));

    if (!strcmp(mode, "bench")) {
        long n = atol(argv[5]);
        fmi2ValueReference in = (fmi2ValueReference)atol(argv[6]), out = (fmi2ValueReference)atol(argv[7]);
        double u = 1.0, y = 0.0, t = 0.0, h = 1e-3;
        double t0 = now();
        for (long i = 0; i < n; i++) {
            u = 1.0 + 1e-9 * i;
            OK(fmi2SetReal(c, &in, 1, &u));
        }
        double t1 = now();
        for (long i = 0; i < n; i++) OK(fmi2GetReal(c, &out, 1, &y));
        double t2 = now();
        for (long i = 0; i < n; i++) {
            OK(fmi2DoStep(c, t, h, fmi2True));
            t += h;
        }
        double t3 = now();
        for (long i = 0; i < n; i++) {
            OK(fmi2SetReal(c, &in, 1, &u));
            OK(fmi2DoStep(c, t, h, fmi2True));
            OK(fmi2GetReal(c, &out, 1, &y));
            t += h;
        }
        double t4 = now();
        printf("set_us=%.4f\nget_us=%.4f\ndostep_us=%.4f\nstep_us=%.4f\ny=%.17g\n", 1e6 * (t1 - t0) / n,
               1e6 * (t2 - t1) / n, 1e6 * (t3 - t2) / n, 1e6 * (t4 - t3) / n, y);
        fmi2Terminate(c);
        fmi2FreeInstance(c);
        return 0;
    }

    double stop = atof(argv[5]), h = atof(argv[6]);
    int n = argc - 7;
    fmi2ValueReference *vrs = malloc(sizeof *vrs * (n ? n : 1));
    double *values = malloc(sizeof *values * (n ? n : 1));
    for (int i = 0; i < n; i++) vrs[i] = (fmi2ValueReference)atol(argv[7 + i]);
    double t = 0.0;
    long steps = (long)llround(stop / h);

    if (!strcmp(mode, "restore")) {
        /* Co-Simulation; an FMU state taken halfway, the steps to the end, fmi2Terminate, then the
         * state set again and the second half stepped once more (rows "again,..."): a state taken
         * before fmi2Terminate puts the instance back where it was */
        LOAD(fmi2GetFMUstate) LOAD(fmi2SetFMUstate) LOAD(fmi2FreeFMUstate)
        fmi2FMUstate state = NULL;
        long half = steps / 2;
        for (long k = 1; k <= half; k++) OK(fmi2DoStep(c, (k - 1) * h, h, fmi2True));
        OK(fmi2GetFMUstate(c, &state));
        for (int pass = 0; pass < 2; pass++) {
            if (pass) {
                OK(fmi2Terminate(c));
                OK(fmi2SetFMUstate(c, state));
                printf("again\n");
            }
            for (long k = half + 1; k <= steps; k++) {
                OK(fmi2DoStep(c, (k - 1) * h, h, fmi2True));
                OK(fmi2GetReal(c, vrs, n, values));
                print_row(k * h, values, n);
            }
        }
        OK(fmi2FreeFMUstate(c, &state));
        OK(fmi2Terminate(c));
        fmi2FreeInstance(c);
        return 0;
    }

    if (!me) {
        OK(fmi2GetReal(c, vrs, n, values));
        print_row(t, values, n);
        for (long k = 1; k <= steps; k++) {
            fmi2Status stepped = fmi2DoStep(c, t, h, fmi2True);
            if (stepped == fmi2Discard) {
                LOAD(fmi2GetBooleanStatus) LOAD(fmi2GetRealStatus)
                fmi2Boolean ended = fmi2False;
                OK(fmi2GetBooleanStatus(c, fmi2Terminated, &ended));
                if (!ended) OK(stepped);
                OK(fmi2GetRealStatus(c, fmi2LastSuccessfulTime, &t));
                OK(fmi2GetReal(c, vrs, n, values));
                print_row(t, values, n);
                printf("terminated,%.17g\n", t);
                break;
            }
            OK(stepped);
            t = k * h;
            OK(fmi2GetReal(c, vrs, n, values));
            print_row(t, values, n);
        }
    } else {
        /* states and indicators are few in the test models; size generously */
        enum { NX = 64, NZ = 64 };
        double x[NX], dx[NX], z[NZ], z_prev[NZ];
        size_t nx = (size_t)atol(getenv("HOST_NX") ? getenv("HOST_NX") : "0");
        size_t nz = (size_t)atol(getenv("HOST_NZ") ? getenv("HOST_NZ") : "0");
        fmi2EventInfo info = {fmi2True, fmi2False, fmi2False, fmi2False, fmi2False, 0.0};
        while (info.newDiscreteStatesNeeded && !info.terminateSimulation) OK(fmi2NewDiscreteStates(c, &info));
        if (info.terminateSimulation) {
            printf("terminated,%.17g\n", t);
            steps = 0;
        }
        OK(fmi2EnterContinuousTimeMode(c));
        OK(fmi2GetContinuousStates(c, x, nx));
        OK(fmi2GetEventIndicators(c, z_prev, nz));
        OK(fmi2GetReal(c, vrs, n, values));
        print_row(t, values, n);
        long k = 1;
        while (k <= steps) {
            double t_grid = k * h, t_next = t_grid;
            int time_event = info.nextEventTimeDefined && info.nextEventTime <= t_grid;
            if (time_event) t_next = info.nextEventTime;
            OK(fmi2GetDerivatives(c, dx, nx));
            for (size_t i = 0; i < nx; i++) x[i] += (t_next - t) * dx[i];
            t = t_next;
            OK(fmi2SetTime(c, t));
            OK(fmi2SetContinuousStates(c, x, nx));
            OK(fmi2GetEventIndicators(c, z, nz));
            int state_event = 0;
            for (size_t i = 0; i < nz; i++) state_event |= (z[i] > 0) != (z_prev[i] > 0);
            fmi2Boolean enter = fmi2False, terminate = fmi2False;
            OK(fmi2CompletedIntegratorStep(c, fmi2True, &enter, &terminate));
            if (!terminate && (state_event || time_event || enter)) {
                OK(fmi2EnterEventMode(c));
                info.newDiscreteStatesNeeded = fmi2True;
                while (info.newDiscreteStatesNeeded && !info.terminateSimulation) OK(fmi2NewDiscreteStates(c, &info));
                terminate = info.terminateSimulation;
                if (!terminate) OK(fmi2EnterContinuousTimeMode(c));
                if (info.valuesOfContinuousStatesChanged) OK(fmi2GetContinuousStates(c, x, nx));
                OK(fmi2GetEventIndicators(c, z, nz));
            }
            memcpy(z_prev, z, nz * sizeof(double));
            if (terminate) {
                OK(fmi2GetReal(c, vrs, n, values));
                print_row(t, values, n);
                printf("terminated,%.17g\n", t);
                break;
            }
            if (t == t_grid) { /* rows only on the output grid */
                OK(fmi2GetReal(c, vrs, n, values));
                print_row(t, values, n);
                k++;
            }
        }
    }
    OK(fmi2Terminate(c));
    fmi2FreeInstance(c);
    return 0;
}
