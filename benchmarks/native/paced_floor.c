/* The machine's floor for a paced run: a bare C program (no Python in its process) that releases
 * `points` points due at start + k * period on CLOCK_MONOTONIC, each after a step that only burns
 * `busy` seconds of wall time, and writes how late each point came. What it counts late is what
 * the machine does to any paced loop: other processes' turns, the scheduler's ticks, a virtual
 * machine's host. benchmarks/realtime.py runs it beside the flagship's paced runs.
 *
 * How it waits (argv[1]):
 *   spin    polls the clock until the deadline (no sleep)
 *   sleep   clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME) to the deadline, nothing else
 *   hybrid  sleeps to the deadline less `spin` seconds (absolute), then polls: the master's C loop
 *           (deltafmi/master/stepping/native/fixed_step.c pace_to); with spin >= period it polls only
 * The schedule is absolute, as the master's: a late point is not made up by skipping.
 * The thread's timer slack is 1 ns (prctl PR_SET_TIMERSLACK). Options after OUT, any of:
 *   mlock      lock the process's memory first (mlockall) where permitted
 *   cpu=N      run on CPU N only (sched_setaffinity)
 *   fifo=N     run at real-time priority N (SCHED_FIFO)
 *   lead=S     a point may be released up to S seconds before its deadline (the master's
 *              master.realtime.lead, pace_to): a point due more than S from now is waited for
 *              until S/2 before its deadline, the points after it released as they are computed
 *              until one is again more than S ahead (steps computed ahead absorb stalls up to S/2)
 *   done=PATH  also write, per point, when the step before it finished computing, against the
 *              point's deadline (signed doubles: > 0 is a step that completed after its deadline)
 *
 * Usage: paced_floor spin|sleep|hybrid POINTS PERIOD BUSY SPIN OUT [mlock] [cpu=N] [fifo=N] [lead=S]
 * OUT: the signed lateness of each point as native doubles (release - deadline: negative = early,
 * only with a lead); stdout: "cpu wall mlock fifo" (seconds of CPU time and of wall time the loop
 * took, whether mlockall succeeded, whether the priority was set). Plain C99 + POSIX + Linux. */
#define _GNU_SOURCE
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#ifdef __linux__
#include <sched.h>
#include <sys/prctl.h>
#endif

static double clock_of(clockid_t id)
{
    struct timespec ts;
    clock_gettime(id, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double now(void) { return clock_of(CLOCK_MONOTONIC); }

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

int main(int argc, char **argv)
{
    if (argc < 7) {
        fprintf(stderr, "usage: paced_floor spin|sleep|hybrid POINTS PERIOD BUSY SPIN OUT [mlock]\n");
        return 2;
    }
    const char *mode = argv[1];
    long points = atol(argv[2]);
    double period = atof(argv[3]), busy = atof(argv[4]), spin = atof(argv[5]);
    int sleeps = strcmp(mode, "spin") != 0, polls = strcmp(mode, "sleep") != 0;
    if (!strcmp(mode, "sleep")) spin = 0.0;
    double *lateness = malloc((size_t)(points > 0 ? points : 1) * sizeof *lateness);
    double *done = malloc((size_t)(points > 0 ? points : 1) * sizeof *done);
    if (!lateness || !done) return 1;
    memset(lateness, 0, (size_t)(points > 0 ? points : 1) * sizeof *lateness); /* faulted in now */
    memset(done, 0, (size_t)(points > 0 ? points : 1) * sizeof *done);
    int locked = 0, fifo = 0;
    double lead = 0.0;
    const char *done_path = NULL;
    for (int i = 7; i < argc; i++) {
        if (!strcmp(argv[i], "mlock")) locked = mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
        else if (!strncmp(argv[i], "lead=", 5)) lead = atof(argv[i] + 5);
        else if (!strncmp(argv[i], "done=", 5)) done_path = argv[i] + 5;
#ifdef __linux__
        else if (!strncmp(argv[i], "cpu=", 4)) {
            cpu_set_t set;
            CPU_ZERO(&set);
            CPU_SET(atoi(argv[i] + 4), &set);
            if (sched_setaffinity(0, sizeof set, &set)) perror("sched_setaffinity");
        } else if (!strncmp(argv[i], "fifo=", 5)) {
            struct sched_param param = {.sched_priority = atoi(argv[i] + 5)};
            fifo = sched_setscheduler(0, SCHED_FIFO, &param) == 0;
        }
#endif
    }
#ifdef __linux__
    prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
#endif
    double cpu0 = clock_of(CLOCK_PROCESS_CPUTIME_ID), start = now();
    for (long k = 1; k <= points; k++) {
        double until = now() + busy;
        while (now() < until) {
        }
        double deadline = start + (double)k * period, t = now();
        done[k - 1] = t - deadline;
        if (t < deadline - lead) { /* as pace_to: more than the lead early: wait until half of it is left */
            double wake = deadline - lead / 2;
            if (sleeps && wake - t > spin) {
                sleep_until(wake - spin);
                t = now();
            }
            if (polls)
                while (t < wake) t = now();
        }
        lateness[k - 1] = t - deadline;
    }
    double wall = now() - start, cpu = clock_of(CLOCK_PROCESS_CPUTIME_ID) - cpu0;
    FILE *out = fopen(argv[6], "wb");
    if (!out || fwrite(lateness, sizeof *lateness, (size_t)points, out) != (size_t)points) return 1;
    fclose(out);
    if (done_path) {
        FILE *d = fopen(done_path, "wb");
        if (!d || fwrite(done, sizeof *done, (size_t)points, d) != (size_t)points) return 1;
        fclose(d);
    }
    printf("%.9f %.9f %d %d\n", cpu, wall, locked, fifo);
    return 0;
}
