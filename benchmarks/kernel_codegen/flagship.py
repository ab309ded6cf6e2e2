"""The flagship's kernels generated from deltafmi/physics/delta/*.py, closed in a C loop.

:func:`entries` lists what is generated: the plant's ``state_derivative`` and ``evaluate_plant``
(dynamics.py), the controller's whole ``sample`` (sampling.py: DeltaController.step, its state
between samples included) and its pieces ``evaluate``, ``hold`` and ``warm_start``
(control_law.py, for the tests) and the path's ``MinimumJerkPath.evaluate_flat`` (trajectory.py,
specialized on the path's number of waypoints). :func:`build` compiles them with the
hand-written driver flagship_loop.c (the master's RK4 and the closed loop) into one library;
:class:`GeneratedFlagship` runs it on the flagship's data (benchmarks/native.py's
``flagship_models``).
"""
from __future__ import annotations

import ctypes
from ctypes import POINTER, c_double, c_int, c_long
from pathlib import Path
from typing import Any

import numpy as np

from deltafmi.physics.delta import control_law, dynamics, kinematics, sampling
from deltafmi.physics.delta.params import DeltaParams
from deltafmi.physics.delta.trajectory import MinimumJerkPath

from deltafmi.builder.codegen.build import Library, compile_unit, ctypes_type, to_c
from deltafmi.builder.codegen.kernel_types import D, Entry, Obj, Opt, Vec, named, record

LOOP = Path(__file__).resolve().parent / "flagship_loop.c"
#: helpers the fixed-length C data make the identity (list / 3-float conversions)
IDENTITIES = {"_as_list", "_f3"}
_D = POINTER(c_double)


def entries(path: MinimumJerkPath) -> list[Entry]:
    """The generated entries (their C names are what flagship_loop.c calls)."""
    law = named(control_law.ControlLaw)
    return [
        Entry("dfk_state_derivative", dynamics.state_derivative, [Obj(DeltaParams), Vec(18), Vec(3), Vec(3), D]),
        Entry("dfk_evaluate_plant", dynamics.evaluate_plant, [Obj(DeltaParams), Vec(9), Vec(9), Vec(3), Vec(3), D]),
        Entry("dfk_sample", sampling.sample, [law, named(sampling.SampleSettings), named(sampling.SampleState),
                                              Vec(3), Vec(3), Vec(3), Vec(3), Vec(3), Vec(3), D]),
        Entry("dfk_evaluate", control_law.evaluate,
              [law, Vec(3), Vec(3), Vec(3), Vec(3), Vec(3), Vec(3), D, Opt(Vec(6)), Vec(3)]),
        Entry("dfk_hold", control_law.hold, [Vec(3), Opt(Vec(3)), D]),
        Entry("dfk_warm_start", control_law.warm_start, [Vec(6), Vec(6), Opt(Vec(6)), D]),
        Entry("dfk_path", MinimumJerkPath.evaluate_flat, [record(path), D]),
    ]


def build(path: MinimumJerkPath, directory: Path) -> Library:
    """The generated kernels and the driver, compiled into ``directory``."""
    return compile_unit(entries(path), directory, extra_c=LOOP.read_text(), identities=IDENTITIES,
                        name="flagship_generated")


def _ptr(a: np.ndarray):
    return a.ctypes.data_as(_D)


class GeneratedFlagship:
    """The generated closed loop on the flagship's pieces (benchmarks/native.py ``Models``)."""

    def __init__(self, models: Any, directory: Path) -> None:
        self.models = models
        self.path = MinimumJerkPath(models.waypoints, models.durations, models.dwell, models.t0, workspace=None)
        self.library = build(self.path, directory)
        ctl = models.controller
        self.plant = to_c(Obj(DeltaParams), models.plant)
        self.law = to_c(named(control_law.ControlLaw), ctl.law)
        self.path_c = to_c(record(self.path), self.path)
        self.sample_period, self.zoh_lead = float(ctl.sample_period), int(bool(ctl.zoh_lead))
        self.f = np.array(models.f, dtype=float)
        lib = self.library.lib
        plant_p, law_p = POINTER(type(self.plant)), POINTER(type(self.law))
        lib.gen_run.argtypes = [plant_p, c_double, _D, law_p, c_double, c_int, POINTER(type(self.path_c)),
                                c_double, c_double, _D, c_long, _D]
        lib.gen_run.restype = c_int
        lib.gen_replay_controller.argtypes = [law_p, c_double, c_int, _D, c_long, _D]
        lib.gen_replay_controller.restype = c_double
        lib.gen_repeat_derivative.argtypes = [plant_p, c_double, _D, _D, _D, c_long]
        lib.gen_repeat_derivative.restype = c_double
        assert ctypes_type(Obj(DeltaParams)) is type(self.plant)

    def initial_state(self) -> np.ndarray:
        """The plant at rest at z0 (kinematics.inverse_kinematics, as the DeltaRobot component)."""
        q = kinematics.inverse_kinematics(self.models.plant, self.models.z0)
        return np.concatenate([np.asarray(q, dtype=float), np.zeros(9)])

    def run(self, start: float, h: float, steps: int) -> np.ndarray:
        """Rows (steps + 1, 15) as benchmarks/native.py's COLUMNS."""
        rows = np.empty((steps + 1, 15))
        x0 = self.initial_state()
        err = self.library.lib.gen_run(ctypes.byref(self.plant), self.models.pole, _ptr(self.f), ctypes.byref(self.law),
                                       self.sample_period, self.zoh_lead, ctypes.byref(self.path_c), start, h,
                                       _ptr(x0), steps, _ptr(rows))
        if err:
            raise ArithmeticError(f"a generated kernel raised (line {err})")
        return rows

    def replay_controller(self, inputs: np.ndarray) -> tuple[np.ndarray, float]:
        """Torques (samples, 3) of a fresh controller fed ``inputs`` (samples, 15), and the wall seconds."""
        import time

        inputs = np.ascontiguousarray(inputs)
        u = np.empty((len(inputs), 3))
        begin = time.perf_counter()
        self.library.lib.gen_replay_controller(ctypes.byref(self.law), self.sample_period, self.zoh_lead,
                                               _ptr(inputs), len(inputs), _ptr(u))
        return u, time.perf_counter() - begin

    def repeat_derivative(self, x: np.ndarray, u: np.ndarray, calls: int) -> float:
        """Wall seconds of ``calls`` generated plant derivatives at (x, u)."""
        import time

        x, u = np.ascontiguousarray(x, dtype=float), np.ascontiguousarray(u, dtype=float)
        begin = time.perf_counter()
        self.library.lib.gen_repeat_derivative(ctypes.byref(self.plant), self.models.pole, _ptr(x), _ptr(u),
                                               _ptr(self.f), calls)
        return time.perf_counter() - begin
