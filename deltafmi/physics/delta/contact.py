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
:class:`deltafmi.physics.contact.ContactSystem`; the loop closures stay inside the model's own
dynamics (``contact_dynamics``), and an impact's effective mass ``1 / (H Y)`` comes from the
constrained response ``Y = d v' / d lambda`` (:meth:`DeltaToolModel.contact_mobility`): the wrist
inertia along ``n`` with the loops closed, not ``H M^-1 H^T`` of the unconnected arms.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from ..contact.material import CompliantMaterial
from ..contact.system import CONTACT, ContactSystem, LagrangianModel, _Evaluation
from ..friction.law import SEPARATED, SLIP_POSITIVE, STICK, FrictionParams, after_stop
from ..friction.system import STOP, Transition
from .contact_kernels import (ToolPlane, contact_law, indicator_pair, plane_evaluation, plane_indicators,
                              plane_outputs)
from .tool_friction import FRICTIONLESS, V_REF, ToolFriction, friction_indicator, tangent_basis, tangential_state
from .dynamics import accelerations, energy, mass_matrix
from .kinematics import arm_bias, inverse_kinematics, joint_rates, wrist_along
from .params import ARM_ROTATIONS, DeltaParams

__all__ = ["Plane", "DeltaToolModel", "RobotContactSystem", "ToolPlaneSystem", "check_friction",
           "make_robot_contact", "robot_start_state"]


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
    """The robot's tool against a plane (:class:`DeltaToolModel`), evaluated by the kernels, with
    Coulomb friction (``friction``, a :class:`~deltafmi.physics.friction.FrictionParams`; None:
    frictionless) while the contact is in CONTACT.

    Friction has modes of its own (:attr:`friction_mode`: SEPARATED without a friction force,
    STICK, SLIP_POSITIVE along the anchored :attr:`axis`), changed at the events of the contact's
    second indicator (:func:`.tool_friction.friction_indicator`; in CONTACT the normal machine
    does not use it): entering CONTACT the tool slips along ``v_t`` if it moves, else it is
    stopped; STICK slips along ``-lambda_t`` once ``|lambda_t| > mu_s lambda_n``; SLIP stops when
    ``v_t . axis`` reaches 0 with ``|v_t|`` ~ 0 (else the axis turns to ``v_t``); a stopped tool
    sticks where it stands if the multiplier STICK needs lies in the static cone, else slips
    against it (:func:`deltafmi.physics.friction.law.after_stop`); leaving CONTACT ends friction.
    Collisions are frictionless (see docs/robot_contact.md). Transitions go to :attr:`log`.
    """

    model: DeltaToolModel

    def __init__(self, model: DeltaToolModel, law, *, friction: FrictionParams | None = None, **kwargs) -> None:
        super().__init__(model, law, **kwargs)
        if friction is not None:
            check_friction(friction)
        self.friction = friction
        self.tangents = tangent_basis(model.plane.normal)
        self.friction_mode = SEPARATED
        self.axis: tuple[float, float] = (1.0, 0.0)
        self.anchor: tuple[float, float] = (0.0, 0.0)
        #: every friction mode change, in order
        self.log: list[Transition] = []

    @property
    def params(self) -> DeltaParams:
        return self.model.params

    def friction_state(self, mode: int | None = None) -> ToolFriction:
        """The kernels' friction: the current mode (or ``mode``), axis and anchor."""
        fr = self.friction
        if fr is None:
            return FRICTIONLESS
        t1, t2 = self.tangents
        return ToolFriction(self.friction_mode if mode is None else int(mode), float(fr.mu_s), float(fr.mu_k),
                            float(fr.c_v), t1, t2, self.axis, self.anchor)

    def kernel_state(self, modes: Sequence[int] | None = None) -> ToolPlane:
        model = self.model
        return ToolPlane(model.plane.normal, model._offset, model.tool, model.pole,
                         contact_law(self, 0, (self.modes if modes is None else modes)[0]), self.friction_state())

    def kernel_evaluation(self, x: np.ndarray, state: ToolPlane) -> tuple:
        h, hdot, lam, vdot, _, _, _ = plane_evaluation(self.params, state, x, self.model.u, self.model.f)
        return [h], [hdot], [lam], vdot

    def event_indicators(self, t: float, x: np.ndarray) -> np.ndarray:
        """The kernels' two indicators (the second is the friction mode's in CONTACT)."""
        return np.array(plane_indicators(self.params, self.kernel_state(), x, self.model.u, self.model.f))

    def energy(self, x: np.ndarray) -> float:
        """Kinetic + potential + elastic energy (J), as the kernels' outputs."""
        return plane_outputs(self.params, self.kernel_state(), x, self.model.u, self.model.f)[7]

    # --- friction modes ----------------------------------------------------------------------
    def initialize(self, t: float, x: np.ndarray) -> None:
        self.friction_mode = SEPARATED
        super().initialize(t, x)

    def update(self, t: float, x: np.ndarray) -> tuple[None, bool]:
        """The normal machine's event iteration, then the friction mode's, until both settle."""
        x = np.asarray(x, float)
        changed_any = False
        for _ in range(8):
            _, changed = super().update(t, x)
            moved = self._friction_transition(t, x)
            changed_any = changed_any or changed or moved
            if not moved:
                break
        self._cache_key = None
        return None, changed_any

    def _tangential(self, x: np.ndarray, mode: int | None = None) -> tuple[float, tuple, ToolFriction]:
        """(lambda_n, (lambda_t1, lambda_t2, v_t1, v_t2), friction) at ``x`` with the friction ``mode``."""
        state = self.kernel_state()._replace(friction=self.friction_state(mode))
        _, _, lam, _, _, _, tangential = plane_evaluation(self.params, state, x, self.model.u, self.model.f)
        return lam, tangential, state.friction

    def _friction_transition(self, t: float, x: np.ndarray) -> bool:
        """One friction change due at ``x`` (True), or none (False)."""
        if self.friction is None or (self.modes[0] != CONTACT and self.friction_mode == SEPARATED):
            return False
        if self.modes[0] != CONTACT:
            return self._set_friction(t, SEPARATED)
        if self.friction_mode == SEPARATED:  # just captured: moving, or stopped
            _, tangential, _ = self._tangential(x, SLIP_POSITIVE)
            v_t = np.array(tangential[2:])
            speed = float(np.linalg.norm(v_t))
            return self._set_friction(t, SLIP_POSITIVE, v_t / speed) if speed > STOP * V_REF else self._stop(t, x)
        lam_n, tangential, state = self._tangential(x)
        if friction_indicator(state, lam_n, tangential) > 0.0:
            return False
        if self.friction_mode == STICK:
            lam_t = np.array(tangential[:2])
            return self._set_friction(t, SLIP_POSITIVE, -lam_t / float(np.linalg.norm(lam_t)))
        v_t = np.array(tangential[2:])
        speed = float(np.linalg.norm(v_t))
        if speed > STOP * V_REF:  # the velocity turned past 90 deg from the axis: re-anchor
            return self._set_friction(t, SLIP_POSITIVE, v_t / speed)
        return self._stop(t, x)

    def _stop(self, t: float, x: np.ndarray) -> bool:
        """The tool at ``v_t = 0``: STICK where it stands if the multiplier STICK needs is inside
        the static cone, else slip against that multiplier."""
        xl = np.asarray(x, float).tolist()
        self.anchor = tangential_state(self.params, self.friction_state(), xl[:9], xl[9:])[0]
        lam_n, tangential, _ = self._tangential(x, STICK)
        axis = after_stop(np.array(tangential[:2]), lam_n, self.friction)
        return self._set_friction(t, STICK) if axis is None else self._set_friction(t, SLIP_POSITIVE, axis)

    def _set_friction(self, t: float, mode: int, axis: np.ndarray | None = None) -> bool:
        if axis is not None:
            self.axis = (float(axis[0]), float(axis[1]))
        if mode != self.friction_mode:
            self.log.append(Transition(t, 0, int(self.friction_mode), int(mode)))
            self.friction_mode = int(mode)
        return True


def check_friction(friction: FrictionParams) -> None:
    """Refuse friction coefficients no contact can have (a one-line ValueError naming them)."""
    mu_s, mu_k, c_v = (float(v) for v in friction)
    if not (mu_s >= 0.0 and mu_k >= 0.0 and c_v >= 0.0):
        raise ValueError(f"friction coefficients must be >= 0, got mu_s = {mu_s:g}, mu_k = {mu_k:g}, viscous = {c_v:g}")
    if mu_k > mu_s:
        raise ValueError(f"friction: the kinetic coefficient mu_k = {mu_k:g} exceeds the static mu_s = {mu_s:g}")


def make_robot_contact(params: DeltaParams, plane: Plane, material: CompliantMaterial,
                       tool: Sequence[float] = (0.0, 0.0, -0.1), pole: float = 5.0,
                       capture_speed: float = 0.05, friction: FrictionParams | None = None) -> ToolPlaneSystem:
    """The robot-on-a-plane contact system (state ``[q, v]``, 18 values, one gap), with Coulomb
    friction in CONTACT if ``friction`` is given."""
    return ToolPlaneSystem(DeltaToolModel(params, plane, tool, pole), material, capture_speed=capture_speed,
                           friction=friction)


def robot_start_state(params: DeltaParams, z0: Sequence[float],
                      zd0: Sequence[float] = (0.0, 0.0, 0.0)) -> np.ndarray:
    """``[q, v]`` with the wrist at ``z0`` moving at ``zd0`` and the loops closed."""
    q = inverse_kinematics(params, z0)
    return np.concatenate([q, joint_rates(params, q, zd0)])
