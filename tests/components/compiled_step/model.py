"""Test component for a compiled Co-Simulation step (issue 26): a sampled accumulator whose step runs
as generated C in its FMU, handing steps to Python where Python must log; its Python ``do_step``
counts its own calls."""
from typing import NamedTuple

from deltafmi.component import Component, Experiment, Input, Kernel, NativeKernels, Output, Parameter


class Tally(NamedTuple):
    total: float   #: sum of the samples so far
    count: int     #: samples taken
    negative: bool  #: some sample was negative


def tally_step(tally: Tally, period: float, k: int, t0: float, t: float, h: float, u: float,
               scale: float) -> tuple[Tally, int, int, float, int]:
    """The samples t0 + k period in [t, t + h): each adds scale * u to the total. A first
    negative sample is Python's (it warns)."""
    end = t + h - 1e-9 * period
    defer = 0
    while t0 + k * period < end:
        if u < 0.0 and not tally.negative:
            defer = 1
        tally = Tally(tally.total + scale * u, tally.count + 1, tally.negative or u < 0.0)
        k += 1
    return tally, k, defer, tally.total, tally.count


def tally_update(tally: Tally, period: float, k: int, t0: float, t: float, u: float,
                 scale: float) -> tuple[Tally, int, int, float, float, int]:
    """The event update at t (Model Exchange's time events): the sample due at t, if any."""
    defer = 0
    if t >= t0 + k * period - 1e-9 * period:
        if u < 0.0 and not tally.negative:
            defer = 1
        tally = Tally(tally.total + scale * u, tally.count + 1, tally.negative or u < 0.0)
        k += 1
    return tally, k, defer, t0 + k * period, tally.total, tally.count


class CompiledTally(Component):
    """total = sum of scale * u over the samples t0 + k period (a compiled step)."""

    default_experiment = Experiment(stop=1.0, step=0.01)
    period = Parameter(0.01, unit="s", description="Sample period")
    scale = Parameter(2.0, description="Weight of a sample")
    u = Input(0.0, description="Sampled input")
    total = Output(0.0, variability="discrete", description="Sum of scale * u")
    count = Output(0, type=int, description="Samples taken")
    python_steps = Output(0, type=int, description="Steps the Python do_step took")
    python_updates = Output(0, type=int, description="Event updates the Python update took")

    native = NativeKernels(
        step=Kernel(tally_step, "_tally", "period", "_k", "_t0", "t", "h", "u", "scale", updates=("_tally", "_k"),
                    defer=True, returns=("total", "count")),
        update=Kernel(tally_update, "_tally", "period", "_k", "_t0", "t", "u", "scale", updates=("_tally", "_k"),
                      defer=True, returns=("total", "count")),
        attributes={"_tally": Tally, "_k": int, "_t0": float})

    def setup(self) -> None:
        self._tally, self._k, self._t0 = None, 0, 0.0

    def initialize(self, t: float) -> None:
        self._tally, self._k, self._t0 = Tally(0.0, 0, False), 0, t

    def do_step(self, t: float, h: float) -> None:
        negative_before = self._tally.negative
        self._tally, self._k, _, self.total, self.count = tally_step(self._tally, self.period, self._k, self._t0, t, h,
                                                                     self.u, self.scale)
        if self._tally.negative and not negative_before:
            self.log(f"a negative sample at t = {t}", level="warning")
        self.python_steps += 1

    def update(self, t: float) -> None:
        negative_before = self._tally.negative
        self._tally, self._k, _, _, self.total, self.count = tally_update(self._tally, self.period, self._k, self._t0,
                                                                          t, self.u, self.scale)
        if self._tally.negative and not negative_before:
            self.log(f"a negative sample at t = {t}", level="warning")
        self.python_updates += 1

    def next_time_event(self, t: float) -> float:
        return self._t0 + self._k * self.period
