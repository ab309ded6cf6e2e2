"""Test component for algebraic loops: a first-order lag whose output also feeds its input through."""
from deltafmi.component import Component, Experiment, Input, Output, Parameter, State


class Lag(Component):
    """T x' = u - x, y = x + d u: a lag with a direct feedthrough d (a state in an algebraic loop)."""

    default_experiment = Experiment(stop=1.0, step=0.01, tolerance=1e-10)
    T = Parameter(0.5, unit="s", description="Time constant")
    d = Parameter(0.5, description="Direct feedthrough from u to y")
    x = State(1.0, description="Lag state")
    u = Input(0.0, description="Input")
    y = Output(description="x + d u")
    direct_feedthrough = {"y": ["u"]}

    def derivatives(self, t):
        return [(self.u - self.x) / self.T]

    def outputs(self, t):
        self.y = self.x + self.d * self.u
