/* StateSpace3: a linear state-space model with array variables (FMI 3.0 <Dimension>):
 *
 *   der(x) = A x + B u,   y = C x + D u      x[3], u[2], y[2]; A[3,3], B[3,2], C[2,3], D[2,2]
 *
 * The matrices are fixed parameters, stored (and serialized) row-major as FMI 3.0 does.
 * Co-Simulation holds u over the step and steps exactly: [x; 1] := expm(h [A, B u; 0, 0]) [x; 1],
 * the exponential by scaling and squaring of its Taylor series.
 */
#include <math.h>
#include <string.h>

#include "plumbing.h"

#define NX 3
#define NU 2
#define NY 2

struct ModelData {
    double time;
    double A[NX][NX], B[NX][NU], C[NY][NX], D[NY][NU];
    double u[NU], x[NX], der_x[NX], y[NY];
};

const char *const MODEL_GUID = "{8c4e2a90-3f1b-4d6e-9a7c-5b2d1e0f3a03}";
const size_t MODEL_DATA_SIZE = sizeof(ModelData);
const size_t NUMBER_OF_STATES = NX;
const size_t NUMBER_OF_EVENT_INDICATORS = 0;

const Variable VARIABLES[] = {
    VARIABLE(0, time, Float64Type, Calculated),
    VARIABLE(1, A, Float64Type, Fixed),
    VARIABLE(2, B, Float64Type, Fixed),
    VARIABLE(3, C, Float64Type, Fixed),
    VARIABLE(4, D, Float64Type, Fixed),
    VARIABLE(5, u, Float64Type, ContinuousInput),
    VARIABLE(6, x, Float64Type, Fixed),
    VARIABLE(7, der_x, Float64Type, Calculated),
    VARIABLE(8, y, Float64Type, Calculated),
};
const size_t NUMBER_OF_VARIABLES = sizeof(VARIABLES) / sizeof(VARIABLES[0]);

#define M(v) (comp->data->v)

Status setStartValues(ModelInstance *comp) {
    static const double A[NX][NX] = {{-1, 2, 0}, {-2, -1, 0}, {0, 0, -0.5}};
    static const double B[NX][NU] = {{1, 0}, {0, 0}, {0, 1}};
    static const double C[NY][NX] = {{1, 0, 0}, {0, 1, 1}};
    static const double D[NY][NU] = {{0, 0}, {0, 0.5}};
    static const double x0[NX] = {1, 0, 0.5};
    memcpy(M(A), A, sizeof(A));
    memcpy(M(B), B, sizeof(B));
    memcpy(M(C), C, sizeof(C));
    memcpy(M(D), D, sizeof(D));
    memcpy(M(x), x0, sizeof(x0));
    return OK;
}

Status initialize(ModelInstance *comp) {
    (void)comp;
    return OK;
}

Status calculateValues(ModelInstance *comp) {
    M(time) = comp->time;
    for (int i = 0; i < NX; i++) {
        M(der_x)[i] = 0;
        for (int j = 0; j < NX; j++) M(der_x)[i] += M(A)[i][j] * M(x)[j];
        for (int j = 0; j < NU; j++) M(der_x)[i] += M(B)[i][j] * M(u)[j];
    }
    for (int i = 0; i < NY; i++) {
        M(y)[i] = 0;
        for (int j = 0; j < NX; j++) M(y)[i] += M(C)[i][j] * M(x)[j];
        for (int j = 0; j < NU; j++) M(y)[i] += M(D)[i][j] * M(u)[j];
    }
    return OK;
}

void getContinuousStates(ModelInstance *comp, double x[]) { memcpy(x, M(x), sizeof(M(x))); }

void setContinuousStates(ModelInstance *comp, const double x[]) { memcpy(M(x), x, sizeof(M(x))); }

void getDerivatives(ModelInstance *comp, double dx[]) {
    calculateValues(comp);
    memcpy(dx, M(der_x), sizeof(M(der_x)));
}

void getEventIndicators(ModelInstance *comp, double z[]) { (void)comp, (void)z; }

void eventUpdate(ModelInstance *comp) { comp->nextEventTimeDefined = false; }

#define N (NX + 1)

static void multiply(const double a[N][N], const double b[N][N], double c[N][N]) {
    double r[N][N] = {{0}};
    for (int i = 0; i < N; i++)
        for (int k = 0; k < N; k++)
            for (int j = 0; j < N; j++) r[i][j] += a[i][k] * b[k][j];
    memcpy(c, r, sizeof(r));
}

/* e = expm(m): Taylor series of m / 2^s with |m| / 2^s <= 1/2, squared s times. */
static void expm(double m[N][N], double e[N][N]) {
    double norm = 0;
    for (int i = 0; i < N; i++) {
        double row = 0;
        for (int j = 0; j < N; j++) row += fabs(m[i][j]);
        norm = fmax(norm, row);
    }
    int s = norm > 0.5 ? (int)ceil(log2(norm / 0.5)) : 0;
    double scale = ldexp(1.0, -s), term[N][N], next[N][N];
    for (int i = 0; i < N; i++)
        for (int j = 0; j < N; j++) {
            m[i][j] *= scale;
            e[i][j] = term[i][j] = i == j;
        }
    for (int k = 1; k <= 20; k++) {  /* 0.5^20 / 20! is far below round-off */
        multiply(term, m, next);
        for (int i = 0; i < N; i++)
            for (int j = 0; j < N; j++) e[i][j] += term[i][j] = next[i][j] / k;
    }
    for (int i = 0; i < s; i++) multiply(e, e, e);
}

bool advance(ModelInstance *comp, double t_stop) {
    double h = t_stop - comp->time, m[N][N] = {{0}}, e[N][N];
    for (int i = 0; i < NX; i++) {
        for (int j = 0; j < NX; j++) m[i][j] = h * M(A)[i][j];
        for (int j = 0; j < NU; j++) m[i][NX] += h * M(B)[i][j] * M(u)[j];
    }
    expm(m, e);
    double x[NX];
    for (int i = 0; i < NX; i++) {
        x[i] = e[i][NX];
        for (int j = 0; j < NX; j++) x[i] += e[i][j] * M(x)[j];
    }
    memcpy(M(x), x, sizeof(x));
    comp->time = t_stop;
    return false;
}
