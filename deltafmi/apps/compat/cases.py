"""What each shipped model (:data:`deltafmi.models.MODELS`) runs in the compatibility tree: its
stop time, communication step and tolerance (``X_ref.opt``), the variables of ``X_ref.csv`` and
the input signals of ``X_in.csv``.

Runs are short (the robots 0.2 s: their Python right-hand sides are the slow part of anyone's
import test) and record at most ten variables, as the rules recommend; the inputs are smooth so
that an importer interpolating them linearly (as the rules ask) and one holding them over a
communication step see nearly the same signal.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable, Dict, Optional, Tuple

import numpy as np

__all__ = ["Case", "case_for"]

Signals = Callable[[np.ndarray], Dict[str, np.ndarray]]


@dataclass(frozen=True)
class Case:
    """One model's compatibility run. ``record`` and the keys of ``inputs(t)`` are declaration
    names (an array whole: ``z``); ``inputs(t)`` gives a 1-D array per scalar input and a
    (time x elements) array per array input. Inputs it leaves out keep their start values."""

    stop: float
    step: float
    tolerance: float
    record: Tuple[str, ...]
    inputs: Optional[Signals] = None
    start: float = 0.0


def _sine(amplitude: float, frequency: float) -> Callable[[np.ndarray], np.ndarray]:
    return lambda t: amplitude * np.sin(2 * math.pi * frequency * t)


def _columns(t: np.ndarray, *rows: Callable[[np.ndarray], np.ndarray] | float) -> np.ndarray:
    """A (time x elements) array from one function of t (or constant) per element."""
    return np.column_stack([row(t) if callable(row) else np.full_like(t, row) for row in rows])


def _plant_inputs(t: np.ndarray) -> Dict[str, np.ndarray]:
    # a small torque wave on arm 1 over no torque at all: the arms fall and swing under gravity
    return {"u": _columns(t, _sine(20.0, 2.0), 0.0, 0.0), "f": _columns(t, 0.0, 0.0, 0.0)}


def _controller_inputs(t: np.ndarray) -> Dict[str, np.ndarray]:
    from deltafmi.physics.delta.control import inverse_kinematics_servo
    from deltafmi.physics.delta.params import RL5

    y, _ = inverse_kinematics_servo(RL5, [0.0, 0.0, -1.0])  # measured: the robot at rest at home
    w = 2 * math.pi * 2.0
    a = 0.01  # m: the reference moves 1 cm up and down at 2 Hz
    return {"y": _columns(t, *y), "yd": _columns(t, 0.0, 0.0, 0.0),
            "r": _columns(t, 0.0, 0.0, lambda s: -1.0 + a * np.sin(w * s)),
            "rd": _columns(t, 0.0, 0.0, lambda s: a * w * np.cos(w * s)),
            "rdd": _columns(t, 0.0, 0.0, lambda s: -a * w * w * np.sin(w * s))}


def _wrist_inputs(t: np.ndarray) -> Dict[str, np.ndarray]:
    # the delta's torque wave and a small wave on each wrist joint: the tool swings as the arms fall
    return {**_plant_inputs(t), "tau": _columns(t, _sine(0.02, 3.0), _sine(0.02, 2.0), _sine(0.01, 5.0))}


CASES: Dict[str, Case] = {
    "BouncingBall": Case(3.0, 0.005, 1e-8, ("q", "v", "f", "energy", "contact")),
    "BouncingBallRestitution": Case(3.0, 0.005, 1e-8, ("q", "v", "lam", "energy", "mode"),
                                    lambda t: {"F": _sine(1.0, 1.0)(t)}),
    "BoxOnTable": Case(2.0, 0.005, 1e-8, ("pos", "theta", "vel", "omega", "total_force"),
                       lambda t: {"push": _columns(t, _sine(3.0, 0.5), 0.0), "torque": _sine(0.5, 1.0)(t)}),
    "DeltaController": Case(0.2, 1e-3, 1e-6, ("u", "status", "z_est"), _controller_inputs),
    "DeltaRobot": Case(0.2, 1e-3, 1e-6, ("y", "z", "zd", "energy"), _plant_inputs),
    "DeltaRobotBox": Case(0.2, 1e-3, 1e-8, ("y", "z", "zd", "energy"), _plant_inputs),
    "DeltaRobotContact": Case(0.2, 1e-3, 1e-8, ("y", "z", "zd", "energy"), _plant_inputs),
    "DeltaWrist": Case(0.2, 1e-3, 1e-8, ("y", "qw", "tip", "energy"), _wrist_inputs),
    # unheld, the robot drops the peg from 20 mm above the (centred) hole into it: contact after 0.09 s
    "DeltaWristPeg": Case(0.2, 1e-3, 1e-8, ("y", "qw", "tip", "depth", "contact_force"), _wrist_inputs),
    "NewtonsCradle": Case(1.0, 0.002, 1e-8, ("vx", "energy", "momentum")),
    "Oscillator": Case(4.0, 0.005, 1e-8, ("x", "v", "energy", "impacts"),
                       lambda t: {"F": _sine(2.0, 0.5)(t)}),
    "TactileSensor": Case(0.5, 1e-3, 1e-6, ("pad", "difference", "total", "offset", "compression"),
                          lambda t: {"fn": 10.0 + _sine(5.0, 4.0)(t)}),
    "TargetFollower": Case(2.0, 1e-3, 1e-6, ("r", "rd", "rdd", "status"),
                           lambda t: {"target": _columns(t, _sine(0.2, 0.5), 0.0, -1.0)}),
    "Trajectory": Case(3.0, 0.005, 1e-6, ("r", "rd", "rdd")),
}


def case_for(model: str, md: Any) -> Case:
    """The run of the packaged model ``model`` (``md``: its fmpy model description); a model
    without a case here runs its default experiment (at most 1000 communication steps) and
    records its first ten outputs."""
    if model in CASES:
        return CASES[model]
    experiment = md.defaultExperiment
    start = float(experiment.startTime or 0.0) if experiment else 0.0
    stop = float(experiment.stopTime or start + 1.0) if experiment else start + 1.0
    step = max(float(experiment.stepSize or 0.0) if experiment else 0.0, (stop - start) / 1000)
    tolerance = float(experiment.tolerance or 1e-6) if experiment else 1e-6
    outputs = list(dict.fromkeys(v.name.split("[")[0] for v in md.modelVariables if v.causality == "output"))
    return Case(stop, step, tolerance, tuple(outputs[:10]), start=start)
