"""The delta robot touching the world: robot + task as one Lagrangian system with gap functions.

The seed talk: "Robot + Task represented as Lagrangian system + constraint functions h_i(q)". The
robot is the stabilised index-1 DAE of :mod:`.dynamics` (nine joint angles, six loop-closure
multipliers); a tool fixed to the travelling plate (which only translates) has its tip at
``z(q) + tool``, and a rigid plane through ``(0, 0, height)`` with unit normal ``n`` gives the gap

    h(q) = n . (z(q) + tool - (0, 0, height)),      H = dh/dq = n^T Jv(q),

with ``z`` the wrist (the mean of the three arms' wrist points, whose derivative is exactly
``Jv v``). A normal force ``lambda`` therefore enters the robot as ``H^T lambda = Jv^T (n lambda)``:
the plant's external wrist force, which the DAE solve already applies. The unilateral constraint
``h >= 0`` runs through the FREE / COLLISION / CONTACT machine of
:class:`deltafmi.mechanics.contact.ContactSystem`; the loop closures stay inside the model's own
dynamics (``contact_dynamics``), and an impact's effective mass ``1 / (H Y)`` comes from the
constrained response ``Y = d v' / d lambda`` (:meth:`DeltaToolModel.contact_mobility`): the wrist
inertia along ``n`` with the loops closed, not ``H M^-1 H^T`` of the unconnected arms.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..contact.material import CompliantMaterial
from ..contact.system import ContactSystem, LagrangianModel, _Evaluation
from .contact_kernels import ToolPlane, contact_law, indicator_pair, plane_evaluation, plane_outputs
from .dynamics import accelerations, energy, mass_matrix
from .kinematics import arm_bias, inverse_kinematics, joint_rates, wrist_along
from .params import ARM_ROTATIONS, DeltaParams

__all__ = ["Plane", "DeltaToolModel", "RobotContactSystem", "ToolPlaneSystem", "make_robot_contact",
           "robot_start_state"]


@dataclass(frozen=True)
class Plane:
    """A rigid plane crossing the robot axis (x = y = 0) at ``height``, with ``normal`` pointing
    out of the body (towards the robot; normalised here). Its gap is the signed distance."""

    height: float = -1.15
    normal: tuple[float, float, float] = (0.0, 0.0, 1.0)

    def __post_init__(self) -> None:
        n = np.asarray(self.normal, dtype=float).reshape(-1)
        norm = float(np.linalg.norm(n)) if n.shape == (3,) else 0.0
        if not norm > 0.0:
            raise ValueError(f"surface normal must be a non-zero 3-vector, got {self.normal!r}")
        object.__setattr__(self, "normal", tuple(float(c) / norm for c in n))

    def gap(self, point: Sequence[float]) -> float:
        """Signed distance of ``point`` from the plane (m), positive on the robot's side."""
        nx, ny, nz = self.normal
        return nx * point[0] + ny * point[1] + nz * (point[2] - self.height)


class DeltaToolModel(LagrangianModel):
    """The delta robot with a tool tip above a plane: one gap, the DAE as the model's dynamics.

    Inputs as attributes: ``u`` servo torques (N m) and ``f`` an external wrist force (N, world).
    """

    n_q = 9
    n_c = 1

    def __init__(self, params: DeltaParams, plane: Plane, tool: Sequence[float] = (0.0, 0.0, -0.1),
                 pole: float = 5.0) -> None:
        self.params, self.plane, self.pole = params, plane, float(pole)
        self.tool = tuple(float(c) for c in tool)
        self.u = [0.0, 0.0, 0.0]
        self.f = [0.0, 0.0, 0.0]
        self._last_key: bytes = b""
        self._last: tuple = (0.0, ())
        n = plane.normal
        # h = n . mean_i P_i + offset
        self._offset = sum(n[k] * self.tool[k] for k in range(3)) - n[2] * plane.height

    # --- geometry ---------------------------------------------------------------------------
    def _arms(self, q: np.ndarray) -> tuple[float, tuple]:
        """n . z(q) and n^T Jv(q); the machine asks for gap and Jacobian at the same q in turn."""
        key = q.tobytes() if isinstance(q, np.ndarray) else bytes(np.asarray(q, float))
        if key != self._last_key:
            ql = q.tolist() if isinstance(q, np.ndarray) else [float(t) for t in q]
            self._last_key, self._last = key, wrist_along(self.params, self.plane.normal, ql)
        return self._last

    def gaps(self, q: np.ndarray) -> np.ndarray:
        """``[h]``: the tool tip's signed distance from the plane (m)."""
        return np.array([self._arms(q)[0] + self._offset])

    def gap_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``H = n^T Jv(q)``, shape (1, 9)."""
        return np.array([self._arms(q)[1]])

    def gap_jacobian_dot_v(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``(d/dt H) v = n . mean_i R_i (d/dt dpsi/dq) v_i``."""
        p, n = self.params, np.asarray(self.plane.normal)
        q, v = np.asarray(q, float), np.asarray(v, float)
        bias = sum(r @ arm_bias(p, q[3 * i:3 * i + 3], v[3 * i:3 * i + 3])
                   for i, r in enumerate(ARM_ROTATIONS)) / 3.0
        return np.array([float(n @ bias)])

    def wrist_force(self, lam: float) -> list[float]:
        """External wrist force plus the contact force ``n lambda`` (N, world)."""
        n = self.plane.normal
        return [self.f[k] + n[k] * lam for k in range(3)]

    # --- dynamics --------------------------------------------------------------------------
    def contact_dynamics(self, t: float, q: np.ndarray, v: np.ndarray, H: np.ndarray,
                         lam: np.ndarray) -> np.ndarray:
        """Joint accelerations of the closed-loop DAE with the contact force on the wrist."""
        return accelerations(self.params, q, v, self.u, self.wrist_force(float(lam[0])), self.pole)[0]

    def contact_mobility(self, t: float, q: np.ndarray, v: np.ndarray, H: np.ndarray,
                         rows: Sequence[int]) -> np.ndarray:
        """``d v' / d lambda``: the DAE is affine in the wrist force, so the difference of two
        solves (unit normal force and none) is exact up to round-off."""
        base = accelerations(self.params, q, v, self.u, self.f, self.pole)[0]
        pushed = accelerations(self.params, q, v, self.u, self.wrist_force(1.0), self.pole)[0]
        return np.column_stack([pushed - base for _ in rows])

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Block-diagonal mass matrix of the three arms (kinetic energy)."""
        return mass_matrix(self.params, q)

    def potential_energy(self, q: np.ndarray) -> float:
        """Gravity potential, zero in the base plane."""
        return energy(self.params, q, np.zeros(9))

    def inputs_key(self, t: float, q: np.ndarray, v: np.ndarray) -> tuple:
        """The inputs ``u`` and ``f``."""
        return (*self.u, *self.f)

    def effective_mass(self, q: np.ndarray) -> float:
        """Inertia the plane feels at the tool, ``1 / (H Y)`` (kg), with the loops closed."""
        q = np.asarray(q, float)
        H = self.gap_jacobian(q)
        return 1.0 / float(H[0] @ self.contact_mobility(0.0, q, np.zeros(9), H, [0])[:, 0])


class RobotContactSystem(ContactSystem):
    """A :class:`ContactSystem` of compliant contacts that evaluates between events with the float
    kernels of :mod:`.contact_kernels` (what the contact FMUs compile to C): the event iteration,
    the effective masses and the capture decisions stay the machine's, made on exactly the
    numbers of the kernels. The capture decision's load estimate (a rigid CONTACT) keeps the
    machine's own solve."""

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        if any(material is None for material in self.materials):
            raise ValueError(f"{type(self).__name__}: every contact needs a compliant material")

    @property
    def params(self) -> DeltaParams:
        """The robot's parameters (the kernels' first argument)."""
        raise NotImplementedError

    def kernel_state(self, modes: Sequence[int] | None = None) -> tuple:
        """The kernels' description of the contacts in ``modes`` (default: the current ones)."""
        raise NotImplementedError

    def kernel_evaluation(self, x: np.ndarray, state: tuple) -> tuple:
        """(gaps, their rates, contact forces, v') of the kernels at ``x``."""
        raise NotImplementedError

    def _solve_unguarded(self, t: float, x: np.ndarray, modes: np.ndarray, rigid: int | None) -> _Evaluation:
        if rigid is not None:
            return super()._solve_unguarded(t, x, modes, rigid)
        h, hdot, lam, vdot = self.kernel_evaluation(x, self.kernel_state(modes))
        q, _ = self.split(np.asarray(x, float))
        return _Evaluation(np.array(h), np.array(hdot), self.model.gap_jacobian(q), np.array(lam), np.array(vdot))

    def _indicator_pair(self, i: int, ev: _Evaluation) -> tuple[float, float]:
        return indicator_pair(contact_law(self, i, self.modes[i]), float(ev.h[i]), float(ev.hdot[i]))


class ToolPlaneSystem(RobotContactSystem):
    """The robot's tool against a plane (:class:`DeltaToolModel`), evaluated by the kernels."""

    model: DeltaToolModel

    @property
    def params(self) -> DeltaParams:
        return self.model.params

    def kernel_state(self, modes: Sequence[int] | None = None) -> ToolPlane:
        model = self.model
        return ToolPlane(model.plane.normal, model._offset, model.tool, model.pole,
                         contact_law(self, 0, (self.modes if modes is None else modes)[0]))

    def kernel_evaluation(self, x: np.ndarray, state: ToolPlane) -> tuple:
        h, hdot, lam, vdot, _, _ = plane_evaluation(self.params, state, x, self.model.u, self.model.f)
        return [h], [hdot], [lam], vdot

    def energy(self, x: np.ndarray) -> float:
        """Kinetic + potential + elastic energy (J), as the kernels' outputs."""
        return plane_outputs(self.params, self.kernel_state(), x, self.model.u, self.model.f)[7]


def make_robot_contact(params: DeltaParams, plane: Plane, material: CompliantMaterial,
                       tool: Sequence[float] = (0.0, 0.0, -0.1), pole: float = 5.0,
                       capture_speed: float = 0.05) -> ToolPlaneSystem:
    """The robot-on-a-plane contact system (state ``[q, v]``, 18 values, one gap)."""
    return ToolPlaneSystem(DeltaToolModel(params, plane, tool, pole), material, capture_speed=capture_speed)


def robot_start_state(params: DeltaParams, z0: Sequence[float],
                      zd0: Sequence[float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """``[q, v]`` with the wrist at ``z0`` moving at ``zd0`` and the loops closed."""
    q = inverse_kinematics(params, z0)
    return np.concatenate([q, joint_rates(params, q, zd0)])
