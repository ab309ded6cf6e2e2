"""Test component that needs scipy, which a host with nothing but fmpy lacks (portable FMU tests)."""
from scipy import special

from deltafmi.component import Component, Experiment, Output, State


class Erf(Component):
    """x grows at 1/s from 0; y = erf(x), computed by scipy.special."""

    default_experiment = Experiment(stop=1.0, step=0.01, tolerance=1e-10)
    x = State(0.0, unit="s", description="Time since the start")
    y = Output(description="erf(x)")

    def derivatives(self, t):
        return [1.0]

    def outputs(self, t):
        self.y = float(special.erf(self.x))
