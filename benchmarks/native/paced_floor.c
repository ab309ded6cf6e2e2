/* The machine's floor for a paced run: the C loop's pacing (fixed_step.c pace_to: every point
 * due at start + k * period on CLOCK_MONOTONIC, polled for; a late point is not made up by
 * skipping, the schedule is absolute) around a step that only burns `busy` seconds of wall time.
 * What it counts late is what the machine does to any paced loop: other processes' turns, the
 * scheduler's ticks, a virtual machine's host. benchmarks/realtime.py compares the flagship's
 * paced run with it, measured in the same run. Plain C99 + POSIX clocks. */
#define _POSIX_C_SOURCE 200112L
#include <time.h>

static double now(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* `points` points `period` apart after `busy` seconds of work each; *overruns: points later than
 * `tolerance`, *behind: times a point came more than a whole period late after one that did not
 * (episodes, as deltafmi's Pacer counts them); returns the largest lateness [s] */
double paced_floor(long points, double period, double busy, double tolerance, long *overruns, long *behind)
{
    double start = now(), worst = 0.0;
    int late_before = 0;
    *overruns = *behind = 0;
    for (long k = 1; k <= points; k++) {
        double until = now() + busy;
        while (now() < until) {
        }
        double deadline = start + (double)k * period, t = now();
        while (t < deadline) t = now();
        double late = t - deadline;
        if (late > worst) worst = late;
        if (late > tolerance) (*overruns)++;
        if (late > period && !late_before) (*behind)++;
        late_before = late > period;
    }
    return worst;
}
