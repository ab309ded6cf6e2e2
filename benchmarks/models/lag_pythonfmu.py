"""The same lag as lag_deltafmi.py, written for pythonfmu (Co-Simulation only)."""
import math

from pythonfmu import Fmi2Causality, Fmi2Slave, Fmi2Variability, Real


class Lag(Fmi2Slave):
    """First-order lag y' = (u - y) / T, discretized exactly per step."""

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self.T = 0.1
        self.u = 0.0
        self.y = 0.0
        self.register_variable(Real("T", causality=Fmi2Causality.parameter, variability=Fmi2Variability.fixed))
        self.register_variable(Real("u", causality=Fmi2Causality.input))
        self.register_variable(Real("y", causality=Fmi2Causality.output))

    def do_step(self, current_time, step_size):
        self.y += (self.u - self.y) * (1.0 - math.exp(-step_size / self.T))
        return True
