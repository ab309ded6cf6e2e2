"""Test component for algebraic loops: a static gain with an offset and direct feedthrough."""
from deltafmi.component import Component, Experiment, Input, Output, Parameter


class Gain(Component):
    """y = (a + a_rate t) u + b + w: a static gain whose output reacts to its inputs at once."""

    default_experiment = Experiment(stop=1.0, step=0.1, tolerance=1e-10)
    a = Parameter(1.0, description="Gain at t = 0")
    a_rate = Parameter(0.0, unit="1/s", description="Rate of change of the gain")
    b = Parameter(0.0, description="Offset")
    u = Input(0.0, description="Input through the gain")
    w = Input(0.0, description="Input added to the output")
    y = Output(description="(a + a_rate t) u + b + w")
    direct_feedthrough = {"y": ["u", "w"]}

    def outputs(self, t):
        self.y = (self.a + self.a_rate * t) * self.u + self.b + self.w
