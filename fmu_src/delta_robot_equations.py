"""The talk's Modelica delta robot (deltaRobotLagrange) as equations: three arms, one loop constraint."""
import math

import numpy as np

from deltafmi.component import Experiment, Input, Output, Parameter
from deltafmi.models.delta_arm import DeltaArm
from deltafmi.models.robot_parameters import RobotParameters
from deltafmi.runtime.equations import EquationComponent, Real, cat, der, jacobian, sqrt

__all__ = ["DeltaRobotEquations"]


def rot_z(angle: float) -> np.ndarray:
    """Rotation about z (Utilities.RotZ)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


ROT2, ROT3 = rot_z(2.0 * math.pi / 3.0), rot_z(-2.0 * math.pi / 3.0)
B = np.array([1.0, 0.0, 0.0])  # input torque vector


class DeltaRobotEquations(RobotParameters, EquationComponent):
    """Three-arm delta robot (RL5-1450) written as the talk's Modelica listing: equations, not a solution.

    Three instances of one arm model, the multipliers lambda[6], the loop constraint h0 and its
    stabilisation h2 + 2 p h1 + p^2 h0 = 0 with h1 = der(h0), h2 = der(h1): the compiler
    differentiates h0 and solves the linear system in der(v), tau and lambda. Same parameters,
    inputs and outputs as DeltaRobot.
    """

    model_name = "DeltaRobotEquations"
    direct_feedthrough = {"lam": ["u", "f"]}
    default_experiment = Experiment(start=0.0, stop=1.0, step=1e-3, tolerance=1e-6)

    pole = Parameter(5.0, unit="1/s", min=0.0, description="Baumgarte pole p: hdd + 2 p hd + p^2 h = 0")
    loop_tolerance = Parameter(0.0, unit="m", min=0.0, description="Unused here (DeltaRobot's ME projection)")
    z0 = Parameter([0.0, 0.0, -1.0], unit="m", description="Initial wrist position; the robot starts at rest")
    u = Input([0.0] * 3, unit="N.m", description="Servo torques")
    f = Input([0.0] * 3, unit="N", description="External force on the wrist, world frame")
    y = Output(shape=3, unit="rad", description="Servo angles q_i1 (measured)")
    yd = Output(shape=3, unit="rad/s", description="Servo rates")
    z = Output(shape=3, unit="m", description="Wrist (plate centre) position")
    zd = Output(shape=3, unit="m/s", description="Wrist velocity")
    lam = Output(shape=6, unit="N", name="lambda", description="Loop-closure forces (world)")
    residual = Output(unit="m", description="Loop-closure residual |h(q)|")
    energy = Output(unit="J", description="Kinetic plus potential energy (zero at z = 0)")
    arm1, arm2, arm3 = DeltaArm(), DeltaArm(), DeltaArm()
    h0, h1, h2 = Real(shape=6, unit="m"), Real(shape=6, unit="m/s"), Real(shape=6, unit="m/s2")

    def equations(self):
        a1, a2, a3 = self.arm1, self.arm2, self.arm3
        dz1, dz2, dz3 = (jacobian(a1.psi, a1.q) / 3.0, ROT2 @ jacobian(a2.psi, a2.q) / 3.0,
                         ROT3 @ jacobian(a3.psi, a3.q) / 3.0)
        la, lb = self.lam[0:3], self.lam[3:6]
        return [a1.tau == 3.0 * dz1.T @ la + 3.0 * dz1.T @ lb + dz1.T @ self.f + B * self.u[0],
                a2.tau == -3.0 * dz2.T @ la + B * self.u[1] + dz2.T @ self.f,
                a3.tau == -3.0 * dz3.T @ lb + B * self.u[2] + dz3.T @ self.f,
                self.h0 == cat(a1.psi - ROT2 @ a2.psi, a1.psi - ROT3 @ a3.psi),
                self.h1 == der(self.h0),
                self.h2 == der(self.h1),
                0.0 == self.h2 + 2.0 * self.pole * self.h1 + self.pole ** 2 * self.h0,
                self.y == [a1.q[0], a2.q[0], a3.q[0]],
                self.yd == [a1.v[0], a2.v[0], a3.v[0]],
                self.z == (a1.psi + ROT2 @ a2.psi + ROT3 @ a3.psi) / 3.0,
                self.zd == der(self.z),
                self.residual == sqrt(self.h0 @ self.h0),
                self.energy == a1.energy + a2.energy + a3.energy]

    def initial_equations(self):
        return [self.h0 == 0.0, self.z == self.z0, self.arm1.v == 0.0, self.arm2.v == 0.0, self.arm3.v == 0.0]
