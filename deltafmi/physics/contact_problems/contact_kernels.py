"""The contact framework's continuous part as plain-float kernels, for models with a diagonal mass
matrix and one collision law for all their contacts (the ball, the box, Newton's cradle).

:class:`~deltafmi.physics.contact.system.ContactSystem` evaluates with numpy; these functions
compute the same quantities (same formulas, same modes, frozen coordinates and unused contacts)
in the Python subset ``deltafmi build`` translates to C (deltafmi/builder/codegen/translate.py):
fixed-length tuples, loops over constant ranges, ``math``. A model supplies its gaps ``h``, gap
Jacobian ``H`` (rows per contact), ``(d/dt H) v``, diagonal masses and applied forces;
:func:`contact_response` returns the multipliers and accelerations of the current modes,
:func:`indicator_pairs` the event indicators, :func:`elastic_energy` the energy stored in
collisions. :class:`KernelContactSystem` runs the mode machine (events, Python) on the same
evaluation, so its decisions see exactly the numbers the compiled kernels integrate.

Differences from the numpy evaluation, all round-off: ``M^-1`` of a diagonal matrix is a division,
and the joint CONTACT solve is Gaussian elimination without pivoting (its matrix
``H_K M^-1 H_K^T`` is symmetric positive definite); redundant contacts in CONTACT, where numpy falls
back to least squares, raise instead (none of the examples can reach it).
"""
from __future__ import annotations

from typing import Callable, Optional, Sequence

import numpy as np

from ..contact.collision_law import CollisionLaw
from ..contact.law_kernels import LawConstants, law_acceleration, law_end_indicator, law_potential
from ..contact.system import COLLISION, CONTACT, EPS, FREE, ContactSystem, LagrangianModel, _Evaluation

__all__ = ["KernelContactSystem", "contact_response", "elastic_energy", "free_rates", "indicator_pairs",
           "kinetic_energy"]


def _solve_masked(A: Sequence[Sequence[float]], b: Sequence[float], keep: Sequence[bool]) -> list[float]:
    """``x`` with ``A[K, K] x[K] = b[K]`` for ``K = {i: keep[i]}`` and ``x[i] = 0`` elsewhere; ``A[K, K]``
    symmetric positive definite (elimination without pivoting)."""
    n = len(b)  # range(n) of a variable is a C loop for the translator; range(len(b)) is unrolled
    rows = [[A[i][j] if keep[i] and keep[j] else (1.0 if i == j else 0.0) for j in range(len(b))]
            for i in range(len(b))]
    rhs = [b[i] if keep[i] else 0.0 for i in range(len(b))]
    for k in range(n):
        if not rows[k][k] > 0.0:
            raise ValueError("contacts in CONTACT are redundant: their joint solve is singular")
        rhs = [rhs[i] - rows[i][k] / rows[k][k] * rhs[k] if i > k else rhs[i] for i in range(len(b))]
        rows = [[rows[i][j] - rows[i][k] / rows[k][k] * rows[k][j] if i > k else rows[i][j] for j in range(len(b))]
                for i in range(len(b))]
    x = [0.0 for i in range(len(b))]
    for back in range(n):
        k = n - 1 - back
        s = rhs[k]
        for j in range(k + 1, n):
            s = s - rows[k][j] * x[j]
        x = [s / rows[k][k] if j == k else x[j] for j in range(len(b))]
    return x


def contact_response(h: Sequence[float], hdot: Sequence[float], H: Sequence[Sequence[float]],
                     dHv: Sequence[float], mass: Sequence[float], Q: Sequence[float],
                     dofs: Sequence[bool], cons: Sequence[bool], modes: Sequence[int],
                     m_eff: Sequence[float], law: LawConstants, alpha0: float,
                     alpha1: float) -> tuple[list[float], list[float]]:
    """``(lambda, v')`` for the modes (ContactSystem._solve with ``M = diag(mass)``): COLLISION
    forces from the law, CONTACT multipliers from ``h'' + alpha1 h' + alpha0 h = 0`` solved jointly;
    zero acceleration for frozen coordinates (``dofs`` false), zero force for unused contacts."""
    n_c = len(h)  # range() of these variables: C loops (smaller code); range(len(h)) is unrolled
    n_q = len(Q)
    lam = [m_eff[i] * law_acceleration(law, -h[i], -hdot[i]) if cons[i] and modes[i] == COLLISION else 0.0
           for i in range(len(h))]
    vdot = []
    for j in range(len(Q)):
        s = Q[j]
        for i in range(n_c):
            s = s + H[i][j] * lam[i]
        vdot.append(s / mass[j] if dofs[j] else 0.0)
    if not any(cons[i] and modes[i] == CONTACT for i in range(len(h))):
        return lam, vdot
    keep = [cons[i] and modes[i] == CONTACT for i in range(len(h))]
    Y = [[H[i][j] / mass[j] if dofs[j] else 0.0 for i in range(len(h))] for j in range(len(Q))]  # M^-1 H^T
    A = []
    b = []
    for i in range(len(h)):
        row = []
        for k in range(len(h)):
            s = 0.0
            for j in range(n_q):
                s = s + H[i][j] * Y[j][k]
            row.append(s)
        A.append(row)
        hv = 0.0
        for j in range(n_q):
            hv = hv + H[i][j] * vdot[j]
        b.append(-hv - dHv[i] - alpha1 * hdot[i] - alpha0 * h[i])
    lam_k = _solve_masked(A, b, keep)
    lam = [lam_k[i] if keep[i] else lam[i] for i in range(len(h))]
    out = []
    for j in range(len(Q)):
        s = vdot[j]
        for i in range(n_c):
            if keep[i]:
                s = s + Y[j][i] * lam_k[i]
        out.append(s)
    return lam, out


def indicator_pairs(h: Sequence[float], hdot: Sequence[float], lam: Sequence[float],
                    cons: Sequence[bool], modes: Sequence[int], law: LawConstants) -> list[float]:
    """``[z1_1..z1_nc, z2_1..z2_nc]`` as ContactSystem.event_indicators (rigid contacts); +1 for
    unused contacts."""
    z1 = []
    z2 = []
    for i in range(len(h)):
        a, b = 1.0, 1.0
        if cons[i]:
            if modes[i] == FREE:
                a = max(h[i] / law.length, hdot[i] / law.reference_speed + EPS)
            elif modes[i] == COLLISION:
                a = law_end_indicator(law, -h[i], -hdot[i]) + EPS
                b = -hdot[i] / law.reference_speed + EPS
            else:
                a = lam[i]
        z1.append(a)
        z2.append(b)
    return z1 + z2


def elastic_energy(h: Sequence[float], cons: Sequence[bool], modes: Sequence[int], m_eff: Sequence[float],
                   law: LawConstants) -> float:
    """Energy stored in the contacts in COLLISION, ``sum m_eff kappa delta**(p+1) / (p+1)``."""
    e = 0.0
    for i in range(len(h)):
        if cons[i] and modes[i] == COLLISION:
            e = e + m_eff[i] * law_potential(law, -h[i])
    return e


def kinetic_energy(mass: Sequence[float], v: Sequence[float]) -> float:
    """``v^T diag(mass) v / 2``."""
    e = 0.0
    for j in range(len(v)):
        e = e + v[j] * (mass[j] * v[j])
    return 0.5 * e


def free_rates(v: Sequence[float], dofs: Sequence[bool]) -> list[float]:
    """``q' = v``, zero for frozen coordinates."""
    return [v[j] if dofs[j] else 0.0 for j in range(len(v))]


#: a model's evaluation kernel: (params, modes, m_eff, state, *inputs) -> (h, hdot, H, lam, vdot)
Evaluate = Callable[..., tuple]


class KernelContactSystem(ContactSystem):
    """A :class:`ContactSystem` whose continuous evaluation is a model's plain-float kernel
    ``evaluate(params, modes, m_eff, x, *inputs) -> (h, hdot, H, lam, vdot)``: the mode machine
    (initialization, events, capture decisions) then sees the numbers the kernels integrate.
    Set ``inputs`` (a tuple of the kernel's input arguments) with the model's inputs; ``params``
    may be set after construction (from the system's own ``alpha0``, ``alpha1``)."""

    def __init__(self, model: LagrangianModel, law: CollisionLaw, evaluate: Evaluate, params: Optional[tuple],
                 **options) -> None:
        super().__init__(model, law, **options)
        self.evaluate, self.params = evaluate, params
        self.inputs: tuple = ()

    def discrete(self) -> tuple[tuple, tuple]:
        """``(modes, m_eff)`` as tuples of ints and floats (the kernels' discrete state)."""
        return tuple(int(m) for m in self.modes), tuple(float(m) for m in self.m_eff)

    def _solve(self, t: float, x: np.ndarray, modes: np.ndarray, rigid=None) -> _Evaluation:
        h, hdot, H, lam, vdot = self.evaluate(self.params, tuple(int(m) for m in modes),
                                              tuple(float(m) for m in self.m_eff),
                                              [float(v) for v in x], *self.inputs)
        return _Evaluation(np.array(h), np.array(hdot), np.array(H), np.array(lam), np.array(vdot))
