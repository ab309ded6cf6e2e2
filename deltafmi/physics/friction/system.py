"""Contacts with Coulomb friction as a mode machine (SEPARATED / STICK / SLIP+ / SLIP-), FMU-shaped.

The system ``q' = v``, ``M(q) v' = Q(t, q, v) + sum_i (H_i^T lambda_n_i + W_i^T lambda_t_i)``
has per contact ``i`` a normal gap ``h_i(q)`` (``H_i = dh_i/dq``) and a tangential relative
velocity ``v_t_i = W_i(q) v - u_i`` (``u_i``: the other surface's speed, a belt's, constant between
events). While the contact is closed its normal multiplier enforces the talk's stabilised
constraint ``h'' + alpha1 h' + alpha0 h = 0`` (docs/contact.md, section 5); the tangential force
depends on the mode (:mod:`.law`):

* STICK: ``v_t' + beta v_t = 0`` with multiplier ``lambda_t`` (``v_t = 0`` is exact: the velocity
  is projected onto it when the mode is entered, ``beta`` only guards against drift);
* SLIP: ``lambda_t = -mu_k lambda_n e - c_v v_t``, affine in the unknown ``lambda_n``, with ``e``
  the unit slip direction of :func:`.law.slip_force_direction` (``s`` on a tangent line,
  ``v_t / |v_t|`` in a tangential plane while ``v_t`` is on the side of the contact's ``axis``).

``v_t`` has ``n_t`` components per contact (1: a line, 2: a plane; ``W_i`` its ``n_t`` rows).
All multipliers of closed contacts come from one linear solve: with ``E_i = H_i - mu_k e_i^T W_i``
(``E_i = H_i`` in STICK) and ``C = [H_closed; W_stick]``, ``G = [E_closed; W_stick]``,

    C M^-1 G^T lambda = rhs - C M^-1 Q',    v' = M^-1 (Q' + G^T lambda)

(``Q'`` includes the viscous forces), solved by least squares: ``C M^-1 G^T`` is singular when
sticking contacts are redundant (statically indeterminate: the minimum-norm multipliers share the
load), and it is not symmetric when a contact slips, and may then become singular (Painleve's
paradox: no or many solutions; least squares picks one, a limit of this rigid model).

Two event indicators per contact (fixed count), FMI domains ``z > 0`` / ``z <= 0``:
``z1`` = STICK: ``(mu_s lambda_n - |lambda_t|) / f_ref + EPS``; SLIP: ``v_t . axis / v_ref + EPS``
(``axis = [s]`` on a line: the stop; in a plane the crossing is a stop if ``|v_t|`` is ~0, else
the velocity has turned by 90 deg and the axis is re-anchored to ``v_t / |v_t|``);
``z2`` = ``lambda_n / f_ref`` while closed (release). SEPARATED contacts stay separated (this layer
models sliding contacts; impacts belong to :mod:`deltafmi.physics.contact`). Every transition is
appended to :attr:`FrictionSystem.log`.
"""
from __future__ import annotations

from typing import NamedTuple, Sequence, Union

import numpy as np

from ..contact.system import LagrangianModel
from .law import (SEPARATED, STICK, FrictionParams, after_stop, slip_force, slip_force_direction,
                  slip_mode, stick_margin)

__all__ = ["EPS", "FrictionModel", "FrictionSystem", "STOP", "Transition"]

#: offset of the indicators: a contact that sits exactly on the static cone, or has just started
#: slipping (v_t = 0 to round-off, ~1e-16 v_ref), is strictly inside its mode's domain. A located
#: stop is late by EPS v_ref / |v_t'|, a release by EPS f_ref / |lambda_t'|: as small as round-off allows.
EPS = 1e-12
#: a slipping contact whose ``v_t . axis`` crosses zero has stopped if ``|v_t| <= STOP v_ref``
#: (always on a line, where ``|v_t| = EPS v_ref`` there); faster, its velocity turned in the plane
STOP = 1e-8
#: singular values below RCOND times the largest count as zero in the multipliers' solve
RCOND = 1e-10


class FrictionModel(LagrangianModel):
    """A :class:`~deltafmi.physics.contact.system.LagrangianModel` whose gaps are sliding
    contacts: add ``tangent_jacobian`` and ``friction`` (one :class:`FrictionParams` or one per
    contact); the normal gaps, their Jacobian and ``(d/dt H) v`` are the Lagrangian model's."""

    friction: Union[FrictionParams, Sequence[FrictionParams]] = FrictionParams()
    #: tangent directions per contact: 1 (a tangent line) or 2 (a tangential plane)
    n_t: int = 1

    def tangent_jacobian(self, q: np.ndarray) -> np.ndarray:
        """``W``: ``W v`` is the body's tangential velocity at each contact, shape (n_c n_t, n_q),
        the ``n_t`` orthonormal tangent rows of contact ``i`` at rows ``i n_t ...``."""
        raise NotImplementedError

    def tangent_jacobian_dot_v(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``(d/dt W) v``. Default: the Lagrangian model's central difference, applied to ``W``."""
        return _TangentRows(self).gap_jacobian_dot_v(q, v)

    def surface_velocity(self, t: float) -> np.ndarray:
        """Tangential velocity of the other surface (a belt), shape (n_c n_t,), constant between events."""
        return np.zeros(self.n_c)


class _TangentRows(LagrangianModel):
    """The tangent rows ``W`` of a model posing as gap Jacobian (to reuse its central difference)."""

    def __init__(self, model: FrictionModel) -> None:
        self.n_q, self.n_c = model.n_q, model.n_c * model.n_t
        self.gap_jacobian = model.tangent_jacobian  # type: ignore[method-assign]


class Transition(NamedTuple):
    """One logged mode change of one contact."""

    t: float
    contact: int
    before: int
    after: int


class Evaluation(NamedTuple):
    """Gaps, velocities, multipliers and accelerations at one (t, x) for given modes
    (``v_t`` and ``lam_t`` have shape (n_c, n_t))."""

    h: np.ndarray
    hdot: np.ndarray
    v_t: np.ndarray
    lam_n: np.ndarray
    lam_t: np.ndarray
    vdot: np.ndarray


class FrictionSystem:
    """The mode machine over a :class:`FrictionModel`; state ``x = [q, v]``; FMU hooks
    ``derivatives``, ``event_indicators``, ``update``, ``initialize``, ``energy``,
    ``contact_forces`` (``[lambda_n, lambda_t]``); discrete state ``modes`` and ``axes`` (per
    contact, the unit slip axis: ``[s]`` on a line, the anchored direction in a plane).

    ``alpha0``, ``alpha1``: the normal constraint's stabilisation (1/s^2, 1/s); ``beta`` (1/s): the
    stick constraint's; ``v_ref`` (m/s), ``f_ref`` (N): scales of the dimensionless indicators.
    """

    def __init__(self, model: FrictionModel, *, alpha0: float = 100.0, alpha1: float = 20.0,
                 beta: float = 20.0, v_ref: float = 1.0, f_ref: float = 1.0) -> None:
        self.model = model
        n_c, self.n_t = model.n_c, int(model.n_t)
        fr = model.friction
        self.friction = [fr] * n_c if isinstance(fr, FrictionParams) else list(fr)
        if len(self.friction) != n_c:
            raise ValueError(f"need {n_c} friction parameter sets, got {len(self.friction)}")
        self.alpha0, self.alpha1, self.beta = float(alpha0), float(alpha1), float(beta)
        self.v_ref, self.f_ref = float(v_ref), float(f_ref)
        self.modes = np.full(n_c, STICK, dtype=int)
        self.axes = np.zeros((n_c, self.n_t))
        self.axes[:, 0] = 1.0
        #: every mode change, in order
        self.log: list[Transition] = []
        #: FMU sizes: states ``[q, v]``, two indicators per contact whatever the modes
        self.n_states, self.n_indicators = 2 * model.n_q, 2 * n_c

    def split(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(q, v)`` views of a state."""
        return x[:self.model.n_q], x[self.model.n_q:]

    def _rows(self, contacts: Sequence[int]) -> list[int]:
        """Rows of ``W`` (tangent directions) of the given contacts."""
        return [i * self.n_t + j for i in contacts for j in range(self.n_t)]

    # --- dynamics -----------------------------------------------------------------------
    def evaluate(self, t: float, x: np.ndarray, modes: np.ndarray | None = None) -> Evaluation:
        """Multipliers and accelerations for ``modes`` (default: the current ones)."""
        modes = self.modes if modes is None else modes
        model, k = self.model, self.n_t
        q, v = self.split(np.asarray(x, float))
        h, H, W = model.gaps(q), model.gap_jacobian(q), model.tangent_jacobian(q)
        hdot, v_t = H @ v, (W @ v - model.surface_velocity(t)).reshape(-1, k)
        Hd, Wd = model.gap_jacobian_dot_v(q, v), model.tangent_jacobian_dot_v(q, v)
        M, Q = model.mass_matrix(q), np.array(model.applied_forces(t, q, v), float)
        closed = [i for i in range(model.n_c) if modes[i] != SEPARATED]
        stick = [i for i in closed if modes[i] == STICK]
        rows_E, directions = [], {}
        for i in closed:
            p, W_i = self.friction[i], W[i * k:(i + 1) * k]
            if modes[i] == STICK:
                rows_E.append(H[i])
                continue
            e = directions[i] = slip_force_direction(v_t[i], self.axes[i])
            rows_E.append(H[i] - p.mu_k * e @ W_i)
            Q -= p.c_v * W_i.T @ v_t[i]
        ws = self._rows(stick)
        G = np.vstack(rows_E + [W[ws]]) if closed else np.zeros((0, model.n_q))
        C = np.vstack([H[closed], W[ws]])
        rhs = np.concatenate([-Hd[closed] - self.alpha1 * hdot[closed] - self.alpha0 * h[closed],
                              -Wd[ws] - self.beta * v_t[stick].ravel()])
        MiQ = np.linalg.solve(M, Q)
        MiG = np.linalg.solve(M, G.T) if closed else np.zeros((model.n_q, 0))
        lam = np.zeros(0)
        if closed:
            # SVD, not LU: redundant sticking contacts (a box's two corners on one line) make A
            # singular up to round-off; the minimum-norm multipliers then share the load equally
            # instead of splitting it at random (which would fire spurious slip events)
            lam = np.linalg.lstsq(C @ MiG, rhs - C @ MiQ, rcond=RCOND)[0]
        lam_n, lam_t = np.zeros(model.n_c), np.zeros((model.n_c, k))
        lam_n[closed] = lam[:len(closed)]
        lam_t[stick] = lam[len(closed):].reshape(-1, k)
        for i, e in directions.items():
            lam_t[i] = slip_force(lam_n[i], v_t[i], e, self.friction[i])
        return Evaluation(h, hdot, v_t, lam_n, lam_t, MiQ + MiG @ lam)

    def derivatives(self, t: float, x: np.ndarray) -> np.ndarray:
        """``[v, v']``."""
        return np.concatenate([self.split(x)[1], self.evaluate(t, x).vdot])

    def contact_forces(self, x: np.ndarray, t: float = 0.0) -> np.ndarray:
        """``[lambda_n_1..n, lambda_t_1..n]`` (N; ``n_t`` tangential components per contact)."""
        ev = self.evaluate(t, x)
        return np.concatenate([ev.lam_n, ev.lam_t.ravel()])

    def energy(self, x: np.ndarray) -> float:
        """Kinetic plus potential energy (friction dissipates it, a belt feeds it)."""
        q, v = self.split(np.asarray(x, float))
        return 0.5 * float(v @ self.model.mass_matrix(q) @ v) + self.model.potential_energy(q)

    # --- events -------------------------------------------------------------------------
    def _indicators(self, ev: Evaluation, i: int) -> tuple[float, float]:
        mode = self.modes[i]
        if mode == SEPARATED:
            return 1.0, 1.0
        if mode == STICK:
            z1 = stick_margin(ev.lam_t[i], ev.lam_n[i], self.friction[i]) / self.f_ref + EPS
        else:
            z1 = float(ev.v_t[i] @ self.axes[i]) / self.v_ref + EPS
        return z1, ev.lam_n[i] / self.f_ref

    def event_indicators(self, t: float, x: np.ndarray) -> np.ndarray:
        """``[z1_1..n, z2_1..n]`` (see the module docstring)."""
        ev = self.evaluate(t, x)
        pairs = [self._indicators(ev, i) for i in range(self.model.n_c)]
        return np.array([z1 for z1, _ in pairs] + [z2 for _, z2 in pairs])

    def initialize(self, t: float, x: np.ndarray) -> np.ndarray:
        """Start closed: STICK where ``v_t`` is zero (to ``EPS v_ref``), else SLIP along it; then
        settle by :meth:`update`. Returns the (projected) consistent state."""
        q, v = self.split(np.asarray(x, float))
        v_t = (self.model.tangent_jacobian(q) @ v - self.model.surface_velocity(t)).reshape(-1, self.n_t)
        for i, vt in enumerate(v_t):
            speed = float(np.linalg.norm(vt))
            if speed <= EPS * self.v_ref:
                self.modes[i] = STICK
            else:
                self.axes[i] = vt / speed
                self.modes[i] = slip_mode(self.axes[i])
        x = self._project(t, np.asarray(x, float))
        new_x, _ = self.update(t, x)
        return x if new_x is None else new_x

    def _project(self, t: float, x: np.ndarray, stopped: Sequence[int] = ()) -> np.ndarray:
        """Mass-weighted projection of ``v`` onto ``v_t = 0`` at the sticking contacts and those
        just ``stopped``, keeping the closed contacts' normal velocities: it removes the tiny
        velocity (``~EPS v_ref``) that the located stop leaves over."""
        model = self.model
        q, v = self.split(x)
        closed = [i for i in range(model.n_c) if self.modes[i] != SEPARATED]
        stick = [i for i in closed if self.modes[i] == STICK or i in stopped]
        if not stick:
            return x
        H, W = model.gap_jacobian(q), model.tangent_jacobian(q)
        ws = self._rows(stick)
        C = np.vstack([H[closed], W[ws]])
        target = np.concatenate([H[closed] @ v, model.surface_velocity(t)[ws]])
        MiC = np.linalg.solve(model.mass_matrix(q), C.T)
        dv = MiC @ np.linalg.lstsq(C @ MiC, target - C @ v, rcond=None)[0]
        return np.concatenate([q, v + dv])

    def _transition(self, t: float, x: np.ndarray, ev: Evaluation) -> tuple[int, int, np.ndarray] | None:
        """The first due change ``(contact, new mode, new axis)``, or None."""
        for i in range(self.model.n_c):
            mode = self.modes[i]
            if mode == SEPARATED:
                continue
            z1, z2 = self._indicators(ev, i)
            if z2 <= 0.0:
                return i, SEPARATED, self.axes[i]
            if z1 > 0.0:
                continue
            if mode == STICK:
                axis = -ev.lam_t[i] / float(np.linalg.norm(ev.lam_t[i]))
                return i, slip_mode(axis), axis
            speed = float(np.linalg.norm(ev.v_t[i]))
            if speed > STOP * self.v_ref:
                # in a plane: the velocity turned past 90 deg from the axis without stopping
                return i, mode, ev.v_t[i] / speed
            # stopped while slipping: the multiplier STICK would need decides (at v_t = 0)
            trial = self.modes.copy()
            trial[i] = STICK
            stop = self.evaluate(t, self._project_with(t, x, trial), trial)
            axis = after_stop(stop.lam_t[i], stop.lam_n[i], self.friction[i])
            return (i, STICK, self.axes[i]) if axis is None else (i, slip_mode(axis), axis)
        return None

    def _project_with(self, t: float, x: np.ndarray, modes: np.ndarray) -> np.ndarray:
        saved = self.modes
        self.modes = modes
        try:
            return self._project(t, x)
        finally:
            self.modes = saved

    def update(self, t: float, x: np.ndarray) -> tuple[np.ndarray | None, bool]:
        """Event iteration: apply due changes one at a time (they couple through the joint solve)
        until none is due; returns ``(x_new, changed)``, ``x_new`` the state with ``v`` projected
        onto the sticking and stopped contacts' ``v_t = 0`` (None if nothing changed). Mode
        changes are logged; re-anchoring a plane contact's axis changes only ``axes``."""
        x = np.array(x, float)
        changed = False
        for _ in range(4 * self.model.n_c + 4):
            move = self._transition(t, x, self.evaluate(t, x))
            if move is None:
                break
            i, new, axis = move
            # a slipping contact that stops (to STICK or to slip the other way) loses its last EPS v_ref
            slipping = self.modes[i] not in (STICK, SEPARATED)
            stopped = [i] if slipping and new not in (SEPARATED, self.modes[i]) else []
            if new != self.modes[i]:
                self.log.append(Transition(t, i, int(self.modes[i]), int(new)))
            self.modes[i], self.axes[i] = new, axis
            x = self._project(t, x, stopped)
            changed = True
        return (x if changed else None), changed
