"""The delta robot's process model (:mod:`.delta_process`) as plain-float kernels for a filter's sample.

What an estimator over the robot's DAE computes at every sample, in the few calls a compiled
version makes cheap (the code generator translates these functions to C; a component hands the
compiled ones to its filter, which runs these Python functions otherwise, with the same results):

- :func:`prediction_values`: one classical Runge-Kutta period of the DAE, projected onto the
  closed loops, and the exact Jacobian at its start (:func:`~deltafmi.physics.delta.jacobian.jacobian_values`,
  whose accelerations are the step's first stage), in one call;
- :func:`wrist_kinematics`: the wrist position, the arms' world Jacobians, their inverses (the
  tangent basis dq/dz) and the rate of the wrist Jacobian at one state, what the filter's
  estimate, contact row and process noise need;
- the projection onto the loops is :func:`~deltafmi.physics.delta.dynamics.project_state`.

Each returns a flat list of floats (the layouts are given with each function); a filter takes
them as :class:`ProcessKernels`, callables that return float64 arrays (the form a compiled
function returns), :data:`PYTHON_KERNELS` when it is given no compiled ones.
"""
from __future__ import annotations

import math
from typing import Callable, NamedTuple, Sequence

import numpy as np

from ..delta.dynamics import _as_list, project_state, state_derivative
from ..delta.jacobian import N_VALUES, jacobian_values
from ..delta.kinematics import ARM_COS_SIN
from ..delta.params import DeltaParams

__all__ = ["N_KINEMATICS", "N_PREDICTION", "PYTHON_KERNELS", "ProcessKernels", "prediction_values", "wrist_kinematics"]

#: the floats of :func:`prediction_values`: q (9) and v (9) at the period's end, then the
#: :data:`~deltafmi.physics.delta.jacobian.N_VALUES` of jacobian_values at its start
N_PREDICTION = 18 + N_VALUES
#: the floats of :func:`wrist_kinematics`: z (3), the arms' R_i dpsi/dq (3 x 9), D (27), dq/dz (27)
N_KINEMATICS = 3 + 27 + 27 + 27


def prediction_values(p: DeltaParams, q: Sequence[float], v: Sequence[float], u: Sequence[float],
                      f: Sequence[float], T: float, pole: float, substeps: int) -> list[float]:
    """(q, v) after T under held u and f, then the Jacobian's floats at (q, v): classical
    Runge-Kutta (``substeps`` steps of T / substeps) of the stabilised DAE, projected onto the
    closed loops (:func:`~deltafmi.physics.delta.dynamics.project_state`), its first stage the
    accelerations of :func:`~deltafmi.physics.delta.jacobian.jacobian_values` (the state
    derivative's, to the bit). :data:`N_PREDICTION` floats: q (9), v (9), the Jacobian's values.

    Raises:
        ArithmeticError: H or the KKT matrix lost rank (a direct-kinematic singularity).
    """
    ql, vl, ul, fl = _as_list(q), _as_list(v), _as_list(u), _as_list(f)
    values = jacobian_values(p, ql, vl, ul, fl, pole)
    rate = vl + values[:9]
    x = ql + vl
    h = T / substeps
    for step in range(substeps):
        k1 = rate if step == 0 else state_derivative(p, x, ul, fl, pole)
        k2 = state_derivative(p, [x[i] + 0.5 * h * k1[i] for i in range(18)], ul, fl, pole)
        k3 = state_derivative(p, [x[i] + 0.5 * h * k2[i] for i in range(18)], ul, fl, pole)
        k4 = state_derivative(p, [x[i] + h * k3[i] for i in range(18)], ul, fl, pole)
        x = [x[i] + h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) for i in range(18)]
    qn, vn = project_state(p, x[:9], x[9:])
    return qn + vn + values


def wrist_kinematics(p: DeltaParams, q: Sequence[float], v: Sequence[float]) -> list[float]:
    """z(q), the arms' world Jacobians and D(q, v) = d(Jv v)/dq, :data:`N_KINEMATICS` floats:

    - z (3): the wrist, the mean of the arms' world wrist points R_i psi(q_i);
    - arm i's R_i dpsi/dq(q_i) (9 each, row-major; Jv = [arm 1, arm 2, arm 3] / 3);
    - D (3 x 9, row-major): arm i's columns R_i d(dpsi/dq_i)/dt / 3, the rate of Jv
      (:func:`.delta_process.arm_jacobian_rate`);
    - dq/dz (9 x 3, row-major): arm i's rows the inverse of its R_i dpsi/dq, the tangent basis
      of :func:`.delta_process.tangent_basis` (by the adjugate).

    Raises:
        ZeroDivisionError: an arm's Jacobian is singular (the arm stretched).
    """
    ql, vl = _as_list(q), _as_list(v)
    l0l3, l1, l2 = p.l0 - p.l3, p.l1, p.l2
    z = [0.0, 0.0, 0.0]
    arms: list[float] = []
    rates: list[float] = []
    inverses: list[float] = []
    for arm in range(3):
        cr, sr = ARM_COS_SIN[arm]
        q1, q2, q3 = ql[3 * arm], ql[3 * arm + 1], ql[3 * arm + 2]
        v1, v2, v3 = vl[3 * arm], vl[3 * arm + 1], vl[3 * arm + 2]
        s1, c1, s2, c2, s3, c3 = (math.sin(q1), math.cos(q1), math.sin(q2), math.cos(q2),
                                  math.sin(q3), math.cos(q3))
        px, py, pz = l2 * s2 * s3, l0l3 + l1 * c1 + l2 * c2, l1 * s1 + l2 * s2 * c3
        z = [z[0] + (cr * px - sr * py), z[1] + (sr * px + cr * py), z[2] + pz]
        # dpsi/dq (rows x, y, z of the arm frame), then R_i times it (a rotation about z)
        j = (0.0, l2 * c2 * s3, l2 * s2 * c3,
             -l1 * s1, -l2 * s2, 0.0,
             l1 * c1, l2 * c2 * c3, -l2 * s2 * s3)
        world = [cr * j[0] - sr * j[3], cr * j[1] - sr * j[4], cr * j[2] - sr * j[5],
                 sr * j[0] + cr * j[3], sr * j[1] + cr * j[4], sr * j[2] + cr * j[5],
                 j[6], j[7], j[8]]
        arms += world
        inverses += _inverse3(world)
        # d/dt dpsi/dq (arm_jacobian_rate), rotated and over 3
        r = (0.0, l2 * (c2 * c3 * v3 - s2 * s3 * v2), l2 * (c2 * c3 * v2 - s2 * s3 * v3),
             -l1 * c1 * v1, -l2 * c2 * v2, 0.0,
             -l1 * s1 * v1, -l2 * (s2 * c3 * v2 + c2 * s3 * v3), -l2 * (c2 * s3 * v2 + s2 * c3 * v3))
        rates += [(cr * r[0] - sr * r[3]) / 3.0, (cr * r[1] - sr * r[4]) / 3.0, (cr * r[2] - sr * r[5]) / 3.0,
                  (sr * r[0] + cr * r[3]) / 3.0, (sr * r[1] + cr * r[4]) / 3.0, (sr * r[2] + cr * r[5]) / 3.0,
                  r[6] / 3.0, r[7] / 3.0, r[8] / 3.0]
    # D row-major (3 x 9): row k takes each arm's row k
    d: list[float] = []
    for k in range(3):
        for arm in range(3):
            d += [rates[9 * arm + 3 * k], rates[9 * arm + 3 * k + 1], rates[9 * arm + 3 * k + 2]]
    return [z[0] / 3.0, z[1] / 3.0, z[2] / 3.0] + arms + d + inverses


def _inverse3(m: list[float]) -> list[float]:
    """The inverse of a 3 x 3 matrix (row-major) by its adjugate."""
    a, b, c, d, e, f, g, h, i = m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]
    c00, c01, c02 = e * i - f * h, f * g - d * i, d * h - e * g
    det = a * c00 + b * c01 + c * c02
    return [c00 / det, (c * h - b * i) / det, (b * f - c * e) / det,
            c01 / det, (a * i - c * g) / det, (c * d - a * f) / det,
            c02 / det, (b * g - a * h) / det, (a * e - b * d) / det]


class ProcessKernels(NamedTuple):
    """The kernels a filter calls, each returning a new float64 array: ``predict`` (the arguments
    and floats of :func:`prediction_values`), ``project`` ((p, q, v) -> [q; v] on the loops, as
    :func:`~deltafmi.physics.delta.dynamics.project_state`), ``kinematics`` (:func:`wrist_kinematics`).
    A component's compiled functions of the same names fit (``self.native_functions``)."""

    predict: Callable[..., np.ndarray]
    project: Callable[..., np.ndarray]
    kinematics: Callable[..., np.ndarray]


def _predict(p: DeltaParams, q: Sequence[float], v: Sequence[float], u: Sequence[float], f: Sequence[float],
             T: float, pole: float, substeps: int) -> np.ndarray:
    return np.array(prediction_values(p, q, v, u, f, T, pole, substeps))


def _project(p: DeltaParams, q: Sequence[float], v: Sequence[float]) -> np.ndarray:
    qn, vn = project_state(p, q, v)
    return np.array(qn + vn)


def _kinematics(p: DeltaParams, q: Sequence[float], v: Sequence[float]) -> np.ndarray:
    return np.array(wrist_kinematics(p, q, v))


#: the kernels as Python (what a filter runs without compiled ones)
PYTHON_KERNELS = ProcessKernels(_predict, _project, _kinematics)
