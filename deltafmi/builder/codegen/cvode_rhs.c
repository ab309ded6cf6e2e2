/* ---- CVODE's right-hand side, root and projection functions over the kernels (deltafmi/builder/codegen/cvode_rhs.c) ----
 * A Co-Simulation step integrates with CVODE driven from Python (deltafmi/runtime/cvode.py); its
 * right-hand side (and root functions, with an event-indicator kernel, and the projection after
 * every internal step, with a project kernel, and the Newton matrix, with a state_jacobian kernel)
 * are these, so CVODE's many evaluations per step run no Python. They write the solver's state into the value buffer as the Python callbacks do, and
 * call those (fallback) while the kernels are off or when a kernel raised: Python then explains. */
typedef int (*DfmiCvodeFn)(double t, void *y, void *out, void *user_data);
/* CVProjFn: (t, ycur, corr, epsProj, err, user_data) */
typedef int (*DfmiCvodeProjFn)(double t, void *y, void *corr, double eps, void *err, void *user_data);
/* CVLsJacFn: (t, y, fy, Jac, user_data, tmp1, tmp2, tmp3) */
typedef int (*DfmiCvodeJacFn)(double t, void *y, void *fy, void *jac, void *user_data, void *t1, void *t2, void *t3);
typedef struct {
    const DfmiAttributes *attributes;
    const int *ready;
    double *real;
    int *ints;
    long nx, x_offset, dx_offset, nz;
    double *(*array)(void *vector); /* SUNDIALS' N_VGetArrayPointer */
    DfmiCvodeFn fallback, roots_fallback;
    DfmiCvodeProjFn project_fallback;
    DfmiCvodeJacFn jacobian_fallback;
    double *(*matrix)(void *matrix); /* SUNDIALS' SUNDenseMatrix_Data: column-major, nx rows */
} DfmiCvodeData;

EXPORT int dfmi_kernel_cvode_rhs(double t, void *y, void *ydot, void *user_data)
{
    const DfmiCvodeData *r = user_data;
    if (*r->ready) {
        memcpy(r->real + r->x_offset, r->array(y), (size_t)r->nx * sizeof(double));
        if (dfmi_kernel_derivatives(r->attributes, t, r->real, r->ints, NULL) == 0) {
            memcpy(r->array(ydot), r->real + r->dx_offset, (size_t)r->nx * sizeof(double));
            return 0;
        }
    }
    return r->fallback(t, y, ydot, user_data);
}

/* roots: g is a plain array of nz doubles (CVRootFn) */
EXPORT int dfmi_kernel_cvode_roots(double t, void *y, void *g, void *user_data)
{
    const DfmiCvodeData *r = user_data;
#if DFMI_KERNEL_INDICATORS
    if (*r->ready) {
        memcpy(r->real + r->x_offset, r->array(y), (size_t)r->nx * sizeof(double));
        if (dfmi_kernel_event_indicators(r->attributes, t, r->real, r->ints, g) == 0) return 0;
    }
#endif
    return r->roots_fallback(t, y, g, user_data);
}

/* projection: the project kernel writes the projected states over the solver's in the value
 * buffer; the correction CVODE adds is their difference (as the Python callback computes it) */
EXPORT int dfmi_kernel_cvode_project(double t, void *y, void *corr, double eps, void *err, void *user_data)
{
    const DfmiCvodeData *r = user_data;
#if DFMI_KERNEL_PROJECT
    if (*r->ready) {
        const double *x = r->array(y);
        double *x_buffer = r->real + r->x_offset;
        memcpy(x_buffer, x, (size_t)r->nx * sizeof(double));
        if (dfmi_kernel_project(r->attributes, t, r->real, r->ints, NULL) == 0) {
            double *c = r->array(corr);
            for (long k = 0; k < r->nx; k++) c[k] = x_buffer[k] - x[k];
            return 0;
        }
    }
#endif
    return r->project_fallback(t, y, corr, eps, err, user_data);
}

/* the Newton matrix d rhs / d x: the state_jacobian kernel writes it column by column straight
 * into CVODE's dense matrix (the fallback: the Python jacobian, as without the kernel) */
EXPORT int dfmi_kernel_cvode_jacobian(double t, void *y, void *fy, void *jac, void *user_data, void *t1, void *t2,
                                      void *t3)
{
    const DfmiCvodeData *r = user_data;
#if DFMI_KERNEL_STATE_JACOBIAN
    if (*r->ready) {
        memcpy(r->real + r->x_offset, r->array(y), (size_t)r->nx * sizeof(double));
        if (dfmi_kernel_state_jacobian(r->attributes, t, r->real, r->ints, r->matrix(jac)) == 0) return 0;
    }
#endif
    return r->jacobian_fallback(t, y, fy, jac, user_data, t1, t2, t3);
}
