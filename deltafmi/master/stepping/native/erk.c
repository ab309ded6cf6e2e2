/* Explicit Runge-Kutta steps of an FMI 2.0 Model Exchange FMU, driven through its own fmi2
 * functions (continuous-time mode: fmi2SetTime, fmi2SetContinuousStates, fmi2GetDerivatives).
 *
 * The master calls this once per integrator step instead of making three FMI calls per stage
 * from Python: the stages' linear combinations and the FMI calls stay in C. Plain C, no Python.
 */
#include <stddef.h>

typedef int (*SetTime)(void *component, double time);
typedef int (*SetStates)(void *component, const double *x, size_t nx);
typedef int (*GetDerivatives)(void *component, double *dx, size_t nx);
typedef int (*GetIndicators)(void *component, double *z, size_t nz);

enum { FMI2_WARNING = 1 };

typedef struct {
    SetTime set_time;
    SetStates set_states;
    GetDerivatives get_derivatives;
    void *component;
    int stages;
    const double *a; /* stages x stages, row-major, strictly lower triangular */
    const double *b;
    const double *c;
    size_t nx;
    double *work;    /* (stages + 1) * nx doubles */
    int current;     /* 1: the FMU holds the next step's start time and states already: the first
                      * stage sets neither (cleared once used) */
} ErkPlan;

static int erk_step(ErkPlan *p, double t, double h, double *x)
{
    const size_t nx = p->nx;
    double *restrict stage_x = p->work + (size_t)p->stages * nx; /* apart from the stages' k and from x */
    int worst = 0;
    /* the sums run over the stages in order for each state, as sum += a * k would state by state;
     * the state is the inner loop (contiguous, no dependence between states) */
    for (int i = 0; i < p->stages; i++) {
        const double *point = x;
        if (i > 0) {
            for (size_t n = 0; n < nx; n++) stage_x[n] = 0.0;
            for (int j = 0; j < i; j++) {
                const double a = p->a[i * p->stages + j], *restrict k = p->work + (size_t)j * nx;
                for (size_t n = 0; n < nx; n++) stage_x[n] += a * k[n];
            }
            for (size_t n = 0; n < nx; n++) stage_x[n] = x[n] + h * stage_x[n];
            point = stage_x;
        }
        int status;
        if (i == 0 && p->current) {
            p->current = 0;
        } else {
            /* a stage at the time of the one before (rk4's second and third) leaves it set */
            if (i == 0 || p->c[i] != p->c[i - 1]) {
                status = p->set_time(p->component, t + p->c[i] * h);
                if (status > worst) worst = status;
                if (worst > FMI2_WARNING) return worst;
            }
            status = p->set_states(p->component, point, nx);
            if (status > worst) worst = status;
            if (worst > FMI2_WARNING) return worst;
        }
        status = p->get_derivatives(p->component, p->work + (size_t)i * nx, nx);
        if (status > worst) worst = status;
        if (worst > FMI2_WARNING) return worst;
    }
    for (size_t n = 0; n < nx; n++) stage_x[n] = 0.0;
    for (int i = 0; i < p->stages; i++) {
        const double b = p->b[i], *restrict k = p->work + (size_t)i * nx;
        for (size_t n = 0; n < nx; n++) stage_x[n] += b * k[n];
    }
    for (size_t n = 0; n < nx; n++) x[n] += h * stage_x[n];
    return worst;
}

/* `steps` equal steps of size h from t, updating x in place. Returns the worst fmi2Status seen;
 * a status above fmi2Warning stops at once (x then holds the last completed step). */
__attribute__((visibility("default")))
int deltafmi_erk_steps(ErkPlan *plan, double t, double h, int steps, double *x)
{
    int worst = 0;
    for (int k = 0; k < steps; k++) {
        int status = erk_step(plan, t + k * h, h, x);
        if (status > worst) worst = status;
        if (worst > FMI2_WARNING) break;
    }
    return worst;
}

/* What an integrator's callback asks of the FMU in one foreign call: fmi2SetTime and
 * fmi2SetContinuousStates, then fmi2GetDerivatives (get_indicators NULL) or
 * fmi2GetEventIndicators into out. Returns the worst fmi2Status, or at the first status above
 * fmi2Warning that status plus 256 times the failing call (0 SetTime, 1 SetContinuousStates,
 * 2 the get). */
__attribute__((visibility("default")))
int deltafmi_fmu_evaluate(const ErkPlan *p, GetIndicators get_indicators, double t, const double *x,
                          double *out, size_t n_out)
{
    int worst = p->set_time(p->component, t);
    if (worst > FMI2_WARNING) return worst;
    int status = p->set_states(p->component, x, p->nx);
    if (status > FMI2_WARNING) return status + 256;
    if (status > worst) worst = status;
    status = get_indicators ? get_indicators(p->component, out, n_out) : p->get_derivatives(p->component, out, n_out);
    if (status > FMI2_WARNING) return status + 512;
    return status > worst ? status : worst;
}
