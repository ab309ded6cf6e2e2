"""Independent reference for the delta robot: Lagrange equations in the three servo angles only.

No joint angles q_i2, q_i3 anywhere: the wrist comes from a closed-form forward kinematics written
differently from the library's, derivatives by complex step and finite differences. Used by the
library tests and the FMU tests alike.
"""
import numpy as np

from deltafmi.physics import delta as d

ROT = np.stack(d.ARM_ROTATIONS)  # (3, 3, 3)
SERVO = [0, 3, 6]



def fk_minimal(p, y):
    """Wrist from servo angles, batched and complex-step safe: two linear sphere differences give
    (x, y) affine in z, sphere 1 then a quadratic in z whose lower root is the platform."""
    y = np.asarray(y)
    rad = (p.l0 - p.l3) + p.l1 * np.cos(y)  # (..., 3)
    local = np.stack([np.zeros_like(rad), rad, p.l1 * np.sin(y)], axis=-1)  # (..., 3, 3)
    C = np.einsum("iab,...ib->...ia", ROT, local)  # centres C_i (world)
    D = C[..., 1:, :] - C[..., :1, :]  # (..., 2, 3)
    rhs = 0.5 * (np.sum(C[..., 1:, :] ** 2, -1) - np.sum(C[..., :1, :] ** 2, -1))
    A = D[..., :2]
    det = A[..., 0, 0] * A[..., 1, 1] - A[..., 0, 1] * A[..., 1, 0]
    inv = np.stack([np.stack([A[..., 1, 1], -A[..., 0, 1]], -1),
                    np.stack([-A[..., 1, 0], A[..., 0, 0]], -1)], -2) / det[..., None, None]
    e = np.einsum("...ab,...b->...a", inv, rhs)  # x, y at z = 0
    g = -np.einsum("...ab,...b->...a", inv, D[..., 2])  # d(x, y)/dz
    c1 = C[..., 0, :]
    w = e - c1[..., :2]
    qa = 1.0 + np.sum(g * g, -1)
    qb = 2.0 * (np.sum(g * w, -1) - c1[..., 2])
    qc = np.sum(w * w, -1) + c1[..., 2] ** 2 - p.l2 ** 2
    z = (-qb - np.sqrt(qb * qb - 4 * qa * qc)) / (2 * qa)
    return np.concatenate([e + g * z[..., None], z[..., None]], -1)


class MinimalModel:
    """Lagrange equations in the servo angles y only; no joint angles q_i2, q_i3 anywhere."""

    CS = 1e-30  # complex step

    def __init__(self, p, u, f):
        self.p, self.u, self.f = p, np.asarray(u, float), np.asarray(f, float)

    def jac_and_z(self, ys):
        """Wrist z and Jc = dz/dy at a batch of points ys (n, 3), by complex step."""
        pts = ys[:, None, :] + 1j * self.CS * np.eye(3)[None]
        zc = fk_minimal(self.p, pts)  # (n, 3 dirs, 3 coords)
        return zc[:, 0].real, np.swapaxes(zc.imag / self.CS, 1, 2)

    def potential(self, y, z):
        p = self.p
        elbow_z = p.l1 * np.sin(y)
        return p.g * (np.sum(p.m1 * p.r1 * np.sin(y) + p.m2 * 0.5 * (elbow_z + z[..., 2:3]), -1)
                      + (p.mp + p.payload) * z[..., 2])

    def mass(self, ys):
        """M_y at a batch of points (n, 3) -> (n, 3, 3)."""
        p = self.p
        _, Jc = self.jac_and_z(ys)
        n = len(ys)
        M = np.broadcast_to((p.J1 + p.Jm) * np.eye(3), (n, 3, 3)).copy()
        M += (p.mp + p.payload) * np.einsum("nai,naj->nij", Jc, Jc)
        for i in range(3):
            a = np.zeros((n, 3, 3))  # elbow velocity map: only column i
            a[:, :, i] = np.einsum("ab,nb->na", ROT[i], np.stack(
                [np.zeros(n), -p.l1 * np.sin(ys[:, i]), p.l1 * np.cos(ys[:, i])], -1))
            aa = np.einsum("nai,naj->nij", a, a)
            aj = np.einsum("nai,naj->nij", a, Jc)
            M += p.m2 / 3 * (aa + 0.5 * (aj + np.swapaxes(aj, 1, 2))
                             + np.einsum("nai,naj->nij", Jc, Jc))
        return M

    def rhs(self, t, x):
        y, yd = x[:3], x[3:]
        eps = 1e-5
        scale = max(1.0, np.linalg.norm(yd))  # keep the step along yd at most eps
        pts = np.vstack([y, y + eps / scale * yd, y - eps / scale * yd, y + eps * np.eye(3),
                         y - eps * np.eye(3)])
        Ms = self.mass(pts)
        Mdot = (Ms[1] - Ms[2]) * (scale / (2 * eps))
        dT = np.array([yd @ (Ms[3 + k] - Ms[6 + k]) @ yd for k in range(3)]) / (4 * eps)
        # potential gradient by complex step through the FK
        yc = y + 1j * self.CS * np.eye(3)
        dV = self.potential(yc, fk_minimal(self.p, yc)).imag / self.CS
        _, Jc = self.jac_and_z(y[None])
        Q = self.u + Jc[0].T @ self.f
        ydd = np.linalg.solve(Ms[0], Q - dV - (Mdot @ yd - dT))
        return np.concatenate([yd, ydd])


CASES = {
    # two free falls from rest; the symmetric one passes the all-stretched pose at t = 0.46 s
    "fall-centre": ((0.0, 0.0, -1.0), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
    "fall-offset": ((0.2, -0.1, -0.9), (0.0, 0.0, 0.0), (0.0, 0.0, 0.0)),
    # constant servo torques (near the holding torques 28, 21, 4 N m) and a constant wrist force
    "torque-force": ((-0.25, 0.3, -1.05), (30.0, 15.0, 10.0), (15.0, -20.0, 30.0)),
}
