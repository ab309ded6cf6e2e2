/* Makes tests/c_host/host.c a hostile host: linked against Debian's SUNDIALS 6 (CVODE, serial
 * N_Vector, dense matrix and linear solver), which it uses before it loads the FMU, as
 * OMSimulator or OpenModelica's runtime would. Every SUNDIALS symbol (CVode, cvLsSetup,
 * N_VLinearSum, ...) is then in the process's global scope, where an FMU's own SUNDIALS must not
 * bind to it. host.c calls host_preload() when this file is linked in. */
#include <cvode/cvode.h>
#include <math.h>
#include <nvector/nvector_serial.h>
#include <stdio.h>
#include <stdlib.h>
#include <sunlinsol/sunlinsol_dense.h>
#include <sunmatrix/sunmatrix_dense.h>

static int decay(realtype t, N_Vector y, N_Vector ydot, void *user_data) {
    (void)t;
    (void)user_data;
    NV_Ith_S(ydot, 0) = -NV_Ith_S(y, 0);
    return 0;
}

/* y' = -y, y(0) = 1 to t = 1 with the host's CVODE; exits unless y(1) = exp(-1) to 1e-6. */
void host_preload(void) {
    SUNContext ctx;
    if (SUNContext_Create(NULL, &ctx)) exit(5);
    N_Vector y = N_VNew_Serial(1, ctx);
    NV_Ith_S(y, 0) = 1.0;
    void *mem = CVodeCreate(CV_BDF, ctx);
    SUNMatrix A = SUNDenseMatrix(1, 1, ctx);
    SUNLinearSolver LS = SUNLinSol_Dense(y, A, ctx);
    realtype t = 0.0;
    if (CVodeInit(mem, decay, 0.0, y) || CVodeSStolerances(mem, 1e-10, 1e-12) ||
        CVodeSetLinearSolver(mem, LS, A) || CVode(mem, 1.0, y, &t, CV_NORMAL) < 0) exit(5);
    double error = fabs(NV_Ith_S(y, 0) - exp(-1.0));
    fprintf(stderr, "host SUNDIALS %s: y(1) - exp(-1) = %.3g\n", SUNDIALS_VERSION, error);
    if (error > 1e-6) exit(5);
    /* keep the host's solver alive, as a host would while it runs the FMU */
}
