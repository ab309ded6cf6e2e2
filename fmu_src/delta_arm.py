"""One arm of the delta robot as an equation model part (the talk's Arms.deltaRobotArmLagrange)."""
import numpy as np

from deltafmi.runtime.equations import Model, Real, cos, der, sin

__all__ = ["DeltaArm"]


class DeltaArm(Model):
    """deltaRobotArmLagrange: one arm's Lagrangian open chain, servo q1, forearm polar q2, azimuth q3."""

    q = Real([-0.3254, -2.1792, 0.0], unit="rad")
    v = Real([0.0] * 3, unit="rad/s")
    tau = Real([0.0] * 3, unit="N.m", description="generalized forces from the loop, the servo and f")
    psi = Real([0.0] * 3, unit="m", description="wrist point in the arm frame")
    energy = Real(unit="J")

    def equations(self):
        p = self.outer
        (s1, s2, s3), (c1, c2, c3) = sin(self.q), cos(self.q)
        v1, v2, v3 = self.v
        mpa = (p.mp + p.payload) / 3.0
        a = p.J1 + p.Jm + (p.m2 + mpa) * p.l1 ** 2
        b = (p.m2 / 2.0 + mpa) * p.l1 * p.l2
        beta = (p.m2 / 3.0 + mpa) * p.l2 ** 2
        g1, g2 = p.g * (p.m1 * p.r1 + (p.m2 + mpa) * p.l1), p.g * (p.m2 / 2.0 + mpa) * p.l2
        m12, m13 = b * (s1 * s2 + c1 * c2 * c3), -b * c1 * s2 * s3
        M = np.array([[a, m12, m13], [m12, beta, 0.0], [m13, 0.0, beta * s2 ** 2]])
        C = np.array([b * ((s1 * c2 - c1 * s2 * c3) * v2 ** 2 - 2.0 * c1 * c2 * s3 * v2 * v3 - c1 * s2 * c3 * v3 ** 2),
                      b * (c1 * s2 - s1 * c2 * c3) * v1 ** 2 - beta * s2 * c2 * v3 ** 2,
                      b * s1 * s2 * s3 * v1 ** 2 + 2.0 * beta * s2 * c2 * v2 * v3])
        G = np.array([g1 * c1, g2 * c2 * c3, -g2 * s2 * s3])
        return [der(self.q) == self.v,
                M @ der(self.v) + C + p.damping * self.v + G == self.tau,
                self.psi == [p.l2 * s2 * s3, p.l0 - p.l3 + p.l1 * c1 + p.l2 * c2, p.l1 * s1 + p.l2 * s2 * c3],
                self.energy == 0.5 * self.v @ M @ self.v + g1 * s1 + g2 * s2 * c3]
