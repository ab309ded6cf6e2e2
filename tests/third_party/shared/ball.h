/* The bouncing ball's physics, shared by BouncingBall (FMI 2.0) and BouncingBall3 (FMI 3.0):
 *
 *   der(h) = v,  der(v) = -g  (0 at rest);  at h = 0 moving down: v := -e v, bounces += 1,
 *   and the ball rests once it would leave the ground slower than v_min.
 *
 * Flight is solved exactly: parabolas between impacts found in closed form.
 */
#ifndef BALL_H
#define BALL_H

#include <math.h>
#include <stdbool.h>

typedef struct {
    double h, v, g, e, v_min;
    int bounces;
    bool resting;
} Ball;

static inline void ballStart(Ball *b) {
    b->h = 1.0;
    b->v = 0.0;
    b->g = 9.81;
    b->e = 0.7;
    b->v_min = 0.1;
}

static inline void ballInitialize(Ball *b) {
    b->bounces = 0;
    b->resting = false;
}

static inline double ballAcceleration(const Ball *b) { return b->resting ? 0.0 : -b->g; }

/* Crosses zero (from above) at an impact; positive at rest. */
static inline double ballIndicator(const Ball *b) { return b->resting ? 1.0 : b->h; }

/* At an event: bounce if on the ground moving down. True when the states changed. */
static inline bool ballBounce(Ball *b) {
    if (b->resting || b->h > 0 || b->v >= 0) return false;
    b->h = 0;
    b->v = -b->e * b->v;
    b->bounces += 1;
    if (b->v < b->v_min) {
        b->v = 0;
        b->resting = true;
    }
    return true;
}

/* Flies for *dt, or up to the next impact when that comes first: then *dt is the time to it, the
 * ball is on the ground (moving down) and the result is true. */
static inline bool ballFly(Ball *b, double *dt) {
    if (b->resting) return false;
    /* first tau > 0 (or 0 when on the ground moving down) with h + v tau - g tau^2 / 2 = 0 */
    double tau = (b->v + sqrt(b->v * b->v + 2 * b->g * fmax(b->h, 0.0))) / b->g;
    if (tau <= *dt) {
        b->v -= b->g * tau;
        b->h = 0;
        *dt = tau;
        return true;
    }
    b->h += (b->v - 0.5 * b->g * *dt) * *dt;
    b->v -= b->g * *dt;
    return false;
}

#endif
