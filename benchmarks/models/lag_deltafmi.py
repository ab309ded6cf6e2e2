"""Benchmark model: an exactly discretized first-order lag, stepped by the component itself."""
import math

from deltafmi.component import Component, Experiment, Input, Output, Parameter


class Lag(Component):
    """First-order lag y' = (u - y) / T, discretized exactly per step (no solver: pure FMI cost)."""

    default_experiment = Experiment(stop=1.0, step=1e-3)
    T = Parameter(0.1, unit="s", description="Time constant")
    u = Input(0.0, description="Input")
    y = Output(0.0, initial="exact", description="Output")
    direct_feedthrough = {}

    def do_step(self, t, h):
        self.y += (self.u - self.y) * (1.0 - math.exp(-h / self.T))
