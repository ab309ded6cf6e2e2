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
 * The thread's timer slack is 1 ns (prctl PR_SET_TIMERSLACK); "mlock" as the last argument locks
 * the process's memory first (mlockall) where permitted.
 *
 * Usage: paced_floor spin|sleep|hybrid POINTS PERIOD BUSY SPIN OUT [mlock]
 * OUT: the lateness of each point as native doubles; stdout: "cpu wall mlock" (seconds of CPU
 * time and of wall time the loop took, whether mlockall succeeded). Plain C99 + POSIX + Linux prctl. */
#define _GNU_SOURCE
#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <time.h>
#ifdef __linux__
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
    if (!lateness) return 1;
    memset(lateness, 0, (size_t)(points > 0 ? points : 1) * sizeof *lateness); /* faulted in now */
    int locked = argc > 7 && !strcmp(argv[7], "mlock") && mlockall(MCL_CURRENT | MCL_FUTURE) == 0;
#ifdef __linux__
    prctl(PR_SET_TIMERSLACK, 1UL, 0UL, 0UL, 0UL);
#endif
    double cpu0 = clock_of(CLOCK_PROCESS_CPUTIME_ID), start = now();
    for (long k = 1; k <= points; k++) {
        double until = now() + busy;
        while (now() < until) {
        }
        double deadline = start + (double)k * period, t = now();
        if (sleeps && deadline - t > spin) {
            sleep_until(deadline - spin);
            t = now();
        }
        if (polls)
            while (t < deadline) t = now();
        lateness[k - 1] = t > deadline ? t - deadline : 0.0;
    }
    double wall = now() - start, cpu = clock_of(CLOCK_PROCESS_CPUTIME_ID) - cpu0;
    FILE *out = fopen(argv[6], "wb");
    if (!out || fwrite(lateness, sizeof *lateness, (size_t)points, out) != (size_t)points) return 1;
    fclose(out);
    printf("%.9f %.9f %d\n", cpu, wall, locked);
    return 0;
}
