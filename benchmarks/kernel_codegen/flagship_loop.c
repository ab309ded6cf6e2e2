
/* ------------------------------------------------------------------------------------------------
 * Hand-written driver of the GENERATED kernels above (benchmarks/kernel_codegen/flagship_loop.c):
 * the flagship's closed loop as benchmarks/native/flagship.c runs it (the master's Gauss-Seidel
 * order, classical RK4 with the inputs held), with every computation of the plant, the controller
 * and the path done by the kernels generated from deltafmi/mechanics/delta/*.py. Only the
 * controller's state between samples (DeltaController.step) and the RK4 stages are written here.
 * --------------------------------------------------------------------------------------------- */
#define GL_MIN(a, b) ((b) < (a) ? (b) : (a))
#define GL_MAX(a, b) ((b) > (a) ? (b) : (a))

enum { GL_STATUS_TORQUE_SATURATED = 1, GL_STATUS_SINGULAR = 8, GL_ROW_WIDTH = 15 };

/* DeltaController's state between samples (control.py), for the flagship's options: no tactile
 * loop (its gain is 0), no commanded force */
typedef struct {
    double integral[3];
    double u[3];
    int status;
    double cond;
    int have_u_law, have_x_next, have_xd;
    double u_law[3], x_next[6], xd[6];
} GenController;

void gen_controller_reset(GenController *c)
{
    memset(c, 0, sizeof *c);
    c->cond = NAN;
}

/* DeltaController.step with the generated control_law.evaluate, hold and warm_start; returns the
 * first kernel error (the line of a raise), else 0 */
int gen_controller_step(GenController *c, const ControlLaw *law, double sample_period, int zoh_lead,
                        const double y[3], const double yd[3], const double r[3], const double rd[3],
                        const double rdd[3])
{
    static const double force[3] = {0.0, 0.0, 0.0};
    double dt = (c->status & GL_STATUS_TORQUE_SATURATED) ? 0.0 : sample_period;
    dfk_evaluate_result out;
    int err = dfk_evaluate(law, y, yd, r, rd, rdd, c->integral, dt, c->have_x_next ? c->x_next : NULL, force, &out);
    if (err)
        return err;
    c->status = out.status;
    c->cond = out.cond;
    double lim = law->torque_limit;
    if (out.status & GL_STATUS_SINGULAR) {
        c->have_x_next = c->have_xd = c->have_u_law = 0;
        for (int j = 0; j < 3; j++)
            c->u[j] = GL_MIN(GL_MAX(c->u[j], -lim), lim);
        return 0;
    }
    memcpy(c->integral, out.integral.v, sizeof c->integral);
    dfk_hold_result held;
    if ((err = dfk_hold(out.u.v, zoh_lead && c->have_u_law ? c->u_law : NULL, lim, &held)))
        return err;
    if (held.f1)
        c->status |= GL_STATUS_TORQUE_SATURATED;
    memcpy(c->u_law, out.u.v, sizeof c->u_law);
    c->have_u_law = 1;
    memcpy(c->u, held.f0.v, sizeof c->u);
    err = dfk_warm_start(out.x.v, out.xd.v, c->have_xd ? c->xd : NULL, sample_period, c->x_next);
    c->have_x_next = 1;
    memcpy(c->xd, out.xd.v, sizeof c->xd);
    c->have_xd = 1;
    return err;
}

/* the master's classical RK4 (cosim/stepping/native/erk.c, rk4 tableau, u held), as flagship.c */
static int gen_rk4_step(const DeltaParams *p, double pole, double h, const double u[3], const double f[3],
                        double x[18])
{
    double k1[18], k2[18], k3[18], k4[18], xs[18];
    int bad = dfk_state_derivative(p, x, u, f, pole, k1);
    for (int n = 0; n < 18; n++)
        xs[n] = x[n] + h * (0.5 * k1[n]);
    bad |= dfk_state_derivative(p, xs, u, f, pole, k2);
    for (int n = 0; n < 18; n++)
        xs[n] = x[n] + h * (0.0 * k1[n] + 0.5 * k2[n]);
    bad |= dfk_state_derivative(p, xs, u, f, pole, k3);
    for (int n = 0; n < 18; n++)
        xs[n] = x[n] + h * (0.0 * k1[n] + 0.0 * k2[n] + 1.0 * k3[n]);
    bad |= dfk_state_derivative(p, xs, u, f, pole, k4);
    for (int n = 0; n < 18; n++)
        x[n] += h * ((1.0 / 6.0) * k1[n] + (1.0 / 3.0) * k2[n] + (1.0 / 3.0) * k3[n] + (1.0 / 6.0) * k4[n]);
    return bad;
}

static int gen_outputs(const DeltaParams *p, double pole, const double x[18], const double u[3], const double f[3],
                       dfk_evaluate_plant_result *ev)
{
    return dfk_evaluate_plant(p, x, x + 9, u, f, pole, ev);
}

static void gen_row(double *row, double t, const dfk_evaluate_plant_result *ev, const double ref[9],
                    const GenController *c)
{
    row[0] = t;
    memcpy(row + 1, ev->z.v, 3 * sizeof(double));
    memcpy(row + 4, ev->zd.v, 3 * sizeof(double));
    memcpy(row + 7, ref, 3 * sizeof(double));
    memcpy(row + 10, c->u, 3 * sizeof(double));
    row[13] = c->status;
    row[14] = ev->residual;
}

/* `steps` communication steps from the plant's state x0 at `start`: rows ((steps + 1) x 15) as
 * flagship_run's (the flagship's CSV columns). Returns 0, or the first kernel error. */
int gen_run(const DeltaParams *plant, double pole, const double f[3], const ControlLaw *law, double sample_period,
            int zoh_lead, const MinimumJerkPath *path, double start, double h, const double x0[18], long steps,
            double *rows)
{
    double x[18], ref[9];
    GenController ctl;
    dfk_evaluate_plant_result ev;
    memcpy(x, x0, sizeof x);
    gen_controller_reset(&ctl);
    int err = dfk_path(path, start, ref);
    double y[3] = {x[0], x[3], x[6]}, yd[3] = {x[9], x[12], x[15]};
    err = err ? err : gen_controller_step(&ctl, law, sample_period, zoh_lead, y, yd, ref, ref + 3, ref + 6);
    err = err ? err : gen_outputs(plant, pole, x, ctl.u, f, &ev);
    if (err)
        return err;
    gen_row(rows, start, &ev, ref, &ctl);
    double t_plant = start;
    for (long k = 0; k < steps; k++) {
        double t = start + (double)k * h;
        double t_end = t + h;
        err = dfk_path(path, t_end, ref);
        err = err ? err : gen_rk4_step(plant, pole, t_end - t_plant, ctl.u, f, x);
        t_plant = t_end;
        err = err ? err : gen_outputs(plant, pole, x, ctl.u, f, &ev);
        if (!err && k > 0) {
            y[0] = x[0]; y[1] = x[3]; y[2] = x[6];
            yd[0] = x[9]; yd[1] = x[12]; yd[2] = x[15];
            err = gen_controller_step(&ctl, law, sample_period, zoh_lead, y, yd, ref, ref + 3, ref + 6);
        }
        if (err)
            return err;
        gen_row(rows + (k + 1) * GL_ROW_WIDTH, start + (double)(k + 1) * h, &ev, ref, &ctl);
    }
    return 0;
}

/* A fresh controller stepped through `samples` recorded inputs (y, yd, r, rd, rdd: 15 doubles per
 * sample); torques into u_out (3 per sample) unless NULL. As flagship_replay_controller. */
double gen_replay_controller(const ControlLaw *law, double sample_period, int zoh_lead, const double *inputs,
                             long samples, double *u_out)
{
    GenController c;
    double check = 0.0;
    gen_controller_reset(&c);
    for (long i = 0; i < samples; i++) {
        const double *in = inputs + 15 * i;
        gen_controller_step(&c, law, sample_period, zoh_lead, in, in + 3, in + 6, in + 9, in + 12);
        if (u_out)
            memcpy(u_out + 3 * i, c.u, sizeof c.u);
        check += c.u[0];
    }
    return check;
}

/* `calls` plant derivatives at x (the volatile pointer makes each one compute afresh) */
double gen_repeat_derivative(const DeltaParams *p, double pole, const double *x, const double *u, const double *f,
                             long calls)
{
    const double *volatile xp = x;
    double dx[18], check = 0.0;
    for (long i = 0; i < calls; i++) {
        dfk_state_derivative(p, xp, u, f, pole, dx);
        check += dx[17];
    }
    return check;
}
