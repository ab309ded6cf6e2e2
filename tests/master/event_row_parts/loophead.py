from deltafmi.component import Experiment, Input, Output
from deltafmi.runtime.equations import EquationComponent, Real, der


class LoopHead(EquationComponent):
    """y = x + u / 2 with x' = 1: closed through a follower (u = y), y = 2 t."""
    model_name = "LoopHead"
    default_experiment = Experiment(start=0.0, stop=1.0, step=1e-2, tolerance=1e-10)
    u = Input(0.0, unit="s")
    y = Output(unit="s")
    x = Real(0.0, unit="s")

    def equations(self):
        return [der(self.x) == 1.0, self.y == self.x + 0.5 * self.u]
