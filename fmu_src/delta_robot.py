"""Delta robot plant FMU: a thin component over deltafmi.physics.delta (RL5 defaults)."""
import numpy as np

from deltafmi.component import Component, Experiment, Input, Kernel, NativeKernels, Output, Parameter, State
from deltafmi.physics import delta
from deltafmi.physics.delta import dynamics
from deltafmi.physics.delta.jacobian import jacobian_from_values, jacobian_values, state_jacobian
from deltafmi.physics.delta.params import DeltaParams
from deltafmi.models.robot_parameters import RobotParameters

__all__ = ["DeltaRobot"]


#: the outputs, in the order dynamics.plant_outputs returns them
_OUTPUTS = ("y", "yd", "z", "zd", "lam", "residual", "energy")
#: d y / d [q, v, u, f] and d yd / d [q, v, u, f]: the servo joints (constant)
_SERVO = np.zeros((3, 24))
_SERVO[[0, 1, 2], [0, 3, 6]] = 1.0
_SERVO_RATE = np.roll(_SERVO, 9, axis=1)


def _jacobian_blocks(values: np.ndarray) -> dict:
    """DeltaRobot.jacobian()'s matrices from the floats of jacobian_values (the kernel's, or Python's)."""
    pj = jacobian_from_values(values)
    return {"der": pj.dx, "y": _SERVO.copy(), "yd": _SERVO_RATE.copy(), "z": pj.dz, "zd": pj.dzd,
            "lam": pj.dlam, "energy": pj.denergy[None, :]}


class DeltaRobot(RobotParameters, Component):
    """Three-arm delta robot (RL5-1450): stabilised index-1 DAE in nine joint angles.

    States are the nine joint angles q = [q11, q12, q13, q21, ...] (per arm: servo angle, forearm
    polar and azimuth angle) and their rates; the loop-closure multipliers are solved at every
    evaluation. Inputs are the servo torques u and an external force f on the wrist (plate
    centre), applied through the virtual Jacobian. The robot starts at rest with the wrist at z0
    (closed-form inverse kinematics; an unreachable z0 fails initialization with a message
    giving the reachable workspace). Frame: z up, arm 1 servo axis parallel to x at y = l0.
    """

    model_name = "DeltaRobot"
    # outputs that depend on the inputs without passing through the states
    direct_feedthrough = {"lam": ["u", "f"]}
    default_experiment = Experiment(start=0.0, stop=1.0, step=1e-3, tolerance=1e-6)

    pole = Parameter(5.0, unit="1/s", min=0.0,
                     description="Baumgarte pole p: hdd + 2 p hd + p^2 h = 0 stabilises the loops")
    loop_tolerance = Parameter(
        0.0, unit="m", min=0.0,
        description="Model Exchange: after an integrator step with loop residual |h| above this, a step "
        "event projects q and v onto the closed loops (the importer's solver restarts); 0: never, the "
        "drift is then the importer's integration error (Co-Simulation projects after every step)")
    z0 = Parameter([0.0, 0.0, -1.0], unit="m",
                   description="Initial wrist (plate centre) position; the robot starts at rest")

    # nominals scale the solvers' absolute tolerance (atol = rtol * nominal)
    q = State([0.0] * 9, unit="rad", initial="calculated", nominal=0.01,
              description="Joint angles per arm: servo q_i1, forearm polar q_i2, azimuth q_i3")
    v = State([0.0] * 9, unit="rad/s", initial="calculated", nominal=0.01, description="Joint rates dq/dt")

    u = Input([0.0] * 3, unit="N.m", description="Servo torques")
    f = Input([0.0] * 3, unit="N", description="External force on the wrist, world frame")

    y = Output(shape=3, unit="rad", description="Servo angles q_i1 (measured)")
    yd = Output(shape=3, unit="rad/s", description="Servo rates")
    z = Output(shape=3, unit="m", description="Wrist (plate centre) position")
    zd = Output(shape=3, unit="m/s", description="Wrist velocity, Jv v")
    lam = Output(
        shape=6, unit="N", name="lambda", description="Loop-closure forces (world): [1:3] on arm 1's wrist from "
        "closing with arm 2 (minus on arm 2), [4:6] likewise with arm 3")
    residual = Output(unit="m", description="Loop-closure residual |h(q)| (Euclidean norm)")
    energy = Output(unit="J", description="Kinetic plus potential energy (zero at z = 0)")

    #: what the FMU's C layer computes itself (generated from the same kernels as the methods below)
    native = NativeKernels(
        derivatives=Kernel(dynamics.state_derivative, "_plant", "states", "u", "f", "pole"),
        outputs=Kernel(dynamics.plant_outputs, "_plant", "q", "v", "u", "f", "pole", returns=_OUTPUTS),
        project=Kernel(dynamics.project_state, "_plant", "q", "v", returns=("q", "v")),
        jacobian=Kernel(jacobian_values, "_plant", "q", "v", "u", "f", "pole", then=_jacobian_blocks),
        drift=Kernel(dynamics.loop_drifted, "_plant", "q", "loop_tolerance"),
        attributes={"_plant": DeltaParams},
        # CVODE's Newton matrix in Co-Simulation: jacobian()'s state block, its KKT solve in C too
        state_jacobian=Kernel(state_jacobian, "_plant", "states", "u", "f", "pole"))

    def setup(self) -> None:
        self._plant = None  # DeltaParams, built from the parameters at initialization

    def initialize(self, t: float) -> None:
        self._plant = self.robot_params()
        self.q = delta.inverse_kinematics(self._plant, self.z0)
        self.v = 0.0

    def project(self, t: float) -> None:
        """Close the loops (mass-weighted, least kinetic change): CS after every solver step, ME at
        a step event once the residual exceeds loop_tolerance."""
        self.q, self.v = delta.project_to_constraints(self._plant, self.q, self.v)

    def needs_projection(self, t: float) -> bool:
        return dynamics.loop_drifted(self._plant, self.q, self.loop_tolerance)

    def derivatives(self, t: float) -> list:
        return delta.state_derivative(self._plant, self.states, self.u, self.f, self.pole)

    def jacobian(self, t: float) -> dict:
        """Exact partial derivatives (deltafmi.physics.delta.jacobian); the residual |h|, not
        differentiable on the closed loops, is left to the runtime's differences."""
        return _jacobian_blocks(np.array(jacobian_values(self._plant, self.q, self.v, self.u, self.f, self.pole)))

    def outputs(self, t: float) -> None:
        y, yd, z, zd, lam, residual, energy = dynamics.plant_outputs(self._plant, self.q, self.v, self.u, self.f,
                                                                     self.pole)
        self.write_reals((*y, *yd, *z, *zd, *lam, residual, energy), *_OUTPUTS)
