/* A plain-C FMI 2.0 host for benchmarks/cs_native.py: no Python in this process (the FMU starts its own).
 *
 *   cs_host <unzipdir> <identifier> <guid> cs <steps> <h> <vr>...
 *       Co-Simulation: fmi2DoStep over <steps> steps of <h>, the outputs read after each step
 *   cs_host <unzipdir> <identifier> <guid> me <steps> <h> <rtol> <atol factor> <sundials dir> <vr>...
 *       Model Exchange integrated by this host's own CVODE (BDF, dense Newton, difference-quotient
 *       Jacobian, root finding on the event indicators; atol_i = factor * nominal_i), stopping at
 *       every communication point as a co-simulation master would, events handled as an ME importer
 *       does (fmi2CompletedIntegratorStep, roots, time events: event mode, fmi2NewDiscreteStates,
 *       CVodeReInit).
 *
 * Prints "us_per_step,<microseconds>" (the stepping loop only, instantiation and initialization
 * excluded, and cs's first step, which makes the FMU's solver, printed apart as "first_step_us,<us>")
 * and "cpu_us_per_step,<microseconds>" (the CPU time of the stepping thread over the same loop), then the last row "t,values..." and "rows,<n>". SUNDIALS is opened from <sundials dir>
 * (its libraries by their plain names) and called through the prototypes below (SUNDIALS 7). */
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
#define OK(call) do { fmi2Status s_ = (call); if (s_ > fmi2Warning) { \
    fprintf(stderr, "%s failed with status %d\n", #call, s_); exit(3); } } while (0)


static void log_message(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                        fmi2String message, ...) {
    (void)env;
    if (status < fmi2Warning) return;
    fprintf(stderr, "[%s|%d|%s] ", instance, status, category);
    va_list ap;
    va_start(ap, message);
    vfprintf(stderr, message, ap);
    va_end(ap);
    fputc('\n', stderr);
}

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* this thread's CPU time: on a loaded machine the wall clock also counts the time others ran */
static double cpu_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

/* ---- the SUNDIALS 7 functions this host calls ---- */
typedef int (*RhsFn)(double t, void *y, void *ydot, void *user);
typedef int (*RootFn)(double t, void *y, double *g, void *user);
static struct {
    int (*SUNContext_Create)(int comm, void **ctx);
    void *(*N_VNew_Serial)(long long n, void *ctx);
    double *(*N_VGetArrayPointer)(void *v);
    void *(*CVodeCreate)(int lmm, void *ctx);
    int (*CVodeInit)(void *mem, RhsFn f, double t0, void *y0);
    int (*CVodeSVtolerances)(void *mem, double rtol, void *atol);
    int (*CVodeRootInit)(void *mem, int nrtfn, RootFn g);
    void *(*SUNDenseMatrix)(long long m, long long n, void *ctx);
    void *(*SUNLinSol_Dense)(void *y, void *A, void *ctx);
    int (*CVodeSetLinearSolver)(void *mem, void *LS, void *A);
    int (*CVodeSetUserData)(void *mem, void *user);
    int (*CVodeSetMaxNumSteps)(void *mem, long n);
    int (*CVodeSetStopTime)(void *mem, double t);
    int (*CVodeSetNoInactiveRootWarn)(void *mem);
    int (*CVode)(void *mem, double tout, void *y, double *tret, int itask);
    int (*CVodeReInit)(void *mem, double t0, void *y0);
} sun;

static void *open_sundials(const char *dir, const char *name) {
    char path[4096];
    snprintf(path, sizeof path, "%s/lib%s.so", dir, name);
    void *h = dlopen(path, RTLD_NOW | RTLD_GLOBAL);
    if (!h) {
        snprintf(path, sizeof path, "%s/%s.so", dir, name);
        h = dlopen(path, RTLD_NOW | RTLD_GLOBAL);
    }
    if (!h) {
        fprintf(stderr, "dlopen %s: %s\n", name, dlerror());
        exit(2);
    }
    return h;
}

#define SUN(lib, name) if (!(*(void **)&sun.name = dlsym(lib, #name))) { fprintf(stderr, "missing %s\n", #name); exit(2); }

static void load_sundials(const char *dir) {
    void *core = open_sundials(dir, "sundials_core"), *nvec = open_sundials(dir, "sundials_nvecserial");
    void *mat = open_sundials(dir, "sundials_sunmatrixdense"), *ls = open_sundials(dir, "sundials_sunlinsoldense");
    void *cv = open_sundials(dir, "sundials_cvode");
    SUN(core, SUNContext_Create) SUN(nvec, N_VNew_Serial) SUN(nvec, N_VGetArrayPointer) SUN(mat, SUNDenseMatrix)
    SUN(ls, SUNLinSol_Dense) SUN(cv, CVodeCreate) SUN(cv, CVodeInit) SUN(cv, CVodeSVtolerances)
    SUN(cv, CVodeRootInit) SUN(cv, CVodeSetLinearSolver) SUN(cv, CVodeSetUserData) SUN(cv, CVodeSetMaxNumSteps)
    SUN(cv, CVodeSetStopTime) SUN(cv, CVodeSetNoInactiveRootWarn) SUN(cv, CVode) SUN(cv, CVodeReInit)
}

/* ---- Model Exchange callbacks ---- */
typedef struct {
    fmi2Component c;
    size_t nx, nz;
    fmi2SetTimeTYPE *setTime;
    fmi2SetContinuousStatesTYPE *setStates;
    fmi2GetDerivativesTYPE *getDerivatives;
    fmi2GetEventIndicatorsTYPE *getIndicators;
} Model;

static int rhs(double t, void *y, void *ydot, void *user) {
    Model *m = user;
    if (m->setTime(m->c, t) > fmi2Warning || m->setStates(m->c, sun.N_VGetArrayPointer(y), m->nx) > fmi2Warning ||
        m->getDerivatives(m->c, sun.N_VGetArrayPointer(ydot), m->nx) > fmi2Warning)
        return -1;
    return 0;
}

static int roots(double t, void *y, double *g, void *user) {
    Model *m = user;
    if (m->setTime(m->c, t) > fmi2Warning || m->setStates(m->c, sun.N_VGetArrayPointer(y), m->nx) > fmi2Warning ||
        m->getIndicators(m->c, g, m->nz) > fmi2Warning)
        return -1;
    return 0;
}

static void print_row(double t, const double *values, int n) {
    printf("%.17g", t);
    for (int i = 0; i < n; i++) printf(",%.17g", values[i]);
    printf("\n");
}

int main(int argc, char **argv) {
    if (argc < 7) {
        fprintf(stderr, "usage: cs_host <unzipdir> <identifier> <guid> cs|me <steps> <h> ...\n");
        return 2;
    }
    const char *dir = argv[1], *identifier = argv[2], *guid = argv[3], *mode = argv[4];
    long steps = atol(argv[5]);
    double h = atof(argv[6]);
    int me = !strcmp(mode, "me"), first_vr = me ? 10 : 7;
    if (me && argc < 10) {
        fprintf(stderr, "me needs <rtol> <atol factor> <sundials dir>\n");
        return 2;
    }
    char path[4096], uri[4200];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", dir, identifier);
    snprintf(uri, sizeof uri, "file://%s/resources", dir);
    if (me) load_sundials(argv[9]);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (!lib) {
        fprintf(stderr, "dlopen: %s\n", dlerror());
        return 2;
    }
    LOAD(fmi2Instantiate) LOAD(fmi2SetupExperiment) LOAD(fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationMode) LOAD(fmi2GetReal) LOAD(fmi2DoStep) LOAD(fmi2FreeInstance)
    LOAD(fmi2NewDiscreteStates) LOAD(fmi2EnterContinuousTimeMode) LOAD(fmi2EnterEventMode) LOAD(fmi2GetDerivatives)
    LOAD(fmi2GetEventIndicators) LOAD(fmi2SetTime) LOAD(fmi2GetContinuousStates) LOAD(fmi2SetContinuousStates)
    LOAD(fmi2CompletedIntegratorStep) LOAD(fmi2GetNominalsOfContinuousStates)
    int n_out = argc - first_vr;
    fmi2ValueReference vrs[64];
    double values[64];
    for (int i = 0; i < n_out && i < 64; i++) vrs[i] = (fmi2ValueReference)atol(argv[first_vr + i]);
    fmi2CallbackFunctions cb = {log_message, calloc, free, NULL, NULL};
    fmi2Component c = fmi2Instantiate("bench", me ? fmi2ModelExchange : fmi2CoSimulation, guid, uri, &cb, fmi2False,
                                      fmi2False);
    if (!c) {
        fprintf(stderr, "fmi2Instantiate failed\n");
        return 4;
    }
    OK(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2False, 0.0));
    OK(fmi2EnterInitializationMode(c));
    OK(fmi2ExitInitializationMode(c));
    double t = 0.0, start, elapsed, cpu_start, cpu;
    long rows = 0;
    if (!me) {
        /* the first step makes the FMU's solver (as the ME run makes its own before its loop): timed apart */
        double first = now();
        OK(fmi2DoStep(c, t, h, fmi2True));
        t = h;
        printf("first_step_us,%.6g\n", (now() - first) * 1e6);
        start = now();
        cpu_start = cpu_now();
        for (long i = 1; i < steps; i++) {
            OK(fmi2DoStep(c, t, h, fmi2True));
            t = (i + 1) * h;
            OK(fmi2GetReal(c, vrs, n_out, values));
            rows++;
        }
        elapsed = now() - start;
        cpu = cpu_now() - cpu_start;
    } else {
        fmi2EventInfo info = {fmi2True, fmi2False, fmi2False, fmi2False, fmi2False, 0.0};
        while (info.newDiscreteStatesNeeded && !info.terminateSimulation) OK(fmi2NewDiscreteStates(c, &info));
        OK(fmi2EnterContinuousTimeMode(c));
        /* the counts from the model description would do as well: the FMU says them by failing otherwise */
        Model m = {c, (size_t)atol(getenv("CS_HOST_NX") ? getenv("CS_HOST_NX") : "0"),
                   (size_t)atol(getenv("CS_HOST_NZ") ? getenv("CS_HOST_NZ") : "0"), fmi2SetTime,
                   fmi2SetContinuousStates, fmi2GetDerivatives, fmi2GetEventIndicators};
        void *ctx = NULL;
        sun.SUNContext_Create(0, &ctx);
        void *y = sun.N_VNew_Serial((long long)m.nx, ctx), *atol_v = sun.N_VNew_Serial((long long)m.nx, ctx);
        double *x = sun.N_VGetArrayPointer(y), *atol_x = sun.N_VGetArrayPointer(atol_v);
        OK(fmi2GetContinuousStates(c, x, m.nx));
        OK(fmi2GetNominalsOfContinuousStates(c, atol_x, m.nx));
        double rtol = atof(argv[7]), factor = atof(argv[8]);
        for (size_t i = 0; i < m.nx; i++) atol_x[i] *= factor;
        void *mem = sun.CVodeCreate(2 /* CV_BDF */, ctx);
        void *A = sun.SUNDenseMatrix((long long)m.nx, (long long)m.nx, ctx);
        void *LS = sun.SUNLinSol_Dense(y, A, ctx);
        if (sun.CVodeInit(mem, rhs, t, y) || sun.CVodeSVtolerances(mem, rtol, atol_v) ||
            sun.CVodeSetLinearSolver(mem, LS, A) || sun.CVodeSetUserData(mem, &m) ||
            sun.CVodeSetMaxNumSteps(mem, 100000) || (m.nz && sun.CVodeRootInit(mem, (int)m.nz, roots)) ||
            sun.CVodeSetNoInactiveRootWarn(mem)) {
            fprintf(stderr, "CVODE setup failed\n");
            return 3;
        }
        start = now();
        cpu_start = cpu_now();
        for (long i = 0; i < steps; i++) {
            double t_next = (i + 1) * h;
            while (t < t_next) {
                double t_stop = info.nextEventTimeDefined && info.nextEventTime < t_next ? info.nextEventTime : t_next;
                double tret = t;
                int flag = t_stop > t ? (sun.CVodeSetStopTime(mem, t_stop), sun.CVode(mem, t_stop, y, &tret, 1)) : 0;
                if (flag < 0) {
                    fprintf(stderr, "CVODE failed with flag %d at t = %g\n", flag, tret);
                    return 3;
                }
                t = flag == 2 ? tret : t_stop;
                OK(fmi2SetTime(c, t));
                OK(fmi2SetContinuousStates(c, x, m.nx));
                fmi2Boolean step_event = fmi2False, terminate = fmi2False;
                OK(fmi2CompletedIntegratorStep(c, fmi2True, &step_event, &terminate));
                int time_event = info.nextEventTimeDefined && t >= info.nextEventTime;
                if (flag == 2 || time_event || step_event) {
                    OK(fmi2EnterEventMode(c));
                    info.newDiscreteStatesNeeded = fmi2True;
                    info.terminateSimulation = fmi2False;
                    while (info.newDiscreteStatesNeeded && !info.terminateSimulation)
                        OK(fmi2NewDiscreteStates(c, &info));
                    OK(fmi2EnterContinuousTimeMode(c));
                    OK(fmi2GetContinuousStates(c, x, m.nx));
                    sun.CVodeReInit(mem, t, y);
                }
            }
            OK(fmi2GetReal(c, vrs, n_out, values));
            rows++;
        }
        elapsed = now() - start;
        cpu = cpu_now() - cpu_start;
    }
    long timed = me ? steps : steps - 1;
    printf("us_per_step,%.6g\n", elapsed / (double)timed * 1e6);
    printf("cpu_us_per_step,%.6g\n", cpu / (double)timed * 1e6);
    OK(fmi2GetReal(c, vrs, n_out, values));
    print_row(t, values, n_out);
    printf("rows,%ld\n", rows);
    fmi2FreeInstance(c);
    return 0;
}
