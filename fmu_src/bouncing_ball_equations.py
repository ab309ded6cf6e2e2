"""The talk's myBouncingBall as equations: contact modes, an if-equation and an algorithm."""
from deltafmi.component import Experiment, Output, Parameter
from deltafmi.runtime.equations import EquationComponent, If, Real, assign, der, edge, ifelse

__all__ = ["BouncingBallEquations"]


class BouncingBallEquations(EquationComponent):
    """The talk's myBouncingBall written as equations and an algorithm (BouncingBall by hand).

    In contact state 1 the floor force solves 0 = h'' + a1 h' + a0 h + a2 h^3 (an if-equation:
    the compiler sorts and solves each branch, the kernel switches between them); the algorithm
    moves the contact state at the events of its relations, with edge() and pre() semantics.
    """

    model_name = "BouncingBallEquations"
    default_experiment = Experiment(start=0.0, stop=3.0, step=1e-3, tolerance=1e-8)
    cs_options = dict(rtol=1e-9, atol=1e-11)

    g = Parameter(9.81, unit="m/s2", description="Gravity")
    m = Parameter(1.0, unit="kg", description="Mass of the ball", min=0.0)
    a0 = Parameter(100.0, description="Contact law stiffness a0 (1/s2)")
    a1 = Parameter(20.0, description="Contact law damping a1 (1/s)")
    a2 = Parameter(1e6, description="Contact law cubic stiffening a2 (1/(m2.s2))")
    linFlag = Parameter(False, description="Always apply the contact equation (linear model)")
    contact = Output(0, type=int, description="Contact state: 0 free, 1 contact law, 2 released")
    f = Output(unit="N", description="Force of the floor on the ball, f = contact*lambda")
    lam = Output(unit="N", description="Multiplier lambda of the contact equation")
    energy = Output(unit="J", description="Mechanical energy m v^2/2 + m g q")
    q = Real(1.0, unit="m", description="Height of the ball")
    v = Real(0.0, unit="m/s", description="Vertical velocity")
    h, hDot, hDotDot = Real(unit="m"), Real(unit="m/s"), Real(unit="m/s2")

    def equations(self):
        return [If(self.contact.is_(1) | self.linFlag,
                   [0.0 == self.hDotDot + self.a1 * self.hDot + self.a0 * self.h + self.a2 * self.h ** 3],
                   [self.lam == 0.0]),
                self.f == ifelse(self.linFlag, self.lam, self.contact * self.lam),
                der(self.q) == self.v,
                self.m * der(self.v) == -self.m * self.g + self.f,
                self.h == self.q,
                self.hDot == der(self.h),
                self.hDotDot == der(self.hDot),
                self.energy == 0.5 * self.m * self.v ** 2 + self.m * self.g * self.q]

    def algorithm(self):
        b1, b2, b3 = self.h <= 0.0, self.lam < 0.0, self.h > 0.0
        b4 = (self.h <= 0.0) & (self.hDot < 0.0)
        c = self.contact
        return [If(edge(b1) & c.is_(0), assign(c, 1)),
                If(c.is_(1) & edge(b2), assign(c, 2)),
                If(c.is_(2) & edge(b3), assign(c, 0)),
                If(c.is_(2) & edge(b4), assign(c, 1))]
