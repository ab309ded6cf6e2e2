"""The textbook bouncing ball as equations: a when clause with reinit."""
from deltafmi.component import Experiment, Output, Parameter
from deltafmi.runtime.equations import EquationComponent, Real, assign, der, pre, reinit, when

__all__ = ["BouncingBallReinit"]


class BouncingBallReinit(EquationComponent):
    """The textbook ball: free fall, and at every impact v -> -e v (when h <= 0: reinit)."""

    model_name = "BouncingBallReinit"
    default_experiment = Experiment(start=0.0, stop=3.0, step=1e-3, tolerance=1e-10)
    cs_options = dict(rtol=1e-11, atol=1e-13)

    g = Parameter(9.81, unit="m/s2", description="Gravity")
    e = Parameter(0.8, description="Coefficient of restitution", min=0.0, max=1.0)
    h0 = Parameter(1.0, unit="m", description="Drop height (from rest)")
    height = Output(unit="m", description="Height of the ball")
    impacts = Output(0, type=int, description="Impacts so far")
    h = Real(1.0, unit="m")
    v = Real(0.0, unit="m/s")

    def equations(self):
        return [der(self.h) == self.v, der(self.v) == -self.g, self.height == self.h,
                when(self.h <= 0.0, reinit(self.v, -self.e * pre(self.v)), assign(self.impacts, pre(self.impacts) + 1))]

    def initial_equations(self):
        return [self.h == self.h0, self.v == 0.0]
