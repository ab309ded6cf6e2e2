"""Test component for the NaN check: an output that leaves the real numbers at a set time."""
import math

from deltafmi.component import Component, Experiment, Output, Parameter


class Fragile(Component):
    """y = sqrt(t_nan - t): real until t_nan, NaN after it (a model pushed out of its domain);
    ok = t stays finite."""

    default_experiment = Experiment(stop=1.0, step=0.01, tolerance=1e-8)
    t_nan = Parameter(0.415, unit="s", description="Time after which y is NaN")
    y = Output(description="sqrt(t_nan - t), NaN after t_nan")
    ok = Output(description="t, always finite")
    direct_feedthrough = {}

    def outputs(self, t):
        self.y = math.sqrt(self.t_nan - t) if t <= self.t_nan else math.nan
        self.ok = t
