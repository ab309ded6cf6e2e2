"""Newton's cradle's kernels: its ``ContactSystem`` evaluation in plain floats (see
:mod:`.contact_kernels`), for pendulums or a free chain of ``n`` of its allocated balls (the rest
frozen), compiled into its FMU and called by its Python methods alike."""
from __future__ import annotations

import math
from typing import NamedTuple, Sequence

from ..contact.law_kernels import LawConstants
from .contact_kernels import (contact_response, elastic_energy, free_rates, indicator_pairs,
                              kinetic_energy)

__all__ = ["CradleModes", "CradleParams", "N_BALLS", "cradle_derivatives", "cradle_evaluate", "cradle_indicators",
           "cradle_outputs"]

N_BALLS = 7  #: balls the kernels are generated for (the FMU's allocation)
F7 = tuple[float, float, float, float, float, float, float]
F6 = tuple[float, float, float, float, float, float]
I6 = tuple[int, int, int, int, int, int]


class CradleParams(NamedTuple):
    """``n`` balls in use of the 7 allocated, pendulums (else a free chain), equal balls, pendulum
    length, gravity, pivot positions, the contacts' collision law and the CONTACT law."""

    n: int
    pendulum: bool
    mass: float
    radius: float
    length: float
    g: float
    pivots: F7
    law: LawConstants
    alpha0: float
    alpha1: float


class CradleModes(NamedTuple):
    """Mode and effective mass (frozen at the impact) of each contact (balls i, i+1)."""

    modes: I6
    m_eff: F6


def cradle_evaluate(p: CradleParams, modes: Sequence[int], m_eff: Sequence[float],
                    x: Sequence[float]) -> tuple:
    """``(h, hdot, H, lambda, v')`` of the cradle (state ``[q, v]``) for ``modes``
    (PendulumModel's or ChainModel's gaps, Jacobian and forces)."""
    L = p.length
    r = p.radius
    q = x[:N_BALLS]
    v = x[N_BALLS:]
    dofs = [j < p.n for j in range(N_BALLS)]
    cons = [i + 1 < p.n for i in range(N_BALLS - 1)]
    h = []
    H = []
    dHv = []
    if p.pendulum:
        cx = [p.pivots[j] + L * math.sin(q[j]) for j in range(N_BALLS)]
        cz = [-L * math.cos(q[j]) for j in range(N_BALLS)]
        jx = [L * math.cos(q[j]) for j in range(N_BALLS)]            # d centre / d theta
        jz = [L * math.sin(q[j]) for j in range(N_BALLS)]
        px = [L * -math.sin(q[j]) * v[j] ** 2 for j in range(N_BALLS)]  # centripetal acceleration
        pz = [L * math.cos(q[j]) * v[j] ** 2 for j in range(N_BALLS)]
        for i in range(N_BALLS - 1):
            dx = cx[i + 1] - cx[i]
            dz = cz[i + 1] - cz[i]
            dist = math.sqrt(dx * dx + dz * dz)
            nx = dx / dist
            nz = dz / dist
            h.append(dist - r - r)
            H.append([-(nx * jx[j] + nz * jz[j]) if j == i else (nx * jx[j] + nz * jz[j] if j == i + 1 else 0.0)
                      for j in range(N_BALLS)])
            wx = jx[i + 1] * v[i + 1] - jx[i] * v[i]
            wz = jz[i + 1] * v[i + 1] - jz[i] * v[i]
            nw = nx * wx + nz * wz
            dHv.append((wx * wx + wz * wz - nw ** 2) / dist + (nx * (px[i + 1] - px[i]) + nz * (pz[i + 1] - pz[i])))
        Q = [-p.mass * p.g * L * math.sin(q[j]) for j in range(N_BALLS)]
        mass = [p.mass * L ** 2 for j in range(N_BALLS)]
    else:
        for i in range(N_BALLS - 1):
            h.append(q[i + 1] - q[i] - r - r)
            H.append([-1.0 if j == i else (1.0 if j == i + 1 else 0.0) for j in range(N_BALLS)])
            dHv.append(0.0)
        Q = [0.0 for j in range(N_BALLS)]
        mass = [p.mass for j in range(N_BALLS)]
    hdot = []
    for i in range(N_BALLS - 1):
        s = 0.0
        for j in range(N_BALLS):
            s = s + H[i][j] * v[j]
        hdot.append(s)
    lam, vdot = contact_response(h, hdot, H, dHv, mass, Q, dofs, cons, modes, m_eff, p.law, p.alpha0, p.alpha1)
    return h, hdot, H, lam, vdot


def cradle_derivatives(p: CradleParams, d: CradleModes, x: Sequence[float]) -> list[float]:
    """``[q', v']``, zero for the frozen balls."""
    h, hdot, H, lam, vdot = cradle_evaluate(p, d.modes, d.m_eff, x)
    return free_rates(x[N_BALLS:], [j < p.n for j in range(N_BALLS)]) + vdot


def cradle_indicators(p: CradleParams, d: CradleModes, x: Sequence[float]) -> list[float]:
    """Two event indicators per contact, +1 for the unused ones."""
    h, hdot, H, lam, vdot = cradle_evaluate(p, d.modes, d.m_eff, x)
    return indicator_pairs(h, hdot, lam, [i + 1 < p.n for i in range(N_BALLS - 1)], d.modes, p.law)


def cradle_outputs(p: CradleParams, d: CradleModes, x: Sequence[float]) -> list[float]:
    """``x[7], vx[7], lambda[6], energy, momentum``: horizontal ball positions and velocities,
    contact forces, kinetic + potential + elastic energy, momentum of the balls in use."""
    L = p.length
    q = x[:N_BALLS]
    v = x[N_BALLS:]
    h, hdot, H, lam, vdot = cradle_evaluate(p, d.modes, d.m_eff, x)
    potential = 0.0
    if p.pendulum:
        pos = [p.pivots[j] + L * math.sin(q[j]) for j in range(N_BALLS)]
        vel = [L * math.cos(q[j]) * v[j] for j in range(N_BALLS)]
        mass = [p.mass * L ** 2 for j in range(N_BALLS)]
        for j in range(N_BALLS):
            potential = potential + p.mass * p.g * L * (1.0 - math.cos(q[j]))
    else:
        pos = [q[j] for j in range(N_BALLS)]
        vel = [v[j] for j in range(N_BALLS)]
        mass = [p.mass for j in range(N_BALLS)]
    energy = (kinetic_energy(mass, v) + potential
              + elastic_energy(h, [i + 1 < p.n for i in range(N_BALLS - 1)], d.modes, d.m_eff, p.law))
    momentum = 0.0
    for j in range(N_BALLS):
        if j < p.n:
            momentum = momentum + p.mass * vel[j]
    return pos + vel + lam + [energy, momentum]
