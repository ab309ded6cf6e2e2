"""A ball that bounces on a table, comes to rest on it and is lifted off: a constraint switched at events."""
from deltafmi.component import Experiment, Output, Parameter
from deltafmi.runtime.equations import EquationComponent, If, Real, assign, der, edge, ifelse, reinit, time

__all__ = ["BallOnTableEquations"]


class BallOnTableEquations(EquationComponent):
    """The talk's FREE / CONTACT machine as equations: free flight, impacts with restitution e,
    and once an impact is slower than capture_speed, CONTACT: the constraint h = 0 holds (the
    compiler reduces its index in that mode: lam = m g - F) until lam would pull (lam < 0).

    From t_lift an upward force F_lift acts on the ball.
    """

    model_name = "BallOnTableEquations"
    default_experiment = Experiment(start=0.0, stop=4.0, step=1e-3, tolerance=1e-10)
    cs_options = dict(rtol=1e-11, atol=1e-13)

    g = Parameter(9.81, unit="m/s2", description="Gravity")
    m = Parameter(0.5, unit="kg", min=0.0, description="Mass")
    e = Parameter(0.5, min=0.0, max=1.0, description="Coefficient of restitution")
    capture_speed = Parameter(0.1, unit="m/s", description="An impact slower than this ends in CONTACT")
    t_lift = Parameter(3.0, unit="s", description="From this time the force F_lift pulls the ball up")
    F_lift = Parameter(10.0, unit="N", description="The lifting force")
    h0 = Parameter(0.5, unit="m", description="Drop height")
    mode = Output(0, type=int, description="0 FREE, 1 CONTACT")
    lam = Output(unit="N", description="Contact force of the table")
    height = Output(unit="m", description="Height of the ball above the table")
    h = Real(0.5, unit="m")
    v = Real(0.0, unit="m/s")

    def equations(self):
        force = ifelse(time >= self.t_lift, self.F_lift, 0.0)
        return [der(self.h) == self.v,
                self.m * der(self.v) == -self.m * self.g + force + self.lam,
                If(self.mode.is_(1), [self.h == 0.0], [self.lam == 0.0]),
                self.height == self.h]

    def initial_equations(self):
        return [self.h == self.h0, self.v == 0.0]

    def algorithm(self):
        hit, slow, pulls = self.h <= 0.0, self.v > -self.capture_speed, self.lam < 0.0
        return [If(self.mode.is_(0) & edge(hit),
                   If(slow, [assign(self.mode, 1), reinit(self.h, 0.0), reinit(self.v, 0.0)],
                      [reinit(self.v, -self.e * self.v)])),
                If(self.mode.is_(1) & edge(pulls), assign(self.mode, 0))]
