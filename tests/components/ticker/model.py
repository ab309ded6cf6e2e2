"""Test components: a sampled counter with no states that does not step itself (no do_step), with
and without a Clock; its sample raises after ``fail_after`` seconds."""
from deltafmi.component import Clock, Component, Experiment, Output, Parameter


class Ticker(Component):
    """Counts its samples, every sample_period from the start."""

    default_experiment = Experiment(stop=0.006, step=1e-3)
    sample_period = Parameter(1e-3, unit="s")
    fail_after = Parameter(1e9, unit="s", description="The samples after this time raise")
    n = Output(0, type=int, variability="discrete", description="Samples taken")

    def setup(self):
        self._t0, self._k = 0.0, 0

    def initialize(self, t):
        self._t0, self._k = t, 0

    def next_time_event(self, t):
        return self._t0 + self._k * self.sample_period

    def update(self, t):
        if t >= self.next_time_event(t) - 1e-9 * self.sample_period:
            if t > self.fail_after:
                raise RuntimeError(f"the sample at t = {t:g} failed")
            self.n = self.n + 1
            self._k += 1


class ClockedTicker(Ticker):
    """The Ticker with its sample instants declared as a Clock."""

    sample = Clock(period="sample_period")
