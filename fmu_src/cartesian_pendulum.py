"""A pendulum in Cartesian coordinates: the index-3 DAE as written, reduced by the equation compiler."""
from deltafmi.component import Experiment, Output, Parameter
from deltafmi.runtime.equations import EquationComponent, Real, der, sin

__all__ = ["CartesianPendulum"]


class CartesianPendulum(EquationComponent):
    """Point mass on a massless rod of length L, in x (horizontal) and y (up) with a multiplier.

    m x'' = -lam x / L, m y'' = -lam y / L - m g, x^2 + y^2 = L^2 (index 3): the compiler
    differentiates the constraint twice, solves the multiplier with the accelerations and projects
    the states back onto the circle and its tangent.
    """

    model_name = "CartesianPendulum"
    default_experiment = Experiment(start=0.0, stop=10.0, step=1e-3, tolerance=1e-10)
    cs_options = dict(rtol=1e-11, atol=1e-13)

    L = Parameter(1.0, unit="m", min=0.0, description="Rod length")
    g = Parameter(9.81, unit="m/s2", description="Gravity")
    m = Parameter(1.0, unit="kg", min=0.0, description="Mass")
    phi0 = Parameter(0.5, unit="rad", description="Start angle from the downward vertical (at rest)")

    x = Output(unit="m", description="Horizontal position of the mass")
    y = Output(unit="m", description="Vertical position of the mass (up)")
    px = Real(0.5, unit="m")
    py = Real(-0.8, unit="m")
    vx = Real(unit="m/s")
    vy = Real(unit="m/s")
    lam = Real(unit="N", description="Rod tension")

    def equations(self):
        return [der(self.px) == self.vx,
                der(self.py) == self.vy,
                self.m * der(self.vx) == -self.lam * self.px / self.L,
                self.m * der(self.vy) == -self.lam * self.py / self.L - self.m * self.g,
                self.px ** 2 + self.py ** 2 == self.L ** 2,
                self.x == self.px,
                self.y == self.py]

    def initial_equations(self):
        return [self.px == self.L * sin(self.phi0), self.vx == 0.0]
