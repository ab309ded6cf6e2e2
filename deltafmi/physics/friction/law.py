"""Coulomb friction with viscous terms, as the laws of the STICK and SLIP modes of one contact.

One contact has a normal multiplier ``lambda_n >= 0`` and a tangential relative velocity ``v_t``
(1 component on a tangent line, 2 in a tangential plane). Its tangential force ``lambda_t`` is

* STICK: a multiplier of the constraint ``v_t = 0``, admissible while
  ``|lambda_t| <= mu_s lambda_n`` (the static cone);
* SLIP: ``lambda_t = -mu_k lambda_n e - c_v v_t`` (kinetic Coulomb plus viscous), ``e`` the unit
  slip direction: ``s = +1 / -1`` on a line (modes SLIP+ / SLIP-), ``v_t / |v_t|`` in a plane.

Because the direction on a line (or the anchoring axis in a plane, see
:func:`slip_force_direction`) is a discrete state, not ``sign(v_t)`` evaluated inside the
right-hand side, the force is exact on both sides of ``v_t = 0`` and the transition between the
modes happens at a located event: there is no regularisation (``tanh(v_t / v_eps)``) and hence
no creep of a sticking body and no stiff slope ``mu lambda_n / v_eps`` for the integrator.
:func:`regularised_force` is the smooth law for comparison, with its error bound.
"""
from __future__ import annotations

import math
from typing import NamedTuple, Optional

import numpy as np

__all__ = ["FrictionParams", "SEPARATED", "SLIP_NEGATIVE", "SLIP_POSITIVE", "STICK", "after_stop",
           "regularisation_error_bound", "regularised_force", "slip_force", "slip_force_direction", "slip_mode",
           "stick_margin"]

#: contact modes (FMU Integers): the normal contact opened, or closed and sticking / slipping
SEPARATED, STICK, SLIP_POSITIVE, SLIP_NEGATIVE = 0, 1, 2, 3
MODE_NAMES = {SEPARATED: "SEPARATED", STICK: "STICK", SLIP_POSITIVE: "SLIP+", SLIP_NEGATIVE: "SLIP-"}


class FrictionParams(NamedTuple):
    """Friction of one contact: ``mu_s`` static, ``mu_k`` kinetic (``mu_k <= mu_s``) Coulomb
    coefficients, ``c_v`` viscous coefficient (N s/m) acting while slipping."""

    mu_s: float = 0.5
    mu_k: float = 0.4
    c_v: float = 0.0


def slip_mode(axis: np.ndarray) -> int:
    """The SLIP mode of a contact slipping along ``axis``: SLIP+ / SLIP- by its sign on a 1-D
    tangent; SLIP+ ("along its axis") in a tangential plane."""
    return SLIP_NEGATIVE if axis.size == 1 and axis[0] < 0.0 else SLIP_POSITIVE


def slip_force_direction(v_t: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """Unit direction ``e`` of the slip velocity: ``v_t / |v_t|`` while ``v_t . axis > 0``, else
    the (anchored) ``axis`` itself. On a 1-D tangent ``axis = [s]`` and both cases give ``s``.
    In a plane, past ``v_t . axis = 0`` the force keeps pushing along ``axis``, so ``v_t`` goes
    through zero transversally and the stop is an ordinary located event, not a chattering
    Filippov point (``v_t / |v_t|`` flips at ``v_t = 0``)."""
    vn = float(np.linalg.norm(v_t))
    return v_t / vn if vn > 0.0 and float(v_t @ axis) > 0.0 else axis


def slip_force(lam_n: float, v_t: np.ndarray, direction: np.ndarray, p: FrictionParams) -> np.ndarray:
    """Tangential force while slipping along the unit ``direction``: ``-mu_k lambda_n e - c_v v_t``."""
    return -p.mu_k * lam_n * direction - p.c_v * v_t


def stick_margin(lam_t: np.ndarray, lam_n: float, p: FrictionParams) -> float:
    """``mu_s lambda_n - |lambda_t|``: >= 0 inside the static cone (STICK holds)."""
    return p.mu_s * lam_n - float(np.linalg.norm(lam_t))


def after_stop(lam_t_stick: np.ndarray, lam_n: float, p: FrictionParams) -> Optional[np.ndarray]:
    """At zero tangential velocity, given the multiplier ``lambda_t`` that STICK would need: None
    (STICK) inside the static cone, else the axis ``-lambda_t / |lambda_t|`` to slip along (the
    unbalanced load drives the body against ``lambda_t``, and, for a contact not coupled to
    others, since ``|lambda_t| > mu_s lambda_n >= mu_k lambda_n`` the kinetic force cannot stop it)."""
    if stick_margin(lam_t_stick, lam_n, p) >= 0.0:
        return None
    return -lam_t_stick / float(np.linalg.norm(lam_t_stick))


def regularised_force(lam_n: float, v_t: float, p: FrictionParams, v_eps: float) -> float:
    """The smooth comparison law ``-mu_k lambda_n tanh(v_t / v_eps) - c_v v_t`` (no static
    friction: ``mu_s`` cannot be represented). Its deviation from the slip force is bounded by
    :func:`regularisation_error_bound`; a load below the static limit makes it creep at
    ``v_t = v_eps artanh(load / (mu_k lambda_n))`` instead of sticking."""
    return -p.mu_k * lam_n * math.tanh(v_t / v_eps) - p.c_v * v_t


def regularisation_error_bound(lam_n: float, v_t: float, p: FrictionParams, v_eps: float) -> float:
    """``|regularised - slip force| = mu_k lambda_n (1 - tanh(|v_t| / v_eps)) <= 2 mu_k lambda_n
    exp(-2 |v_t| / v_eps)`` for ``v_t != 0`` (since ``1 - tanh x = 2 / (exp(2x) + 1)``)."""
    return 2.0 * p.mu_k * lam_n * math.exp(-2.0 * abs(v_t) / v_eps)
