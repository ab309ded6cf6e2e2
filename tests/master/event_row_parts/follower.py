from deltafmi.component import Experiment, Input, Output, Parameter
from deltafmi.runtime.equations import EquationComponent, Real, der


class Follower(EquationComponent):
    """y = u (direct feedthrough); area: the integral of u."""
    model_name = "Follower"
    default_experiment = Experiment(start=0.0, stop=1.0, step=1e-2, tolerance=1e-10)
    u = Input(0.0, unit="m")
    y = Output(unit="m")
    area = Real(0.0, unit="m.s")

    def equations(self):
        return [self.y == self.u, der(self.area) == self.u]
