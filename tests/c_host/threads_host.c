/* A plain-C FMI 2.0 importer that runs several Co-Simulation instances from several threads.
 *
 *   threads_host parallel|serial <stop> <step> <job>...
 *   <job> = <abs unzipdir> <identifier> <guid> <vr,vr,...>     (four arguments per job)
 *
 * parallel: one thread per job; each opens its FMU's binary, then all wait at a barrier and call
 * fmi2Instantiate at the same moment, then step to <stop> concurrently. serial: the same jobs one
 * after another on the main thread. Either way the results are printed afterwards, job by job:
 * "<job> <t> <value>..." with every digit, so two runs compare as text; stderr gets one line per job,
 * "timing job=<i> steps=<n> start=<s> end=<s>" (CLOCK_MONOTONIC around the stepping, for
 * benchmarks/threads.py), besides the FMUs' log messages. Jobs naming the same
 * unzipdir share one binary (two instances of one FMU); different unzipdirs load different
 * binaries, which share no static variables. Exit status 0 only if every job succeeded.
 */
#include <dlfcn.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "fmi2Functions.h"

typedef struct {
    const char *dir, *identifier, *guid;
    char name[32]; /* instance name: job<index> */
    fmi2ValueReference vrs[16];
    int n_vrs;
    double stop, step;
    long steps;
    double *rows; /* (steps + 1) x (1 + n_vrs) */
    double start, end; /* monotonic seconds around the stepping */
    char error[512];
} Job;

static pthread_barrier_t g_barrier;
static int g_parallel;

static double now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return ts.tv_sec + 1e-9 * ts.tv_nsec;
}

static void logger(fmi2ComponentEnvironment env, fmi2String instance, fmi2Status status, fmi2String category,
                   fmi2String message, ...) {
    (void)env;
    char text[4096];
    va_list ap;
    va_start(ap, message);
    vsnprintf(text, sizeof text, message, ap);
    va_end(ap);
    fprintf(stderr, "[%s|%d|%s] %s\n", instance, status, category, text); /* one call: lines stay whole */
}

#define LOAD(name)                                                                  \
    name##TYPE *name = (name##TYPE *)dlsym(lib, #name);                            \
    if (!name) {                                                                    \
        snprintf(job->error, sizeof job->error, "missing %s", #name);               \
        return NULL;                                                                \
    }

#define CALL(call)                                                                                \
    do {                                                                                          \
        fmi2Status s_ = (call);                                                                   \
        if (s_ > fmi2Warning) {                                                                   \
            snprintf(job->error, sizeof job->error, "%s failed with status %d", #call, (int)s_);  \
            return NULL;                                                                          \
        }                                                                                         \
    } while (0)

static void *run_job(void *argument) {
    Job *job = argument;
    char path[4096], uri[4200];
    snprintf(path, sizeof path, "%s/binaries/linux64/%s.so", job->dir, job->identifier);
    snprintf(uri, sizeof uri, "file://%s/resources", job->dir);
    void *lib = dlopen(path, RTLD_NOW | RTLD_LOCAL);
    if (g_parallel) pthread_barrier_wait(&g_barrier); /* before any early return: no thread waits forever */
    if (!lib) {
        snprintf(job->error, sizeof job->error, "dlopen: %s", dlerror());
        return NULL;
    }
    LOAD(fmi2Instantiate) LOAD(fmi2SetupExperiment) LOAD(fmi2EnterInitializationMode)
    LOAD(fmi2ExitInitializationMode) LOAD(fmi2GetReal) LOAD(fmi2DoStep) LOAD(fmi2Terminate) LOAD(fmi2FreeInstance)
    fmi2CallbackFunctions cb = {logger, calloc, free, NULL, NULL};
    fmi2Component c = fmi2Instantiate(job->name, fmi2CoSimulation, job->guid, uri, &cb, fmi2False, fmi2False);
    if (!c) {
        snprintf(job->error, sizeof job->error, "fmi2Instantiate returned NULL");
        return NULL;
    }
    CALL(fmi2SetupExperiment(c, fmi2False, 0.0, 0.0, fmi2True, job->stop));
    CALL(fmi2EnterInitializationMode(c));
    CALL(fmi2ExitInitializationMode(c));
    int width = 1 + job->n_vrs;
    double t = 0.0;
    job->rows[0] = t;
    CALL(fmi2GetReal(c, job->vrs, (size_t)job->n_vrs, job->rows + 1));
    job->start = now();
    for (long k = 1; k <= job->steps; k++) {
        CALL(fmi2DoStep(c, t, job->step, fmi2True));
        t = k * job->step;
        job->rows[k * width] = t;
        CALL(fmi2GetReal(c, job->vrs, (size_t)job->n_vrs, job->rows + k * width + 1));
    }
    job->end = now();
    CALL(fmi2Terminate(c));
    fmi2FreeInstance(c);
    return NULL;
}

int main(int argc, char **argv) {
    if (argc < 8 || (argc - 4) % 4 != 0 || (strcmp(argv[1], "parallel") && strcmp(argv[1], "serial"))) {
        fprintf(stderr, "usage: threads_host parallel|serial <stop> <step> (<unzipdir> <identifier> <guid> "
                        "<vr,vr,...>)...\n");
        return 2;
    }
    g_parallel = !strcmp(argv[1], "parallel");
    double stop = atof(argv[2]), step = atof(argv[3]);
    int n = (argc - 4) / 4;
    Job *jobs = calloc((size_t)n, sizeof *jobs);
    pthread_t *threads = calloc((size_t)n, sizeof *threads);
    for (int i = 0; i < n; i++) {
        Job *job = &jobs[i];
        char **a = argv + 4 + 4 * i;
        snprintf(job->name, sizeof job->name, "job%d", i);
        job->dir = a[0];
        job->identifier = a[1];
        job->guid = a[2];
        for (char *p = a[3]; *p && job->n_vrs < 16; p += strcspn(p, ","), p += *p == ',')
            job->vrs[job->n_vrs++] = (fmi2ValueReference)strtoul(p, NULL, 10);
        job->stop = stop;
        job->step = step;
        job->steps = lround(stop / step);
        job->rows = calloc((size_t)(job->steps + 1) * (size_t)(1 + job->n_vrs), sizeof(double));
    }
    if (g_parallel) {
        pthread_barrier_init(&g_barrier, NULL, (unsigned)n);
        for (int i = 0; i < n; i++) pthread_create(&threads[i], NULL, run_job, &jobs[i]);
        for (int i = 0; i < n; i++) pthread_join(threads[i], NULL);
    } else {
        for (int i = 0; i < n; i++) run_job(&jobs[i]);
    }
    int failed = 0;
    for (int i = 0; i < n; i++) {
        Job *job = &jobs[i];
        if (job->error[0]) {
            fprintf(stderr, "job %d (%s): %s\n", i, job->identifier, job->error);
            failed = 1;
            continue;
        }
        fprintf(stderr, "timing job=%d steps=%ld start=%.9f end=%.9f\n", i, job->steps, job->start, job->end);
        for (long k = 0; k <= job->steps; k++) {
            printf("%d", i);
            for (int j = 0; j <= job->n_vrs; j++) printf(" %.17g", job->rows[k * (1 + job->n_vrs) + j]);
            printf("\n");
        }
    }
    return failed;
}
