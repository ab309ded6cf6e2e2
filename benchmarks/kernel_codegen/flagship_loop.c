
/* ------------------------------------------------------------------------------------------------
 * Hand-written driver of the GENERATED kernels above (benchmarks/kernel_codegen/flagship_loop.c):
 * the flagship's closed loop as benchmarks/native/flagship.c runs it (the master's Gauss-Seidel
 * order, classical RK4 with the inputs held), with every computation of the plant, the controller
 * (its sample, state between samples included: sampling.sample) and the path done by the kernels
 * generated from deltafmi/physics/delta/*.py. Only the RK4 stages and the loop are written here.
 * --------------------------------------------------------------------------------------------- */
enum { GL_ROW_WIDTH = 15 };

/* sampling.initial_state(): no integral, no torque, no warm start, nothing warned */
static void gen_controller_reset(SampleState *c)
{
    memset(c, 0, sizeof *c);
    c->cond = NAN;
    c->iterations = -1;
}

/* DeltaController.step: the generated sample, the state updated in place; no tactile loop (the
 * flagship's gain is 0), no commanded force. Returns the kernel's error (the line of a raise) or 0 */
static int gen_controller_step(SampleState *c, const ControlLaw *law, const SampleSettings *settings,
                               const double y[3], const double yd[3], const double r[3], const double rd[3],
                               const double rdd[3])
{
    static const double force[3] = {0.0, 0.0, 0.0};
    return dfk_sample(law, settings, c, y, yd, r, rd, rdd, force, 0.0, c);
}

static SampleSettings gen_settings(double sample_period, int zoh_lead)
{
    SampleSettings s = {sample_period, zoh_lead, 0.0, {{1.0, 0.0, 0.0}}};
    return s;
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
                    const SampleState *c)
{
    row[0] = t;
    memcpy(row + 1, ev->z.v, 3 * sizeof(double));
    memcpy(row + 4, ev->zd.v, 3 * sizeof(double));
    memcpy(row + 7, ref, 3 * sizeof(double));
    memcpy(row + 10, c->u.v, 3 * sizeof(double));
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
    SampleState ctl;
    SampleSettings settings = gen_settings(sample_period, zoh_lead);
    dfk_evaluate_plant_result ev;
    memcpy(x, x0, sizeof x);
    gen_controller_reset(&ctl);
    int err = dfk_path(path, start, ref);
    double y[3] = {x[0], x[3], x[6]}, yd[3] = {x[9], x[12], x[15]};
    err = err ? err : gen_controller_step(&ctl, law, &settings, y, yd, ref, ref + 3, ref + 6);
    err = err ? err : gen_outputs(plant, pole, x, ctl.u.v, f, &ev);
    if (err)
        return err;
    gen_row(rows, start, &ev, ref, &ctl);
    double t_plant = start;
    for (long k = 0; k < steps; k++) {
        double t = start + (double)k * h;
        double t_end = t + h;
        err = dfk_path(path, t_end, ref);
        err = err ? err : gen_rk4_step(plant, pole, t_end - t_plant, ctl.u.v, f, x);
        t_plant = t_end;
        err = err ? err : gen_outputs(plant, pole, x, ctl.u.v, f, &ev);
        if (!err && k > 0) {
            y[0] = x[0]; y[1] = x[3]; y[2] = x[6];
            yd[0] = x[9]; yd[1] = x[12]; yd[2] = x[15];
            err = gen_controller_step(&ctl, law, &settings, y, yd, ref, ref + 3, ref + 6);
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
    SampleState c;
    SampleSettings settings = gen_settings(sample_period, zoh_lead);
    double check = 0.0;
    gen_controller_reset(&c);
    for (long i = 0; i < samples; i++) {
        const double *in = inputs + 15 * i;
        gen_controller_step(&c, law, &settings, in, in + 3, in + 6, in + 9, in + 12);
        if (u_out)
            memcpy(u_out + 3 * i, c.u.v, sizeof c.u.v);
        check += c.u.v[0];
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
