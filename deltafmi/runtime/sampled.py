"""A Component that acts only at periodic sample instants, in Python (an estimator, a controller
whose sample calls a library): the scheduling every such component needs, written once.

Samples are due at ``t_start + k * sample_period`` for k = ``first_sample``, first_sample + 1, ...
Co-Simulation: ``doStep(t, h)`` takes the samples due in [t, t + h) with the inputs at t.
Model Exchange: the sample instants are time events. FMI 3.0: declare a Clock with
``period="sample_period"`` and its ticks are the same instants. Nothing here knows what a sample
computes.
"""
from __future__ import annotations

from .base import Component

__all__ = ["SampledComponent"]


class SampledComponent(Component):
    """Base class: declare a Parameter ``sample_period``, call :meth:`start_sampling` in
    ``initialize``, implement :meth:`take_sample` (one sample with the inputs now; the outputs it
    writes hold until the next). ``first_sample`` = 1 skips the start instant, whose event
    iteration some importers run before they have set the inputs from connected outputs."""

    first_sample = 0
    _t0 = 0.0
    _k = 0

    def start_sampling(self, t: float) -> None:
        """The first sample instant is ``t + first_sample * sample_period``."""
        if not self.sample_period > 0.0:
            raise ValueError(f"sample_period must be > 0, got {self.sample_period}")
        self._t0, self._k = t, self.first_sample

    @property
    def sample_index(self) -> int:
        """k of the sample being taken (in :meth:`take_sample`), or of the next one."""
        return self._k

    def take_sample(self) -> None:
        """One sample at the instant ``t_start + sample_index * sample_period``."""
        raise NotImplementedError

    def _sample_now(self) -> None:
        self.take_sample()
        self._k += 1

    def next_time_event(self, t: float) -> float:
        return self._t0 + self._k * self.sample_period

    def update(self, t: float) -> None:
        if t >= self.next_time_event(t) - 1e-9 * self.sample_period:
            self._sample_now()
            while self.next_time_event(t) <= t:  # never schedule an instant already passed
                self._k += 1

    def do_step(self, t: float, h: float) -> None:
        end = t + h - 1e-9 * self.sample_period
        while self.next_time_event(t) < end:
            self._sample_now()
