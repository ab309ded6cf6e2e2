/* A C transcription of the flagship's kernels: see flagship.h.
 *
 * Transcribed from (all under deltafmi/):
 *   mechanics/delta/dynamics.py      state_derivative, evaluate_plant and their helpers
 *   mechanics/delta/kinematics.py    inverse_kinematics (the plant's initial state)
 *   mechanics/delta/control_law.py   evaluate (position mode), hold, warm_start and helpers
 *   mechanics/delta/control.py       DeltaController.step
 *   mechanics/delta/trajectory.py    MinimumJerkPath, minimum_jerk
 *   cosim/stepping/native/erk.c      the master's Runge-Kutta step (rk4 tableau, inputs held)
 *   benchmarks/cosim.py              Floor.run: the closed loop in the master's Gauss-Seidel order
 *
 * Conventions kept from the Python so that the results agree bit for bit: expressions are
 * written in the same order (a + b + c is (a + b) + c in both languages, -a * b is (-a) * b),
 * Python's min()/max() are PY_MIN/PY_MAX (first argument on ties), x ** 2 is libm's pow(x, 2.0), the
 * two sets of arm rotations stay distinct (the plant's exact (-1/2, sqrt(3)/2), the controller's
 * cos/sin of 2 pi/3), and nothing is fused or reassociated (no -ffast-math; FP_CONTRACT off).
 */
#include "flagship.h"

#include <math.h>
#include <string.h>

/* a * b + c stays two roundings, as in Python: no fused multiply-add (GCC ignores the pragma;
 * its -std=c99 turns the contraction off) */
#ifdef __clang__
#pragma STDC FP_CONTRACT OFF
#endif

#define PY_MIN(a, b) ((b) < (a) ? (b) : (a))
#define PY_MAX(a, b) ((b) > (a) ? (b) : (a))

static const double PI = 3.141592653589793;

/* ------------------------------------------------------------------------------------------------
 * plant: mechanics/delta/dynamics.py
 * --------------------------------------------------------------------------------------------- */

/* kinematics.ARM_COS_SIN: (cos, sin) of the plant's arm rotations 0, +2pi/3, -2pi/3 */
static double arm_cos_sin[3][2];

static void init_arm_cos_sin(void)
{
    double sq3_2 = sqrt(3.0) / 2.0;
    arm_cos_sin[0][0] = 1.0;  arm_cos_sin[0][1] = 0.0;
    arm_cos_sin[1][0] = -0.5; arm_cos_sin[1][1] = sq3_2;
    arm_cos_sin[2][0] = -0.5; arm_cos_sin[2][1] = -sq3_2;
}

/* dynamics._constants: (a, b, beta, g1, g2) */
static void plant_constants(const DeltaParams *p, double c[5])
{
    double mpa = (p->mp + p->payload) / 3.0;
    c[0] = p->J1 + p->Jm + (p->m2 + mpa) * p->l1 * p->l1;
    c[1] = (0.5 * p->m2 + mpa) * p->l1 * p->l2;
    c[2] = (p->m2 / 3.0 + mpa) * p->l2 * p->l2;
    c[3] = p->g * (p->m1 * p->r1 + (p->m2 + mpa) * p->l1);
    c[4] = p->g * (0.5 * p->m2 + mpa) * p->l2;
}

/* dynamics._arm_mass_inverse: m12, m13, m33 and the inverse (i11, i12, i13, i22, i23, i33) */
static void arm_mass_inverse(double a, double b, double beta, double s1, double c1, double s2, double c2,
                             double s3, double c3, double out[9])
{
    double m12 = b * (s1 * s2 + c1 * c2 * c3);
    double m13 = -b * c1 * s2 * s3;
    double m33 = beta * s2 * s2;
    double i11 = beta * m33;
    double i12 = -m12 * m33;
    double i13 = -beta * m13;
    double i22 = a * m33 - m13 * m13;
    double i23 = m13 * m12;
    double i33 = a * beta - m12 * m12;
    double det = a * i11 + m12 * i12 + m13 * i13;
    out[0] = m12; out[1] = m13; out[2] = m33;
    out[3] = i11 / det; out[4] = i12 / det; out[5] = i13 / det;
    out[6] = i22 / det; out[7] = i23 / det; out[8] = i33 / det;
}

/* dynamics._arm_response: W = Ht m^-1 Ht^T (6 unique) and Y = m^-1 Ht^T (9, row-major) */
static void arm_response(const double i[6], const double h[9], double W[6], double Y[9])
{
    double i11 = i[0], i12 = i[1], i13 = i[2], i22 = i[3], i23 = i[4], i33 = i[5];
    double h00 = h[0], h01 = h[1], h02 = h[2], h10 = h[3], h11 = h[4], h12 = h[5];
    double h20 = h[6], h21 = h[7], h22 = h[8];
    double y10 = i11 * h00 + i12 * h01 + i13 * h02;
    double y20 = i12 * h00 + i22 * h01 + i23 * h02;
    double y30 = i13 * h00 + i23 * h01 + i33 * h02;
    double y11 = i11 * h10 + i12 * h11 + i13 * h12;
    double y21 = i12 * h10 + i22 * h11 + i23 * h12;
    double y31 = i13 * h10 + i23 * h11 + i33 * h12;
    double y12 = i11 * h20 + i12 * h21 + i13 * h22;
    double y22 = i12 * h20 + i22 * h21 + i23 * h22;
    double y32 = i13 * h20 + i23 * h21 + i33 * h22;
    W[0] = h00 * y10 + h01 * y20 + h02 * y30;
    W[1] = h00 * y11 + h01 * y21 + h02 * y31;
    W[2] = h00 * y12 + h01 * y22 + h02 * y32;
    W[3] = h10 * y11 + h11 * y21 + h12 * y31;
    W[4] = h10 * y12 + h11 * y22 + h12 * y32;
    W[5] = h20 * y12 + h21 * y22 + h22 * y32;
    Y[0] = y10; Y[1] = y11; Y[2] = y12;
    Y[3] = y20; Y[4] = y21; Y[5] = y22;
    Y[6] = y30; Y[7] = y31; Y[8] = y32;
}

/* One arm's share of the DAE evaluation (dynamics._arm) */
typedef struct {
    double b[3];    /* A + 2p Pd + p^2 P (world) */
    double W[6];    /* Ht m^-1 Ht^T */
    double x[3];    /* m^-1 rhs */
    double Y[9];    /* m^-1 Ht^T */
    double P[3];    /* wrist point (world) */
    double Pd[3];   /* wrist velocity (world) */
    double e;       /* kinetic + potential energy */
} ArmTerms;

/* dynamics._arm */
static void arm_terms(const double consts[5], double damping, double pole, double cr, double sr, double l0l3,
                      double l1, double l2, double q1, double q2, double q3, double v1, double v2, double v3,
                      double u, double fx, double fy, double fz, ArmTerms *out)
{
    double a = consts[0], b = consts[1], beta = consts[2], g1 = consts[3], g2 = consts[4];
    double s1 = sin(q1), c1 = cos(q1), s2 = sin(q2), c2 = cos(q2), s3 = sin(q3), c3 = cos(q3);
    /* local wrist point, Jacobian rows and velocity-product term */
    double px = l2 * s2 * s3, py = l0l3 + l1 * c1 + l2 * c2, pz = l1 * s1 + l2 * s2 * c3;
    double j01 = l2 * c2 * s3, j02 = l2 * s2 * c3;
    double j10 = -l1 * s1, j11 = -l2 * s2;
    double j20 = l1 * c1, j21 = l2 * c2 * c3, j22 = -l2 * s2 * s3;
    double w23 = v2 * v2 + v3 * v3;
    double vv11 = v1 * v1;
    double v23 = 2.0 * v2 * v3;
    double ax = l2 * (-s2 * s3 * w23 + c2 * c3 * v23);
    double ay = -l1 * c1 * vv11 - l2 * c2 * v2 * v2;
    double az = -l1 * s1 * vv11 - l2 * (s2 * c3 * w23 + c2 * s3 * v23);
    /* rotate to the world: rows of Ht = R J */
    double h[9];
    h[0] = -sr * j10; h[1] = cr * j01 - sr * j11; h[2] = cr * j02;
    h[3] = cr * j10;  h[4] = sr * j01 + cr * j11; h[5] = sr * j02;
    h[6] = j20;       h[7] = j21;                 h[8] = j22;
    double h00 = h[0], h01 = h[1], h02 = h[2], h10 = h[3], h11 = h[4], h12 = h[5];
    double h20 = h[6], h21 = h[7], h22 = h[8];
    /* mass block and its inverse (m23 = 0) */
    double mi[9];
    arm_mass_inverse(a, b, beta, s1, c1, s2, c2, s3, c3, mi);
    double m12 = mi[0], m13 = mi[1], m33 = mi[2];
    double i11 = mi[3], i12 = mi[4], i13 = mi[5], i22 = mi[6], i23 = mi[7], i33 = mi[8];
    /* generalized forces: B u + Jv^T f - C - D v - G  (Jv_i = Ht_i / 3) */
    double ft0 = fx / 3.0, ft1 = fy / 3.0, ft2 = fz / 3.0;
    double r1 = (u + h00 * ft0 + h10 * ft1 + h20 * ft2 - damping * v1 - g1 * c1
                 - b * ((s1 * c2 - c1 * s2 * c3) * v2 * v2 - c1 * c2 * s3 * v23 - c1 * s2 * c3 * v3 * v3));
    double r2 = (h01 * ft0 + h11 * ft1 + h21 * ft2 - damping * v2 - g2 * c2 * c3
                 - b * (c1 * s2 - s1 * c2 * c3) * vv11 + beta * s2 * c2 * v3 * v3);
    double r3 = (h02 * ft0 + h12 * ft1 + h22 * ft2 - damping * v3 + g2 * s2 * s3
                 - b * s1 * s2 * s3 * vv11 - beta * s2 * c2 * v23);
    double x1 = i11 * r1 + i12 * r2 + i13 * r3;
    double x2 = i12 * r1 + i22 * r2 + i23 * r3;
    double x3 = i13 * r1 + i23 * r2 + i33 * r3;
    arm_response(mi + 3, h, out->W, out->Y);
    /* world wrist point, velocity, free acceleration; b = A + 2p Pd + p^2 P */
    double Px = cr * px - sr * py, Py = sr * px + cr * py, Pz = pz;
    double dx = h00 * v1 + h01 * v2 + h02 * v3;
    double dy = h10 * v1 + h11 * v2 + h12 * v3;
    double dz = h20 * v1 + h21 * v2 + h22 * v3;
    double Ax = h00 * x1 + h01 * x2 + h02 * x3 + cr * ax - sr * ay;
    double Ay = h10 * x1 + h11 * x2 + h12 * x3 + sr * ax + cr * ay;
    double Az = h20 * x1 + h21 * x2 + h22 * x3 + az;
    double tp = 2.0 * pole, pp = pole * pole;
    out->b[0] = Ax + tp * dx + pp * Px;
    out->b[1] = Ay + tp * dy + pp * Py;
    out->b[2] = Az + tp * dz + pp * Pz;
    out->x[0] = x1; out->x[1] = x2; out->x[2] = x3;
    out->P[0] = Px; out->P[1] = Py; out->P[2] = Pz;
    out->Pd[0] = dx; out->Pd[1] = dy; out->Pd[2] = dz;
    out->e = (0.5 * (a * vv11 + beta * v2 * v2 + m33 * v3 * v3) + v1 * (m12 * v2 + m13 * v3)
              + g1 * s1 + g2 * s2 * c3);
}

/* dynamics._sym3_inv: inverse of an SPD 3x3 (6 unique entries); -1 when it lost rank */
static int sym3_inv(double a11, double a12, double a13, double a22, double a23, double a33, double out[6])
{
    double c11 = a22 * a33 - a23 * a23;
    double c12 = a13 * a23 - a12 * a33;
    double c13 = a12 * a23 - a13 * a22;
    double det = a11 * c11 + a12 * c12 + a13 * c13;
    if (!(det > 0.0))
        return -1;  /* the Python raises ArithmeticError: a direct-kinematic singularity */
    out[0] = c11 / det; out[1] = c12 / det; out[2] = c13 / det;
    out[3] = (a11 * a33 - a13 * a13) / det;
    out[4] = (a12 * a13 - a11 * a23) / det;
    out[5] = (a11 * a22 - a12 * a12) / det;
    return 0;
}

/* dynamics._schur_factor: P^-1 (6), X = P^-1 W1 (9), Z^-1 (6) of [[W1 + W2, W1], [W1, W1 + W3]] */
static int schur_factor(const double W1[6], const double W2[6], const double W3[6], double out[21])
{
    double a11 = W1[0], a12 = W1[1], a13 = W1[2], a22 = W1[3], a23 = W1[4], a33 = W1[5];
    double *P = out, *z = out + 15;
    if (sym3_inv(a11 + W2[0], a12 + W2[1], a13 + W2[2], a22 + W2[3], a23 + W2[4], a33 + W2[5], P))
        return -1;
    double p11 = P[0], p12 = P[1], p13 = P[2], p22 = P[3], p23 = P[4], p33 = P[5];
    double x11 = p11 * a11 + p12 * a12 + p13 * a13;
    double x12 = p11 * a12 + p12 * a22 + p13 * a23;
    double x13 = p11 * a13 + p12 * a23 + p13 * a33;
    double x21 = p12 * a11 + p22 * a12 + p23 * a13;
    double x22 = p12 * a12 + p22 * a22 + p23 * a23;
    double x23 = p12 * a13 + p22 * a23 + p23 * a33;
    double x31 = p13 * a11 + p23 * a12 + p33 * a13;
    double x32 = p13 * a12 + p23 * a22 + p33 * a23;
    double x33 = p13 * a13 + p23 * a23 + p33 * a33;
    out[6] = x11; out[7] = x12; out[8] = x13;
    out[9] = x21; out[10] = x22; out[11] = x23;
    out[12] = x31; out[13] = x32; out[14] = x33;
    /* Z = (W1 + W3) - W1 X, symmetric */
    return sym3_inv(a11 + W3[0] - (a11 * x11 + a12 * x21 + a13 * x31),
                    a12 + W3[1] - (a11 * x12 + a12 * x22 + a13 * x32),
                    a13 + W3[2] - (a11 * x13 + a12 * x23 + a13 * x33),
                    a22 + W3[3] - (a12 * x12 + a22 * x22 + a23 * x32),
                    a23 + W3[4] - (a12 * x13 + a22 * x23 + a23 * x33),
                    a33 + W3[5] - (a13 * x13 + a23 * x23 + a33 * x33), z);
}

/* dynamics._schur_solve: [la; lb] from the factors and the right-hand side r (6) */
static void schur_solve(const double f[21], const double r[6], double lam[6])
{
    double p11 = f[0], p12 = f[1], p13 = f[2], p22 = f[3], p23 = f[4], p33 = f[5];
    double x11 = f[6], x12 = f[7], x13 = f[8], x21 = f[9], x22 = f[10], x23 = f[11];
    double x31 = f[12], x32 = f[13], x33 = f[14];
    double z11 = f[15], z12 = f[16], z13 = f[17], z22 = f[18], z23 = f[19], z33 = f[20];
    double s1 = r[0], s2 = r[1], s3 = r[2], u1 = r[3], u2 = r[4], u3 = r[5];
    double t1 = u1 - (x11 * s1 + x21 * s2 + x31 * s3);
    double t2 = u2 - (x12 * s1 + x22 * s2 + x32 * s3);
    double t3 = u3 - (x13 * s1 + x23 * s2 + x33 * s3);
    double lb1 = z11 * t1 + z12 * t2 + z13 * t3;
    double lb2 = z12 * t1 + z22 * t2 + z23 * t3;
    double lb3 = z13 * t1 + z23 * t2 + z33 * t3;
    lam[0] = p11 * s1 + p12 * s2 + p13 * s3 - (x11 * lb1 + x12 * lb2 + x13 * lb3);
    lam[1] = p12 * s1 + p22 * s2 + p23 * s3 - (x21 * lb1 + x22 * lb2 + x23 * lb3);
    lam[2] = p13 * s1 + p23 * s2 + p33 * s3 - (x31 * lb1 + x32 * lb2 + x33 * lb3);
    lam[3] = lb1; lam[4] = lb2; lam[5] = lb3;
}

/* dynamics._subtract_response: x - M^-1 H^T [la; lb] (arm-major) */
static void subtract_response(const double x[9], const double Y1[9], const double Y2[9], const double Y3[9],
                              const double lam[6], double out[9])
{
    double la0 = lam[0], la1 = lam[1], la2 = lam[2], lb0 = lam[3], lb1 = lam[4], lb2 = lam[5];
    double F0 = la0 + lb0, F1 = la1 + lb1, F2 = la2 + lb2;
    out[0] = x[0] - (Y1[0] * F0 + Y1[1] * F1 + Y1[2] * F2);
    out[1] = x[1] - (Y1[3] * F0 + Y1[4] * F1 + Y1[5] * F2);
    out[2] = x[2] - (Y1[6] * F0 + Y1[7] * F1 + Y1[8] * F2);
    out[3] = x[3] + (Y2[0] * la0 + Y2[1] * la1 + Y2[2] * la2);
    out[4] = x[4] + (Y2[3] * la0 + Y2[4] * la1 + Y2[5] * la2);
    out[5] = x[5] + (Y2[6] * la0 + Y2[7] * la1 + Y2[8] * la2);
    out[6] = x[6] + (Y3[0] * lb0 + Y3[1] * lb1 + Y3[2] * lb2);
    out[7] = x[7] + (Y3[3] * lb0 + Y3[4] * lb1 + Y3[5] * lb2);
    out[8] = x[8] + (Y3[6] * lb0 + Y3[7] * lb1 + Y3[8] * lb2);
}

/* dynamics._evaluate: vdot (9), lam (6) and the three arms' terms; -1 at a singularity */
static int plant_evaluate(const DeltaParams *p, double pole, const double q[9], const double v[9],
                          const double u[3], const double f[3], double vdot[9], double lam[6], ArmTerms arms[3])
{
    double consts[5];
    plant_constants(p, consts);
    double l0l3 = p->l0 - p->l3, l1 = p->l1, l2 = p->l2, dmp = p->damping;
    for (int i = 0; i < 3; i++)
        arm_terms(consts, dmp, pole, arm_cos_sin[i][0], arm_cos_sin[i][1], l0l3, l1, l2, q[3 * i], q[3 * i + 1],
                  q[3 * i + 2], v[3 * i], v[3 * i + 1], v[3 * i + 2], u[i], f[0], f[1], f[2], &arms[i]);
    const double *b1 = arms[0].b, *b2 = arms[1].b, *b3 = arms[2].b;
    double factors[21];
    if (schur_factor(arms[0].W, arms[1].W, arms[2].W, factors))
        return -1;
    double r[6] = {b2[0] - b1[0], b2[1] - b1[1], b2[2] - b1[2], b3[0] - b1[0], b3[1] - b1[1], b3[2] - b1[2]};
    schur_solve(factors, r, lam);
    /* vdot = m^-1 rhs + M^-1 H^T lam, i.e. x minus the response to -lam */
    double x[9] = {arms[0].x[0], arms[0].x[1], arms[0].x[2], arms[1].x[0], arms[1].x[1], arms[1].x[2],
                   arms[2].x[0], arms[2].x[1], arms[2].x[2]};
    double minus[6] = {-lam[0], -lam[1], -lam[2], -lam[3], -lam[4], -lam[5]};
    subtract_response(x, arms[0].Y, arms[1].Y, arms[2].Y, minus, vdot);
    return 0;
}

/* dynamics.state_derivative: dx = [v; vdot] for x = [q; v] */
int flagship_state_derivative(const DeltaParams *p, double pole, const double x[18], const double u[3],
                              const double f[3], double dx[18])
{
    double lam[6];
    ArmTerms arms[3];
    if (!arm_cos_sin[0][0]) init_arm_cos_sin();
    memcpy(dx, x + 9, 9 * sizeof(double));
    return plant_evaluate(p, pole, x, x + 9, u, f, dx + 9, lam, arms);
}

/* dynamics.evaluate_plant: the outputs z, zd (means of the arms' wrist points and velocities),
 * the loop residual |h| and the energy */
int flagship_plant_outputs(const DeltaParams *p, double pole, const double x[18], const double u[3],
                           const double f[3], double z[3], double zd[3], double *residual, double *energy)
{
    double vdot[9], lam[6], h[6];
    ArmTerms A[3];
    if (!arm_cos_sin[0][0]) init_arm_cos_sin();
    if (plant_evaluate(p, pole, x, x + 9, u, f, vdot, lam, A))
        return -1;
    for (int k = 0; k < 3; k++) {
        h[k] = A[0].P[k] - A[1].P[k];
        h[3 + k] = A[0].P[k] - A[2].P[k];
        z[k] = (A[0].P[k] + A[1].P[k] + A[2].P[k]) / 3.0;
        zd[k] = (A[0].Pd[k] + A[1].Pd[k] + A[2].Pd[k]) / 3.0;
    }
    double sum = 0.0;  /* Python 3.11's sum(): left to right from 0 */
    for (int k = 0; k < 6; k++)
        sum += h[k] * h[k];
    *residual = sqrt(sum);
    *energy = A[0].e + A[1].e + A[2].e;
    return 0;
}

/* ------------------------------------------------------------------------------------------------
 * the plant's initial state: kinematics.inverse_kinematics (elbows out, at rest)
 * --------------------------------------------------------------------------------------------- */

/* kinematics._arm_ik: one arm's angles reaching the local wrist point (x, y, z); -1: out of reach */
static int arm_ik(const DeltaParams *p, double x, double y, double z, double q[3])
{
    double l1 = p->l1, l2 = p->l2;
    double Y = y - (p->l0 - p->l3);
    double rho = hypot(Y, z);
    double k = (x * x + Y * Y + z * z + l1 * l1 - l2 * l2) / (2.0 * l1);
    if (rho == 0.0 || fabs(k) > rho)
        return -1;
    double q1 = atan2(z, Y) + acos(PY_MIN(1.0, k / rho));  /* '+': elbow out */
    if (q1 > PI)
        q1 -= 2.0 * PI;
    double ux = x, uy = Y - l1 * cos(q1), uz = z - l1 * sin(q1);
    if (uz >= 0.0)
        return -1;
    q[0] = q1;
    q[1] = atan2(-hypot(ux, uz), uy);
    q[2] = atan2(-ux, -uz);
    return 0;
}

/* the plant's initialize(): q = inverse_kinematics(z0) (via _to_arm_frame), v = 0 */
int flagship_initial_state(const DeltaParams *p, const double z0[3], double x[18])
{
    if (!arm_cos_sin[0][0]) init_arm_cos_sin();
    for (int arm = 0; arm < 3; arm++) {
        double c = arm_cos_sin[arm][0], s = arm_cos_sin[arm][1];
        if (arm_ik(p, c * z0[0] + s * z0[1], -s * z0[0] + c * z0[1], z0[2], x + 3 * arm))
            return -1;
    }
    for (int k = 9; k < 18; k++)
        x[k] = 0.0;
    return 0;
}

/* ------------------------------------------------------------------------------------------------
 * controller: mechanics/delta/control_law.py (position mode) and control.DeltaController.step
 * --------------------------------------------------------------------------------------------- */

enum { STATUS_OK = 0, STATUS_TORQUE_SATURATED = 1, STATUS_INTEGRAL_CLAMPED = 2, STATUS_ILL_CONDITIONED = 4,
       STATUS_SINGULAR = 8 };

/* control_law._ROT: (cos, sin) of the controller's arm rotations, from cos/sin of 2 pi/3 */
static double rot[3][2];

/* control_law._Model */
typedef struct {
    double a, l1, l2, jrot, m1r1g, s0, s1, s2, g, damping;
} ArmModel;

/* control_law._model */
static ArmModel arm_model(const DeltaParams *p)
{
    ArmModel k;
    double mpp = (p->mp + p->payload) / 3.0;
    k.a = p->l0 - p->l3; k.l1 = p->l1; k.l2 = p->l2; k.jrot = p->J1 + p->Jm;
    k.m1r1g = p->m1 * p->r1 * p->g; k.s0 = p->m2 + mpp; k.s1 = p->m2 / 2.0 + mpp;
    k.s2 = p->m2 / 3.0 + mpp; k.g = p->g; k.damping = p->damping;
    return k;
}

/* control_law.Elbow: (cos, sin) of the arm rotation and of the servo angle, wrist-sphere centre */
typedef struct { double cr, sr, c1, s1, ex, ey, ez; } Elbow;
/* control_law.F4: (s2, c2, s3, c3) of one forearm */
typedef struct { double s2, c2, s3, c3; } Forearm;

/* control_law._inv3: inverse of a 3x3 (row-major); -1 when |det| <= 1e-12 */
static int inv3(const double m[9], double out[9])
{
    double m00 = m[0], m01 = m[1], m02 = m[2], m10 = m[3], m11 = m[4], m12 = m[5];
    double m20 = m[6], m21 = m[7], m22 = m[8];
    double c00 = m11 * m22 - m12 * m21;
    double c01 = m12 * m20 - m10 * m22;
    double c02 = m10 * m21 - m11 * m20;
    double det = m00 * c00 + m01 * c01 + m02 * c02;
    if (!(fabs(det) > 1e-12))
        return -1;
    double k = 1.0 / det;
    out[0] = c00 * k; out[1] = (m02 * m21 - m01 * m22) * k; out[2] = (m01 * m12 - m02 * m11) * k;
    out[3] = c01 * k; out[4] = (m00 * m22 - m02 * m20) * k; out[5] = (m02 * m10 - m00 * m12) * k;
    out[6] = c02 * k; out[7] = (m01 * m20 - m00 * m21) * k; out[8] = (m00 * m11 - m01 * m10) * k;
    return 0;
}

/* control_law._elbows */
static void elbows(const ArmModel *k, const double y[3], Elbow elb[3])
{
    for (int i = 0; i < 3; i++) {
        double cr = rot[i][0], sr = rot[i][1];
        double c1 = cos(y[i]), s1 = sin(y[i]);
        double rho = k->a + k->l1 * c1;
        Elbow e = {cr, sr, c1, s1, -sr * rho, cr * rho, k->l1 * s1};
        elb[i] = e;
    }
}

/* control_law._closed_fk: lower intersection of the three spheres |z - E_i| = l2; -1 if they miss */
static int closed_fk(double l2, const Elbow elb[3], double z[3])
{
    double e1x = elb[0].ex, e1y = elb[0].ey, e1z = elb[0].ez;
    double ux = elb[1].ex - e1x, uy = elb[1].ey - e1y, uz = elb[1].ez - e1z;
    double vx = elb[2].ex - e1x, vy = elb[2].ey - e1y, vz = elb[2].ez - e1z;
    double d = sqrt(ux * ux + uy * uy + uz * uz);
    if (d < 1e-12)
        return -1;
    ux = ux / d; uy = uy / d; uz = uz / d;
    double i = ux * vx + uy * vy + uz * vz;
    double wx = vx - i * ux, wy = vy - i * uy, wz = vz - i * uz;
    double j = sqrt(wx * wx + wy * wy + wz * wz);
    if (j < 1e-12)
        return -1;
    wx = wx / j; wy = wy / j; wz = wz / j;
    double px = 0.5 * d;
    double py = (i * i + j * j - 2.0 * i * px) / (2.0 * j);
    double h2 = l2 * l2 - px * px - py * py;
    if (h2 < 0.0)
        return -1;
    double nx = uy * wz - uz * wy, ny = uz * wx - ux * wz, nz = ux * wy - uy * wx;
    double pz = nz > 0.0 ? -sqrt(h2) : sqrt(h2);  /* the solution below the base */
    z[0] = e1x + px * ux + py * wx + pz * nx;
    z[1] = e1y + px * uy + py * wy + pz * ny;
    z[2] = e1z + px * uz + py * wz + pz * nz;
    return 0;
}

/* control_law._forearms_from_z; -1 when a forearm leaves the branch */
static int forearms_from_z(double l2, const Elbow elb[3], const double z[3], Forearm fa[3])
{
    for (int i = 0; i < 3; i++) {
        double wx = (z[0] - elb[i].ex) / l2, wy = (z[1] - elb[i].ey) / l2, dz = (z[2] - elb[i].ez) / l2;
        double dx = elb[i].cr * wx + elb[i].sr * wy, dy = elb[i].cr * wy - elb[i].sr * wx;
        double s2 = -sqrt(dx * dx + dz * dz);  /* branch q2 in (-pi, 0) */
        if (s2 > -1e-9)
            return -1;
        Forearm f = {s2, dy, dx / s2, dz / s2};
        fa[i] = f;
    }
    return 0;
}

/* control_law._directions: rows of N (n, 9) and D_i (dd, 3) */
static void directions(const Elbow elb[3], const Forearm fa[3], double n[9], double dd[3])
{
    for (int i = 0; i < 3; i++) {
        double cr = elb[i].cr, sr = elb[i].sr, c1 = elb[i].c1, s1 = elb[i].s1;
        double s2 = fa[i].s2, c2 = fa[i].c2, s3 = fa[i].s3, c3 = fa[i].c3;
        double dx = s2 * s3;
        n[3 * i] = cr * dx - sr * c2;
        n[3 * i + 1] = sr * dx + cr * c2;
        n[3 * i + 2] = s2 * c3;
        dd[i] = c1 * s2 * c3 - s1 * c2;
    }
}

/* control_law._newton_fk from the angles x (6); returns the iterations, -1 when it does not converge */
static int newton_fk(double l2, const Elbow elb[3], const double x_in[6], double tol, int max_iter, double z[3],
                     Forearm fa[3], double x_out[6])
{
    double x0 = x_in[0], x1 = x_in[1], x2 = x_in[2], x3 = x_in[3], x4 = x_in[4], x5 = x_in[5];
    for (int it = 0; it < max_iter + 1; it++) {
        Forearm f[3] = {{sin(x0), cos(x0), sin(x1), cos(x1)}, {sin(x2), cos(x2), sin(x3), cos(x3)},
                        {sin(x4), cos(x4), sin(x5), cos(x5)}};
        double n[9], w[3][3];
        for (int i = 0; i < 3; i++) {
            double cr = elb[i].cr, sr = elb[i].sr;
            double dx = f[i].s2 * f[i].s3;
            double nx = cr * dx - sr * f[i].c2, ny = sr * dx + cr * f[i].c2, nz = f[i].s2 * f[i].c3;
            n[3 * i] = nx; n[3 * i + 1] = ny; n[3 * i + 2] = nz;
            w[i][0] = elb[i].ex + l2 * nx;
            w[i][1] = elb[i].ey + l2 * ny;
            w[i][2] = elb[i].ez + l2 * nz;
        }
        double ax = w[0][0], ay = w[0][1], az = w[0][2], bx = w[1][0], by = w[1][1], bz = w[1][2];
        double cx = w[2][0], cy = w[2][1], cz = w[2][2];
        double res = fabs(ax - bx);
        res = PY_MAX(res, fabs(ay - by));
        res = PY_MAX(res, fabs(az - bz));
        res = PY_MAX(res, fabs(ax - cx));
        res = PY_MAX(res, fabs(ay - cy));
        res = PY_MAX(res, fabs(az - cz));
        if (res <= tol) {
            /* a far-off guess can converge onto another assembly: keep only the design branch */
            for (int i = 0; i < 3; i++)
                if (f[i].s2 >= 0.0 || f[i].c3 <= 0.0)
                    return -1;
            z[0] = (ax + bx + cx) / 3.0; z[1] = (ay + by + cy) / 3.0; z[2] = (az + bz + cz) / 3.0;
            memcpy(fa, f, sizeof f);
            x_out[0] = x0; x_out[1] = x1; x_out[2] = x2; x_out[3] = x3; x_out[4] = x4; x_out[5] = x5;
            return it;
        }
        double ninv[9];
        if (it == max_iter || inv3(n, ninv) || !(res < 0.5))  /* also catches NaN */
            return -1;
        double b0 = n[0] * ax + n[1] * ay + n[2] * az;
        double b1 = n[3] * bx + n[4] * by + n[5] * bz;
        double b2 = n[6] * cx + n[7] * cy + n[8] * cz;
        double zb[3] = {ninv[0] * b0 + ninv[1] * b1 + ninv[2] * b2, ninv[3] * b0 + ninv[4] * b1 + ninv[5] * b2,
                        ninv[6] * b0 + ninv[7] * b1 + ninv[8] * b2};
        double dq[6];
        for (int i = 0; i < 3; i++) {
            double cr = elb[i].cr, sr = elb[i].sr;
            double s2 = f[i].s2, c2 = f[i].c2, s3 = f[i].s3, c3 = f[i].c3;
            double gx = zb[0] - w[i][0], gy = zb[1] - w[i][1], gz = zb[2] - w[i][2];
            double lx = cr * gx + sr * gy, ly = cr * gy - sr * gx;
            dq[2 * i] = (c2 * s3 * lx - s2 * ly + c2 * c3 * gz) / l2;
            dq[2 * i + 1] = (c3 * lx - s3 * gz) / (l2 * s2);
        }
        x0 = x0 + dq[0]; x1 = x1 + dq[1]; x2 = x2 + dq[2];
        x3 = x3 + dq[3]; x4 = x4 + dq[4]; x5 = x5 + dq[5];
    }
    return -1;
}

/* control_law._inverse_dynamics: servo torques giving wrist acceleration acc (no wrench: the
 * impedance mode is not the flagship's) */
static void inverse_dynamics(const ArmModel *k, const Elbow elb[3], const Forearm fa[3], const double ninv[9],
                             const double dd[3], const double v1s[3], const double xd[6], const double acc[3],
                             double u[3])
{
    double l1 = k->l1, l2 = k->l2, jrot = k->jrot, m1r1g = k->m1r1g, s0 = k->s0, s1m = k->s1, s2m = k->s2;
    double g = k->g, damp = k->damping;
    double ax = acc[0], ay = acc[1], az = acc[2];
    double qa[3], bf[3];
    double sx = 0.0, sy = 0.0, sz = 0.0;
    for (int i = 0; i < 3; i++) {
        double cr = elb[i].cr, sr = elb[i].sr, c1 = elb[i].c1, s1 = elb[i].s1;
        double s2 = fa[i].s2, c2 = fa[i].c2, s3 = fa[i].s3, c3 = fa[i].c3;
        double v1 = v1s[i], v2 = xd[2 * i], v3 = xd[2 * i + 1], di = dd[i];
        double alx = cr * ax + sr * ay, aly = cr * ay - sr * ax;
        /* velocity-product part of the forearm direction's second derivative */
        double vv = v2 * v2 + v3 * v3;
        double cross = 2.0 * v2 * v3;
        double cen = l1 * v1 * v1;  /* elbow centripetal acceleration */
        double tx = alx + l2 * (s2 * s3 * vv - cross * c2 * c3);
        double ty = aly + cen * c1 + l2 * c2 * v2 * v2;
        double tz = az + cen * s1 + l2 * (s2 * c3 * vv + cross * c2 * s3);
        double a1 = (s2 * s3 * tx + c2 * ty + s2 * c3 * tz) / (l1 * di);
        double ey = -l1 * a1 * s1 - cen * c1;  /* elbow acceleration (x component is 0) */
        double ez = l1 * a1 * c1 - cen * s1;
        double fy = aly - ey, fz = az - ez;
        double ezg = ez + g;
        double pmy = s0 * ey + s1m * fy, pmz = s0 * ezg + s1m * fz;
        double pnx = s2m * alx, pny = s1m * ey + s2m * fy, pnz = s1m * ezg + s2m * fz;
        qa[i] = jrot * a1 + m1r1g * c1 + l1 * (c1 * pmz - s1 * pmy) + damp * v1;
        double hb = c2 * s3 * pnx - s2 * pny + c2 * c3 * pnz + damp * v2 / l2;
        double hc = c3 * pnx - s3 * pnz + damp * v3 / (l2 * s2);
        double fx = c2 * s3 * hb + c3 * hc, fyl = -s2 * hb, fzl = c2 * c3 * hb - s3 * hc;
        sx += cr * fx - sr * fyl;
        sy += sr * fx + cr * fyl;
        sz += fzl;
        bf[i] = l1 * (c1 * fzl - s1 * fyl);  /* b_i . F_perp_i */
    }
    double n00 = ninv[0], n01 = ninv[1], n02 = ninv[2], n10 = ninv[3], n11 = ninv[4], n12 = ninv[5];
    double n20 = ninv[6], n21 = ninv[7], n22 = ninv[8];
    sx = sx + 0.0; sy = sy + 0.0; sz = sz + 0.0;  /* + wrench (zero in position mode) */
    double f0 = -(n00 * sx + n10 * sy + n20 * sz);
    double f1 = -(n01 * sx + n11 * sy + n21 * sz);
    double f2 = -(n02 * sx + n12 * sy + n22 * sz);
    u[0] = qa[0] - bf[0] - f0 * l1 * dd[0];
    u[1] = qa[1] - bf[1] - f1 * l1 * dd[1];
    u[2] = qa[2] - bf[2] - f2 * l1 * dd[2];
}

/* control_law.ControlOutput (the fields the sampled controller uses) */
typedef struct {
    double u[3], integral[3], z[3], x[6], xd[6], cond;
    int status;
} ControlOutput;

/* control_law._singular: no torque; the integral untouched */
static void singular(const double integral[3], ControlOutput *out)
{
    memset(out, 0, sizeof *out);
    memcpy(out->integral, integral, sizeof out->integral);
    out->z[0] = out->z[1] = out->z[2] = NAN;
    out->cond = INFINITY;
    out->status = STATUS_SINGULAR;
}

/* control_law.evaluate, position mode (the flagship's: no impedance, no contact force) */
static void law_evaluate(const ControlLawSpec *law, const double y[3], const double yd[3], const double r[3],
                         const double rd[3], const double rdd[3], const double integral[3], double dt,
                         const double *x_guess, ControlOutput *out)
{
    ArmModel k = arm_model(&law->model);
    double l1 = k.l1, l2 = k.l2;
    if (!(isfinite(y[0]) && isfinite(y[1]) && isfinite(y[2]))) {
        singular(integral, out);
        return;
    }
    Elbow elb[3];
    Forearm fa[3];
    double z[3], x[6];
    elbows(&k, y, elb);
    int fk = -1;
    if (x_guess && law->newton)
        fk = newton_fk(l2, elb, x_guess, law->newton_tol, law->newton_max_iter, z, fa, x);
    if (fk < 0) {
        if (closed_fk(l2, elb, z) || forearms_from_z(l2, elb, z, fa)) {
            singular(integral, out);
            return;
        }
        for (int i = 0; i < 3; i++) {  /* control_law._angles */
            x[2 * i] = atan2(fa[i].s2, fa[i].c2);
            x[2 * i + 1] = atan2(fa[i].s3, fa[i].c3);
        }
    }
    double n[9], dd[3], ninv[9];
    directions(elb, fa, n, dd);
    int ninv_missing = inv3(n, ninv);
    double d0 = dd[0], d1 = dd[1], d2 = dd[2];
    double dmin = PY_MIN(PY_MIN(fabs(d0), fabs(d1)), fabs(d2));
    if (ninv_missing || dmin < 1e-9) {
        singular(integral, out);
        memcpy(out->z, z, sizeof z);
        memcpy(out->x, x, sizeof x);
        return;
    }
    double n00 = ninv[0], n01 = ninv[1], n02 = ninv[2], n10 = ninv[3], n11 = ninv[4], n12 = ninv[5];
    double n20 = ninv[6], n21 = ninv[7], n22 = ninv[8];
    /* Frobenius condition number of Jc = N^-1 diag(l1 D) (l1 cancels); N's rows are unit */
    double jc2 = (d0 * d0 * (n00 * n00 + n10 * n10 + n20 * n20) + d1 * d1 * (n01 * n01 + n11 * n11
                  + n21 * n21) + d2 * d2 * (n02 * n02 + n12 * n12 + n22 * n22));
    double cond = sqrt(jc2 * (1.0 / (d0 * d0) + 1.0 / (d1 * d1) + 1.0 / (d2 * d2)));
    int near = cond > law->cond_limit || dmin * law->cond_limit < 1.0;
    int status = near ? STATUS_ILL_CONDITIONED : STATUS_OK;

    /* velocities: N zd = (l1 D_i yd_i), then A_i xd_i = zd - b_i yd_i arm by arm */
    double yd0 = yd[0], yd1 = yd[1], yd2 = yd[2];
    double q0 = l1 * d0 * yd0, q1 = l1 * d1 * yd1, q2 = l1 * d2 * yd2;
    double zdx = n00 * q0 + n01 * q1 + n02 * q2;
    double zdy = n10 * q0 + n11 * q1 + n12 * q2;
    double zdz = n20 * q0 + n21 * q1 + n22 * q2;
    double xd[6];
    for (int i = 0; i < 3; i++) {
        double cr = elb[i].cr, sr = elb[i].sr, c1 = elb[i].c1, s1 = elb[i].s1;
        double s2 = fa[i].s2, c2 = fa[i].c2, s3 = fa[i].s3, c3 = fa[i].c3, ydi = yd[i];
        double rx = cr * zdx + sr * zdy;
        double ry = cr * zdy - sr * zdx + l1 * ydi * s1;
        double rz = zdz - l1 * ydi * c1;
        xd[2 * i] = (c2 * s3 * rx - s2 * ry + c2 * c3 * rz) / l2;
        xd[2 * i + 1] = (c3 * rx - s3 * rz) / (l2 * s2);
    }

    /* outer loop in wrist coordinates */
    double e0 = r[0] - z[0], e1 = r[1] - z[1], e2 = r[2] - z[2];
    double imax = law->integral_max;
    double i0 = PY_MIN(PY_MAX(integral[0] + dt * e0, -imax), imax);
    double i1 = PY_MIN(PY_MAX(integral[1] + dt * e1, -imax), imax);
    double i2 = PY_MIN(PY_MAX(integral[2] + dt * e2, -imax), imax);
    if (imax > 0.0 && PY_MAX(PY_MAX(fabs(i0), fabs(i1)), fabs(i2)) >= imax)
        status |= STATUS_INTEGRAL_CLAMPED;
    double acc[3] = {law->kI * i0 + law->kP * e0 + law->kD * (rd[0] - zdx),
                     law->kI * i1 + law->kP * e1 + law->kD * (rd[1] - zdy),
                     law->kI * i2 + law->kP * e2 + law->kD * (rd[2] - zdz)};
    if (law->feedforward) {
        acc[0] = acc[0] + rdd[0]; acc[1] = acc[1] + rdd[1]; acc[2] = acc[2] + rdd[2];
    }
    double zeros[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    double u[3];
    inverse_dynamics(&k, elb, fa, ninv, dd, law->coriolis ? yd : zeros, law->coriolis ? xd : zeros, acc, u);

    /* control_law._output: saturated torques, or singular if they are not finite */
    if (!(isfinite(u[0]) && isfinite(u[1]) && isfinite(u[2]))) {
        singular(integral, out);
        memcpy(out->z, z, sizeof z);
        memcpy(out->x, x, sizeof x);
        return;
    }
    double lim = law->torque_limit;
    if (PY_MAX(PY_MAX(fabs(u[0]), fabs(u[1])), fabs(u[2])) > lim) {
        status |= STATUS_TORQUE_SATURATED;
        for (int j = 0; j < 3; j++)
            u[j] = PY_MIN(PY_MAX(u[j], -lim), lim);
    }
    memcpy(out->u, u, sizeof u);
    out->integral[0] = i0; out->integral[1] = i1; out->integral[2] = i2;
    memcpy(out->z, z, sizeof z);
    memcpy(out->x, x, sizeof x);
    memcpy(out->xd, xd, sizeof xd);
    out->cond = cond;
    out->status = status;
}

/* DeltaController.reset */
void flagship_controller_reset(Controller *c)
{
    memset(c, 0, sizeof *c);
    c->cond = NAN;
    if (!rot[0][0]) {
        double cr = cos(2.0 * PI / 3.0), sr = sin(2.0 * PI / 3.0);
        rot[0][0] = 1.0; rot[0][1] = 0.0;
        rot[1][0] = cr;  rot[1][1] = sr;
        rot[2][0] = cr;  rot[2][1] = -sr;
    }
}

/* DeltaController.step (no tactile loop: the flagship's tactile input and gain are zero), with
 * control_law.hold (the half-sample lead) and control_law.warm_start */
void flagship_controller_step(Controller *c, const ControlLawSpec *law, const double y[3], const double yd[3],
                              const double r[3], const double rd[3], const double rdd[3])
{
    double dt = (c->status & STATUS_TORQUE_SATURATED) ? 0.0 : law->sample_period;
    ControlOutput out;
    law_evaluate(law, y, yd, r, rd, rdd, c->integral, dt, c->have_x_next ? c->x_next : NULL, &out);
    c->status = out.status;
    c->cond = out.cond;
    double lim = law->torque_limit;
    if (out.status & STATUS_SINGULAR) {
        c->have_x_next = c->have_xd = c->have_u_law = 0;
        for (int j = 0; j < 3; j++)
            c->u[j] = PY_MIN(PY_MAX(c->u[j], -lim), lim);
        return;
    }
    memcpy(c->z, out.z, sizeof c->z);
    memcpy(c->integral, out.integral, sizeof c->integral);
    double u[3] = {out.u[0], out.u[1], out.u[2]};
    if (law->zoh_lead && c->have_u_law) {
        u[0] = 1.5 * out.u[0] - 0.5 * c->u_law[0];
        u[1] = 1.5 * out.u[1] - 0.5 * c->u_law[1];
        u[2] = 1.5 * out.u[2] - 0.5 * c->u_law[2];
        if (!(PY_MAX(PY_MAX(fabs(u[0]), fabs(u[1])), fabs(u[2])) <= lim)) {
            for (int j = 0; j < 3; j++)
                u[j] = PY_MIN(PY_MAX(u[j], -lim), lim);
            c->status |= STATUS_TORQUE_SATURATED;
        }
    }
    memcpy(c->u_law, out.u, sizeof c->u_law);
    c->have_u_law = 1;
    memcpy(c->u, u, sizeof u);
    /* warm start one sample ahead: x + ts xd (+ ts^2/2 xdd by a backward difference) */
    double ts = law->sample_period;
    for (int i = 0; i < 6; i++)
        c->x_next[i] = c->have_xd ? out.x[i] + ts * (1.5 * out.xd[i] - 0.5 * c->xd[i]) : out.x[i] + ts * out.xd[i];
    c->have_x_next = 1;
    memcpy(c->xd, out.xd, sizeof c->xd);
    c->have_xd = 1;
}

/* ------------------------------------------------------------------------------------------------
 * trajectory: mechanics/delta/trajectory.py MinimumJerkPath
 * --------------------------------------------------------------------------------------------- */

/* Python's x ** 2 calls libm's pow(), whose result differs from x * x in the last bit for some x
 * (it does at one sample of the flagship's path). A compiler folds pow(x, 2.0) into x * x, so
 * the call goes through a pointer it cannot see through. */
static double (*volatile libm_pow)(double, double) = pow;

/* trajectory.minimum_jerk: s(tau) = 10 tau^3 - 15 tau^4 + 6 tau^5 and its two derivatives */
static void minimum_jerk(double tau, double out[3])
{
    if (tau <= 0.0) {
        out[0] = 0.0; out[1] = 0.0; out[2] = 0.0;
        return;
    }
    if (tau >= 1.0) {
        out[0] = 1.0; out[1] = 0.0; out[2] = 0.0;
        return;
    }
    double t2 = tau * tau;
    out[0] = t2 * tau * (10.0 + tau * (-15.0 + 6.0 * tau));
    out[1] = 30.0 * t2 * libm_pow(1.0 - tau, 2.0);
    out[2] = 60.0 * tau * (1.0 - tau) * (1.0 - 2.0 * tau);
}

/* MinimumJerkPath.__init__ (trajectory._move_starts: numpy's cumsum adds left to right) */
void flagship_path_init(Path *path, const PathSpec *spec)
{
    path->spec = *spec;
    double before = 0.0;
    for (int k = 0; k < spec->n - 1; k++) {
        path->starts[k] = spec->t0 + before + spec->dwell;
        before += spec->dwell + spec->T[k];
    }
}

/* MinimumJerkPath.evaluate_flat: r, rd, rdd at time t */
void flagship_path_evaluate(const Path *path, double t, double out[9])
{
    const PathSpec *s = &path->spec;
    int k = 0;  /* bisect.bisect_right(starts, t) - 1 */
    while (k < s->n - 1 && !(t < path->starts[k]))
        k++;
    k -= 1;
    if (k < 0) {
        out[0] = s->wp[0][0]; out[1] = s->wp[0][1]; out[2] = s->wp[0][2];
        for (int j = 3; j < 9; j++)
            out[j] = 0.0;
        return;
    }
    double T = s->T[k], m[3];
    minimum_jerk((t - path->starts[k]) / T, m);
    double ds = m[1] / T, dds = m[2] / (T * T);
    for (int j = 0; j < 3; j++) {
        double d = s->wp[k + 1][j] - s->wp[k][j];
        out[j] = s->wp[k][j] + m[0] * d;
        out[3 + j] = ds * d;
        out[6 + j] = dds * d;
    }
}

/* ------------------------------------------------------------------------------------------------
 * the master's classical RK4 (cosim/stepping/native/erk.c with the rk4 tableau, u held)
 * --------------------------------------------------------------------------------------------- */

static int rk4_step(const DeltaParams *p, double pole, double h, const double u[3], const double f[3], double x[18])
{
    double k1[18], k2[18], k3[18], k4[18], xs[18];
    int bad = flagship_state_derivative(p, pole, x, u, f, k1);
    for (int n = 0; n < 18; n++)
        xs[n] = x[n] + h * (0.5 * k1[n]);
    bad |= flagship_state_derivative(p, pole, xs, u, f, k2);
    for (int n = 0; n < 18; n++)
        xs[n] = x[n] + h * (0.0 * k1[n] + 0.5 * k2[n]);
    bad |= flagship_state_derivative(p, pole, xs, u, f, k3);
    for (int n = 0; n < 18; n++)
        xs[n] = x[n] + h * (0.0 * k1[n] + 0.0 * k2[n] + 1.0 * k3[n]);
    bad |= flagship_state_derivative(p, pole, xs, u, f, k4);
    /* b = (1/6, 1/3, 1/3, 1/6), summed as erk.c does: from 0, stage by stage */
    for (int n = 0; n < 18; n++)
        x[n] += h * ((1.0 / 6.0) * k1[n] + (1.0 / 3.0) * k2[n] + (1.0 / 3.0) * k3[n] + (1.0 / 6.0) * k4[n]);
    return bad;
}

/* ------------------------------------------------------------------------------------------------
 * the closed loop (benchmarks/cosim.py Floor.run, the master's Gauss-Seidel order)
 * --------------------------------------------------------------------------------------------- */

static void write_row(double *row, double t, const double z[3], const double zd[3], const double ref[9],
                      const Controller *c, double residual)
{
    row[0] = t;
    memcpy(row + 1, z, 3 * sizeof(double));
    memcpy(row + 4, zd, 3 * sizeof(double));
    memcpy(row + 7, ref, 3 * sizeof(double));
    memcpy(row + 10, c->u, 3 * sizeof(double));
    row[13] = c->status;
    row[14] = residual;
}

/* `steps` communication steps of the flagship from its start; rows ((steps + 1) x ROW_WIDTH, the
 * start included) as the flagship's CSV, and the plant's states ((steps + 1) x 18) unless NULL.
 * Returns 0, or -1 when the plant hit a singularity. */
int flagship_run(const Flagship *fs, long steps, double *rows, double *states)
{
    double x[18], ref[9], z[3], zd[3], residual, energy;
    Path path;
    Controller ctl;
    flagship_path_init(&path, &fs->path);
    flagship_controller_reset(&ctl);
    if (flagship_initial_state(&fs->plant, fs->z0, x))
        return -1;
    /* initialization: the controller samples once at the start (the FMUs do the same) */
    flagship_path_evaluate(&path, fs->start, ref);
    double y[3] = {x[0], x[3], x[6]}, yd[3] = {x[9], x[12], x[15]};
    flagship_controller_step(&ctl, &fs->law, y, yd, ref, ref + 3, ref + 6);
    if (flagship_plant_outputs(&fs->plant, fs->pole, x, ctl.u, fs->f, z, zd, &residual, &energy))
        return -1;
    write_row(rows, fs->start, z, zd, ref, &ctl, residual);
    if (states)
        memcpy(states, x, sizeof x);
    double t_plant = fs->start;  /* the Model Exchange unit's time */
    for (long k = 0; k < steps; k++) {
        double t = fs->start + (double)k * fs->h;   /* the master's communication point */
        double t_end = t + fs->h;                    /* where the trajectory FMU evaluates */
        flagship_path_evaluate(&path, t_end, ref);
        /* fixed_step.c me_step: one rk4 step over the span from the unit's time (not h itself) */
        if (rk4_step(&fs->plant, fs->pole, t_end - t_plant, ctl.u, fs->f, x))
            return -1;
        t_plant = t_end;
        if (flagship_plant_outputs(&fs->plant, fs->pole, x, ctl.u, fs->f, z, zd, &residual, &energy))
            return -1;
        if (k > 0) {  /* the sample at the start was taken at initialization */
            y[0] = x[0]; y[1] = x[3]; y[2] = x[6];
            yd[0] = x[9]; yd[1] = x[12]; yd[2] = x[15];
            flagship_controller_step(&ctl, &fs->law, y, yd, ref, ref + 3, ref + 6);
        }
        write_row(rows + (k + 1) * ROW_WIDTH, fs->start + (double)(k + 1) * fs->h, z, zd, ref, &ctl, residual);
        if (states)
            memcpy(states + (k + 1) * 18, x, sizeof x);
    }
    return 0;
}

/* ------------------------------------------------------------------------------------------------
 * timing loops for benchmarks/native.py (one foreign call per burst, not per kernel call)
 * --------------------------------------------------------------------------------------------- */

/* `calls` state derivatives at x; the volatile pointer makes every call compute afresh */
double flagship_repeat_derivative(const DeltaParams *p, double pole, const double *x, const double *u,
                                  const double *f, long calls)
{
    const double *volatile xp = x;
    double dx[18], check = 0.0;
    for (long i = 0; i < calls; i++) {
        flagship_state_derivative(p, pole, xp, u, f, dx);
        check += dx[17];
    }
    return check;
}

/* A fresh controller stepped through `samples` recorded inputs (y, yd, r, rd, rdd: 15 doubles
 * per sample); the torques into u_out (3 per sample) unless NULL */
double flagship_replay_controller(const ControlLawSpec *law, const double *inputs, long samples, double *u_out)
{
    Controller c;
    double check = 0.0;
    flagship_controller_reset(&c);
    for (long i = 0; i < samples; i++) {
        const double *in = inputs + 15 * i;
        flagship_controller_step(&c, law, in, in + 3, in + 6, in + 9, in + 12);
        if (u_out)
            memcpy(u_out + 3 * i, c.u, sizeof c.u);
        check += c.u[0];
    }
    return check;
}
