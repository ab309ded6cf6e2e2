"""Test component: three decoupled first-order lags with array variables of every FMI type."""
import math

from deltafmi.component import Component, Experiment, Input, Output, Parameter, State


class Lags(Component):
    """Three first-order lags x_i' = -k_i x_i + u_i, with outputs y = gain * x."""

    default_experiment = Experiment(stop=1.0, step=0.01, tolerance=1e-10)
    k = Parameter([1.0, 2.0, 4.0], unit="1/s", description="Rates")
    gain = Parameter(2.0, tunable=True, description="Output gain (tunable)")
    fail_at = Parameter(math.inf, unit="s", description="Raise an exception after this time")
    label = Parameter("lags", description="A string parameter")
    n_steps = Parameter(3, type=int, description="An integer parameter")
    x = State([1.0, 1.0, 1.0], description="Lag states")
    u = Input([0.0, 0.0, 0.0], description="Lag inputs")
    y = Output(shape=3, description="gain * x")
    positive = Output(True, type=bool, description="All states positive")
    direct_feedthrough = {}

    def derivatives(self, t):
        if t > self.fail_at:
            raise ValueError(f"deliberate failure at t = {t}")
        return -self.k * self.x + self.u

    def outputs(self, t):
        self.y = self.gain * self.x
        self.positive = bool((self.x > 0).all())
