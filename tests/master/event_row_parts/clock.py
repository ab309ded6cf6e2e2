from deltafmi.component import Experiment, Input, Output, Parameter
from deltafmi.runtime.equations import EquationComponent, Real, der


class Clock(EquationComponent):
    """y = t, integrated."""
    model_name = "Clock"
    default_experiment = Experiment(start=0.0, stop=1.0, step=1e-2, tolerance=1e-10)
    y = Output(unit="s")
    x = Real(0.0, unit="s")

    def equations(self):
        return [der(self.x) == 1.0, self.y == self.x]
