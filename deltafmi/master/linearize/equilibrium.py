"""Equilibria of a Model Exchange FMU ("trim"): inputs (and states) with every derivative zero.

Unknowns: the free inputs, and the continuous states too when some outputs are to take given
values (a robot held at rest at a given wrist position). Equations: der(x) = 0 and the output
targets. scipy's Levenberg-Marquardt solves them with the FMU's own Jacobian [A B; C D]
(directional derivatives, or central differences), so from a nearby start it converges
quadratically. For the delta robot at rest with free servo torques this is the holding torque:
gravity balanced through the closed loops.
"""
from __future__ import annotations

from typing import Mapping, NamedTuple, Sequence

import numpy as np
from scipy.optimize import least_squares

from ..stepping.jacobians import FmuJacobian, Key

__all__ = ["find_equilibrium"]


class Equilibrium(NamedTuple):
    """The states and free inputs found, and the largest |der(x)| left (its units, per state)."""

    states: np.ndarray
    inputs: np.ndarray
    residual: float


def find_equilibrium(jacobian: FmuJacobian, free_inputs: Sequence[Key], targets: Mapping[Key, float],
                     tolerance: float = 1e-10) -> Equilibrium:
    """Drive the FMU (in continuous-time mode) to der(x) = 0 with outputs ``targets`` (scalar key,
    see :mod:`.jacobians` -> value), solving for ``free_inputs`` (keys) and, when there are
    targets, the states. The FMU is left at the solution. Raises ValueError when none is found:
    largest |der(x)| or target miss above ``tolerance`` times its scale."""
    values, nx = jacobian.values, jacobian.nx
    free_inputs, outputs = list(free_inputs), list(targets)
    move_states = bool(outputs)
    goal = np.array([targets[key] for key in outputs], dtype=float)
    x0 = jacobian.get_states()
    u0 = values.get(free_inputs)
    n_states = nx if move_states else 0
    if n_states + len(free_inputs) == 0:
        raise ValueError("nothing to solve for: name inputs to free (or outputs to hold)")

    def apply(z: np.ndarray) -> None:
        if move_states:
            jacobian.set_states(z[:nx])
        if free_inputs:
            values.set(free_inputs, z[n_states:])

    def residual(z: np.ndarray) -> np.ndarray:
        apply(z)
        return np.concatenate([jacobian.state_derivatives(), values.get(outputs) - goal])

    def derivative(z: np.ndarray) -> np.ndarray:
        apply(z)
        knowns = (jacobian.states if move_states else []) + free_inputs
        return jacobian.block(jacobian.derivatives + outputs, knowns)

    if n_states + len(free_inputs) > nx + len(outputs):
        raise ValueError(f"{n_states + len(free_inputs)} unknowns ({n_states} states, {len(free_inputs)} free inputs) "
                         f"but {nx + len(outputs)} equations ({nx} derivatives, {len(outputs)} held outputs): "
                         "free fewer inputs (--free) or hold more outputs (--hold)")
    start = np.concatenate([x0 if move_states else np.zeros(0), u0])
    scale = max(1.0, float(np.max(np.abs(residual(start)))) if nx + len(outputs) else 1.0)
    solution = least_squares(residual, start, jac=derivative, method="lm", x_scale="jac",
                             ftol=1e-15, xtol=1e-15, gtol=1e-15, max_nfev=200)
    final = residual(solution.x)
    worst = float(np.max(np.abs(final))) if final.size else 0.0
    if not worst <= tolerance * scale:
        raise ValueError(f"no equilibrium found: the largest |der(x)| or output miss left is {worst:.3g} "
                         f"({solution.message.rstrip('.')})")
    apply(solution.x)
    return Equilibrium(solution.x[:nx] if move_states else x0, solution.x[n_states:], worst)
