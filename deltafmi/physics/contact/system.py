"""Multi-mode (FREE / COLLISION / CONTACT) contact for a Lagrangian system, FMU-shaped.

The system ``q' = v``, ``M(q) v' = Q(t, q, v) + sum_i H_i(q)^T lambda_i`` with
``Q = B u - C(q, v) v - d v - g(q)`` and gap functions ``h_i(q) >= 0``, ``H_i = dh_i/dq``.
Every constraint has a mode:

* FREE: ``lambda_i = 0``.
* COLLISION: the compliant law of :mod:`.collision_law` in force form,
  ``lambda_i = m_eff_i * a(delta_i, delta_i')`` with ``m_eff_i = 1 / (H_i M^-1 H_i^T)`` frozen at
  the impact instant. Each contact is its own two-body impact: touching chains pass a wave.
* CONTACT: the talk's soft stabilised constraint ``h'' + alpha1 h' + alpha0 h = 0``, solved jointly
  for the multipliers of all contacts in CONTACT, while ``lambda_i > 0``; or, for a contact whose
  law is a :class:`~.material.CompliantMaterial`, its spring-damper ``(k delta + c delta')_+``.

The model's own dynamics may carry constraints of its own (a closed-loop robot): such a model
supplies ``contact_dynamics`` and ``contact_mobility`` instead of ``M`` and ``Q``.

Transitions happen only at events (two indicators per constraint, fixed count) and never change
the continuous state. :class:`ContactSystem` maps 1:1 onto a Model-Exchange FMU: ``derivatives``,
``event_indicators``, ``update``, ``energy``, ``contact_forces``. Unused degrees of freedom and
constraints (a cradle FMU allocated for 7 balls running 3) are frozen: zero derivatives, zero
force, indicators constant +1.
"""
from __future__ import annotations

from enum import IntEnum
from typing import Optional, Sequence, Union

import numpy as np

from .collision_law import CollisionLaw
from .material import CompliantMaterial

__all__ = ["COLLISION", "CONTACT", "ContactSystem", "EPS", "FREE", "LagrangianModel", "Mode"]

#: a contact's law: a collision law (rigid contact: the talk's stabilised constraint in CONTACT)
#: or a compliant material (its spring-damper in CONTACT, a matched collision law in COLLISION)
Law = Union[CollisionLaw, CompliantMaterial]


#: relative offset of the indicators (see ``ContactSystem._indicator_pair``)
EPS = 1e-9


class Mode(IntEnum):
    """Mode of one constraint (exposed as an Integer: 0, 1, 2)."""

    FREE = 0
    COLLISION = 1
    CONTACT = 2


# plain ints for the hot paths (an IntEnum member lookup costs a few microseconds per evaluation)
FREE, COLLISION, CONTACT = int(Mode.FREE), int(Mode.COLLISION), int(Mode.CONTACT)


class LagrangianModel:
    """A mechanical system with constraint (gap) functions. Subclass and fill in the methods.

    Attributes ``n_q`` (coordinates) and ``n_c`` (constraints) must be set by the subclass.
    """

    n_q: int = 0
    n_c: int = 0

    def mass_matrix(self, q: np.ndarray) -> np.ndarray:
        """Symmetric positive definite ``M(q)``, shape (n_q, n_q)."""
        raise NotImplementedError

    def applied_forces(self, t: float, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """All generalised forces except contact: ``B u - C(q, v) v - d v - g(q)``."""
        raise NotImplementedError

    def potential_energy(self, q: np.ndarray) -> float:
        """Potential energy of the conservative part of ``g(q)``."""
        return 0.0

    def gaps(self, q: np.ndarray) -> np.ndarray:
        """Constraint functions ``h_i(q)``, shape (n_c,); >= 0 when not penetrating."""
        raise NotImplementedError

    def gap_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``H = dh/dq``, shape (n_c, n_q)."""
        raise NotImplementedError

    def gap_jacobian_dot_v(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``(d/dt H) v`` so that ``h'' = H v' + (d/dt H) v``. Default: central difference."""
        scale = float(np.max(np.abs(v))) if v.size else 0.0
        if scale == 0.0:
            return np.zeros(self.n_c)
        eps = 1e-6 / scale
        dH = (self.gap_jacobian(q + eps * v) - self.gap_jacobian(q - eps * v)) / (2.0 * eps)
        return dH @ v

    def kinetic_energy(self, q: np.ndarray, v: np.ndarray) -> float:
        """``v^T M v / 2``."""
        return 0.5 * float(v @ self.mass_matrix(q) @ v)

    def inputs_key(self, t: float, q: np.ndarray, v: np.ndarray) -> object:
        """A value (compared with ``==``) that differs whenever the dynamics at the same
        ``(t, q, v)`` may differ: the model's inputs, for caching. Default: the applied forces."""
        return np.asarray(self.applied_forces(t, q, v), float).tobytes()

    # Optional, both or neither: dynamics with constraints of the model's own (closed loops).
    def contact_dynamics(self, t: float, q: np.ndarray, v: np.ndarray, H: np.ndarray,
                         lam: np.ndarray) -> np.ndarray:
        """``v'`` under the contact multipliers ``lam`` (force ``H^T lam``), shape (n_q,).

        Override (with :meth:`contact_mobility`) when ``M v' = Q + H^T lam`` is not the whole
        story, e.g. a robot whose closed kinematic loops add multipliers of their own. By default
        :class:`ContactSystem` solves that equation itself (honouring its frozen coordinates).
        """
        raise NotImplementedError

    def contact_mobility(self, t: float, q: np.ndarray, v: np.ndarray, H: np.ndarray,
                         rows: Sequence[int]) -> np.ndarray:
        """``d v' / d lam_i`` for the constraints ``rows``, shape (n_q, len(rows)): ``M^-1 H_i^T``
        for a free system, the constrained response for a model with loops of its own."""
        raise NotImplementedError


class _Evaluation:
    """Everything the modes need at one (t, x), computed once."""

    __slots__ = ("h", "hdot", "H", "lam", "vdot")

    def __init__(self, h: np.ndarray, hdot: np.ndarray, H: np.ndarray, lam: np.ndarray,
                 vdot: np.ndarray) -> None:
        self.h, self.hdot, self.H, self.lam, self.vdot = h, hdot, H, lam, vdot


class ContactSystem:
    """FREE / COLLISION / CONTACT state machine over a :class:`LagrangianModel`.

    State vector ``x = [q, v]`` (length ``2 n_q``). Discrete state: ``modes`` and, per constraint,
    the effective mass ``m_eff`` and impact speed frozen at the last impact.

    Parameters: ``law`` one law or one per constraint, each a :class:`CollisionLaw` (CONTACT is then
    the stabilised constraint) or a :class:`CompliantMaterial` (CONTACT is its spring-damper, and
    each impact gets the collision law matched to it); ``alpha0``, ``alpha1`` the stabilised
    CONTACT (slow system) law; ``capture_speed`` the rebound speed below which a loaded contact is
    captured into CONTACT instead of leaving (0 disables CONTACT); ``active_dofs`` /
    ``active_constraints`` boolean masks for frozen, unused parts.
    """

    def __init__(self, model: LagrangianModel, law: Union[Law, Sequence[Law]],
                 *, alpha0: float = 100.0, alpha1: float = 20.0, capture_speed: float = 0.01,
                 active_dofs: Optional[Sequence[bool]] = None,
                 active_constraints: Optional[Sequence[bool]] = None) -> None:
        self.model = model
        n_q, n_c = model.n_q, model.n_c
        laws = [law] * n_c if isinstance(law, (CollisionLaw, CompliantMaterial)) else list(law)
        if len(laws) != n_c:
            raise ValueError(f"need {n_c} collision laws, got {len(laws)}")
        #: per constraint: its compliant material, or None (rigid: stabilised CONTACT)
        self.materials: list[Optional[CompliantMaterial]] = [
            law_i if isinstance(law_i, CompliantMaterial) else None for law_i in laws]
        #: per constraint: the collision law in force (for a material, matched to the effective
        #: mass of the last impact; to 1 kg before the first, which only scales indicators)
        self.laws: list[CollisionLaw] = [law_i.collision_law(1.0) if isinstance(law_i, CompliantMaterial)
                                         else law_i for law_i in laws]
        self.alpha0, self.alpha1 = float(alpha0), float(alpha1)
        self.capture_speed = float(capture_speed)
        self.active_dofs = np.ones(n_q, bool) if active_dofs is None else np.asarray(active_dofs, bool)
        self.active_constraints = (np.ones(n_c, bool) if active_constraints is None
                                   else np.asarray(active_constraints, bool))
        self._dofs = np.flatnonzero(self.active_dofs)
        self._cons = np.flatnonzero(self.active_constraints)
        self._own_dynamics = type(model).contact_dynamics is not LagrangianModel.contact_dynamics
        if self._own_dynamics and not self.active_dofs.all():
            raise ValueError("frozen coordinates (active_dofs) need the default dynamics: "
                             "the model's contact_dynamics would have to honour them")
        self.modes = np.full(n_c, int(FREE), dtype=int)
        self.m_eff = np.zeros(n_c)
        self.impact_speed = np.zeros(n_c)
        self._cache_key: Optional[tuple] = None
        self._cache: Optional[_Evaluation] = None

    # --- sizes --------------------------------------------------------------------------
    @property
    def n_states(self) -> int:
        """Number of continuous states, ``2 n_q``."""
        return 2 * self.model.n_q

    @property
    def n_indicators(self) -> int:
        """Number of event indicators, ``2 n_c`` (fixed, whatever the modes)."""
        return 2 * self.model.n_c

    def split(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(q, v)`` views of a state vector."""
        n = self.model.n_q
        return x[:n], x[n:]

    # --- dynamics -----------------------------------------------------------------------
    def _evaluate(self, t: float, x: np.ndarray) -> _Evaluation:
        # derivatives and indicators are asked at the same point; the applied forces are part of
        # the key because inputs (an FMU's) may change at the same (t, x)
        x = np.asarray(x, float)
        q, v = self.split(x)
        key = (t, x.tobytes(), self.modes.tobytes(), self.model.inputs_key(t, q, v))
        if key == self._cache_key:
            return self._cache
        ev = self._solve(t, x, self.modes)
        self._cache_key, self._cache = key, ev
        return ev

    def _solve(self, t: float, x: np.ndarray, modes: np.ndarray,
               rigid: Optional[int] = None) -> _Evaluation:
        """Contact forces and accelerations for the given modes. With ``rigid = i``, contact i (in
        CONTACT) carries the stabilised constraint's multiplier even if it is compliant: the load
        the rest of the system puts on it, which is what a capture decision asks about."""
        # a solver's trial stage may penetrate absurdly deep: let it overflow, the step is rejected
        with np.errstate(over="ignore", invalid="ignore"):
            return self._solve_unguarded(t, x, modes, rigid)

    def _solve_unguarded(self, t: float, x: np.ndarray, modes: np.ndarray,
                         rigid: Optional[int]) -> _Evaluation:
        model = self.model
        q, v = self.split(np.asarray(x, float))
        h = model.gaps(q)
        H = model.gap_jacobian(q)
        hdot = H @ v
        lam = np.zeros(model.n_c)
        K = []
        for i in self._cons:
            if modes[i] == COLLISION:
                lam[i] = self.m_eff[i] * self.laws[i].acceleration(-h[i], -hdot[i])
            elif modes[i] == CONTACT:
                material = self.materials[i]
                if material is None or i == rigid:
                    K.append(i)
                else:
                    lam[i] = material.force(-h[i], -hdot[i])
        vdot = self._accelerations(t, q, v, H, lam)
        if K:
            Y = self._mobility(t, q, v, H, K)
            A = H[K] @ Y
            b = (-(H[K] @ vdot) - model.gap_jacobian_dot_v(q, v)[K]
                 - self.alpha1 * hdot[K] - self.alpha0 * h[K])
            try:
                lam_K = np.linalg.solve(A, b)
            except np.linalg.LinAlgError:
                lam_K = np.linalg.lstsq(A, b, rcond=None)[0]
            lam[K] = lam_K
            vdot = vdot + Y @ lam_K
        return _Evaluation(h, hdot, H, lam, vdot)

    def _accelerations(self, t: float, q: np.ndarray, v: np.ndarray, H: np.ndarray,
                       lam: np.ndarray) -> np.ndarray:
        """``v'`` under the multipliers ``lam`` (zero for frozen coordinates)."""
        if self._own_dynamics:
            return np.asarray(self.model.contact_dynamics(t, q, v, H, lam), float)
        dofs = self._dofs
        M = self.model.mass_matrix(q)[np.ix_(dofs, dofs)]
        Q = self.model.applied_forces(t, q, v)[dofs] + H[:, dofs].T @ lam
        vdot = np.zeros(self.model.n_q)
        vdot[dofs] = np.linalg.solve(M, Q)
        return vdot

    def _mobility(self, t: float, q: np.ndarray, v: np.ndarray, H: np.ndarray,
                  rows: Sequence[int]) -> np.ndarray:
        """``d v' / d lam`` for the constraints ``rows``, shape (n_q, len(rows))."""
        if self._own_dynamics:
            return np.asarray(self.model.contact_mobility(t, q, v, H, rows), float).reshape(self.model.n_q, len(rows))
        dofs = self._dofs
        M = self.model.mass_matrix(q)[np.ix_(dofs, dofs)]
        Y = np.zeros((self.model.n_q, len(rows)))
        Y[dofs] = np.linalg.solve(M, H[np.ix_(rows, dofs)].T)
        return Y

    def derivatives(self, t: float, x: np.ndarray) -> np.ndarray:
        """``x' = [v, v']`` (zero for frozen degrees of freedom)."""
        ev = self._evaluate(t, x)
        _, v = self.split(x)
        qdot = np.where(self.active_dofs, v, 0.0)
        return np.concatenate([qdot, ev.vdot])

    def contact_forces(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """Multipliers ``lambda_i`` (N for distance gaps), zero in FREE and for unused constraints."""
        return self._evaluate(t, x).lam.copy()

    # --- events -------------------------------------------------------------------------
    def event_indicators(self, t: float, x: np.ndarray) -> np.ndarray:
        """``[z1_1..z1_nc, z2_1..z2_nc]``; an event where one changes domain (z > 0 / z <= 0).

        FREE: z1 <= 0 once penetrating and closing. COLLISION: z1 <= 0 when the force has stopped
        while separating (end of the fast transient), z2 <= 0 past maximal compression (capture
        check). CONTACT: z1 = lambda (<= 0: release). Unused indicators are +1.
        """
        ev = self._evaluate(t, x)
        n_c = self.model.n_c
        z = np.ones(2 * n_c)
        for i in self._cons:
            z[i], z[n_c + i] = self._indicator_pair(i, ev)
        return z

    def _indicator_pair(self, i: int, ev: _Evaluation) -> tuple[float, float]:
        """Dimensionless indicators of constraint i. The offset ``EPS`` puts exact rest (touching
        bodies, h = h' = 0) strictly inside the positive domain: no indicator sits at 0, and the
        round-off motion of touching bodies (~1e-30 m/s) cannot fire events."""
        law, mode = self.laws[i], self.modes[i]
        if mode == FREE:
            return max(ev.h[i] / law.length, ev.hdot[i] / law.reference_speed + EPS), 1.0
        if mode == COLLISION:
            return (law.end_indicator(-ev.h[i], -ev.hdot[i]) + EPS,
                    -ev.hdot[i] / law.reference_speed + EPS)
        material = self.materials[i]
        if material is not None:
            return material.indicator(-ev.h[i], -ev.hdot[i]), 1.0
        return float(ev.lam[i]), 1.0

    def initialize(self, t: float, x: np.ndarray) -> None:
        """Consistent modes at the start: touching or penetrating contacts enter COLLISION (a
        compliant contact carrying no force yet), then the event iteration settles the rest."""
        self.modes[:] = FREE
        ev = self._solve(t, x, self.modes)
        for i in self._cons:
            if ev.h[i] <= EPS * self.laws[i].length:   # touching, up to round-off
                self._enter_collision(i, ev, t, x)
        self._cache_key = None
        self.update(t, x)

    def _enter_collision(self, i: int, ev: _Evaluation, t: float, x: np.ndarray) -> None:
        q, v = self.split(np.asarray(x, float))
        self.m_eff[i] = 1.0 / float(ev.H[i] @ self._mobility(t, q, v, ev.H, [i])[:, 0])
        self.impact_speed[i] = max(-ev.hdot[i], 0.0)
        self.modes[i] = COLLISION
        material = self.materials[i]
        if material is not None:
            self.laws[i] = material.collision_law(self.m_eff[i])

    def _load_if_contact(self, t: float, x: np.ndarray, i: int) -> float:
        """Multiplier contact i would carry in (rigid) CONTACT, the other modes unchanged: the
        load pressing it, whatever its own law."""
        trial = self.modes.copy()
        trial[i] = CONTACT
        return float(self._solve(t, x, trial, rigid=i).lam[i])

    def _rebound_estimate(self, i: int, ev: _Evaluation, load: float) -> float:
        """Relative speed the contact would leave with: e * sqrt(kinetic + elastic - preload work)
        per unit effective mass, all from the current compression state (a decision, not a law)."""
        law = self.laws[i]
        delta, ddot = -ev.h[i], -ev.hdot[i]
        energy2 = ddot * ddot + 2.0 * law.potential(delta) - 2.0 * load / self.m_eff[i] * max(delta, 0.0)
        return law.restitution * float(np.sqrt(max(energy2, 0.0)))

    def update(self, t: float, x: np.ndarray) -> tuple[None, bool]:
        """Discrete update at an event: mode transitions until nothing changes (event iteration).

        Returns ``(None, changed)``: the continuous state never jumps. Transitions:
        FREE -> COLLISION when penetrating and closing (freezes m_eff); COLLISION -> FREE when the
        force has stopped while separating, or -> CONTACT if that rebound is slower than
        ``capture_speed`` and the contact is loaded; COLLISION -> CONTACT when the estimated
        rebound of a loaded, compressed contact is below ``capture_speed``; CONTACT -> FREE when
        ``lambda <= 0``. Collision transitions are applied together, CONTACT ones one at a time.
        """
        x = np.asarray(x, float)
        changed_any = False
        for _ in range(4 * self.model.n_c + 4):
            ev = self._solve(t, x, self.modes)
            changed = self._collision_transitions(t, x, ev)
            if not changed:
                changed = self._contact_transition(t, x, ev)
            if not changed:
                break
            changed_any = True
        self._cache_key = None
        return None, changed_any

    def _collision_transitions(self, t: float, x: np.ndarray, ev: _Evaluation) -> bool:
        """FREE -> COLLISION and COLLISION -> FREE: force-form laws do not couple, so all at once."""
        changed = False
        for i in self._cons:
            if self.modes[i] == FREE and self._indicator_pair(i, ev)[0] <= 0.0:
                self._enter_collision(i, ev, t, x)
                changed = True
            elif self.modes[i] == COLLISION and self._collision_ended(i, ev):
                if ev.hdot[i] >= self.capture_speed or self._load_if_contact(t, x, i) <= 0.0:
                    self.modes[i] = FREE
                    changed = True
        return changed

    def _collision_ended(self, i: int, ev: _Evaluation) -> bool:
        return self._indicator_pair(i, ev)[0] <= 0.0 and ev.hdot[i] > 0.0

    def _contact_transition(self, t: float, x: np.ndarray, ev: _Evaluation) -> bool:
        """One CONTACT change (they couple through the joint solve): release the most negative
        multiplier first, else capture the first loaded collision that cannot leave."""
        pull = {i: self._indicator_pair(i, ev)[0] for i in self._cons if self.modes[i] == CONTACT}
        released = [i for i, z in pull.items() if z <= 0.0]
        if released:
            self.modes[min(released, key=lambda i: pull[i])] = FREE
            return True
        if self.capture_speed <= 0.0:
            return False
        for i in self._cons:
            if self.modes[i] != COLLISION or (ev.h[i] >= 0.0 and not self._collision_ended(i, ev)):
                continue
            load = self._load_if_contact(t, x, i)
            if load > 0.0 and (self._collision_ended(i, ev)
                               or self._rebound_estimate(i, ev, load) < self.capture_speed):
                self.modes[i] = CONTACT
                return True
        return False

    # --- energy -------------------------------------------------------------------------
    def energy(self, x: np.ndarray) -> float:
        """Kinetic + potential + elastic energy stored in the colliding and compliant contacts."""
        q, v = self.split(np.asarray(x, float))
        e = self.model.kinetic_energy(q, v) + self.model.potential_energy(q)
        h = self.model.gaps(q)
        for i in self._cons:
            material = self.materials[i]
            if self.modes[i] == COLLISION:
                e += self.m_eff[i] * self.laws[i].potential(-h[i])
            elif self.modes[i] == CONTACT and material is not None:
                e += material.potential(-h[i])
        return float(e)
