"""Test component with the same file name as first/model.py: a discrete counter."""
from deltafmi.component import Component, Experiment, Input, Output, Parameter


class Counter(Component):
    """Counts steps and accumulates its input times the step size (a discrete integrator)."""

    default_experiment = Experiment(stop=1.0, step=0.1)
    scale = Parameter(1.0, description="Scale of the accumulated value")
    u = Input(1.0, description="Integrand")
    total = Output(description="scale * sum(u h)")
    count = Output(0, type=int, description="Number of steps taken")

    def setup(self):
        self.accumulated = 0.0

    def do_step(self, t, h):
        self.accumulated += self.u * h
        self.count += 1

    def outputs(self, t):
        self.total = self.scale * self.accumulated
