/* A C transcription of the flagship's kernels (scenarios/delta_tracking.yaml): the
 * delta robot's state derivative and outputs, the sampled feedback-linearising controller, the
 * minimum-jerk path and the master's classical RK4 with held inputs, closed in one loop.
 *
 * Written for benchmarks/native.py as the baseline of issue 26 (what "C speed" means for the
 * flagship), and checked against the flagship's own result by tests/test_native_baseline.py.
 * Plain C99 and libm. Every function names the Python function it transcribes; the order of
 * the floating-point operations is the Python's, so the results agree bit for bit where the
 * math library is the same.
 */
#ifndef DELTAFMI_FLAGSHIP_H
#define DELTAFMI_FLAGSHIP_H

/* deltafmi.physics.delta.params.DeltaParams (SI units) */
typedef struct {
    double l0, l1, l2, l3, m1, r1, J1, Jm, m2, mp, payload, g, damping;
} DeltaParams;

/* The controller's law as make_law() builds it (position mode; the flagship's options) */
typedef struct {
    DeltaParams model;       /* the controller's model of the robot */
    double kI, kP, kD;
    double integral_max;     /* bound on the integral STATE per axis (m s) */
    int feedforward, coriolis, zoh_lead, newton;
    double torque_limit, cond_limit, newton_tol;
    int newton_max_iter;
    double sample_period;
} ControlLawSpec;

enum { MAX_WAYPOINTS = 8 };

/* MinimumJerkPath's construction arguments */
typedef struct {
    int n;                                   /* waypoints used */
    double wp[MAX_WAYPOINTS][3];             /* waypoints (m) */
    double T[MAX_WAYPOINTS - 1];             /* move durations (s) */
    double dwell;                            /* rest at each waypoint (s) */
    double t0;                               /* start of the motion (s) */
} PathSpec;

/* The whole flagship: plant, controller, path and the master's grid */
typedef struct {
    DeltaParams plant;
    double pole;             /* Baumgarte pole of the plant (1/s) */
    double z0[3];            /* initial wrist position (m), at rest */
    double f[3];             /* external wrist force (N) */
    ControlLawSpec law;
    PathSpec path;
    double start, h;         /* communication grid */
} Flagship;

/* MinimumJerkPath after construction: start time of each move (as _move_starts) */
typedef struct {
    PathSpec spec;
    double starts[MAX_WAYPOINTS - 1];
} Path;

/* DeltaController's state between samples (flagship_controller_reset before the first) */
typedef struct {
    double integral[3];
    double u[3];             /* the torque held */
    int status;
    double cond;
    double z[3];             /* last estimate of the wrist (ControlOutput.z) */
    int have_u_law;          /* _u_law is not None */
    double u_law[3];
    int have_x_next;         /* _x_next is not None */
    double x_next[6];
    int have_xd;             /* _xd is not None */
    double xd[6];
} Controller;

/* Row of the closed loop, the flagship's outputs in its CSV's order */
enum { ROW_WIDTH = 15 };     /* t, z[3], zd[3], r[3], u[3], status, residual */

int flagship_state_derivative(const DeltaParams *p, double pole, const double x[18], const double u[3],
                              const double f[3], double dx[18]);
int flagship_plant_outputs(const DeltaParams *p, double pole, const double x[18], const double u[3],
                           const double f[3], double z[3], double zd[3], double *residual, double *energy);
int flagship_initial_state(const DeltaParams *p, const double z0[3], double x[18]);
void flagship_path_init(Path *path, const PathSpec *spec);
void flagship_path_evaluate(const Path *path, double t, double out[9]);
void flagship_controller_reset(Controller *c);
void flagship_controller_step(Controller *c, const ControlLawSpec *law, const double y[3], const double yd[3],
                              const double r[3], const double rd[3], const double rdd[3]);
int flagship_run(const Flagship *fs, long steps, double *rows, double *states);
double flagship_repeat_derivative(const DeltaParams *p, double pole, const double *x, const double *u,
                                  const double *f, long calls);
double flagship_replay_controller(const ControlLawSpec *law, const double *inputs, long samples, double *u_out);

#endif
