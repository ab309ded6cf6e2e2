"""The guide's DC motor from connected parts, with the armature inductance (deltafmi.models.circuit_parts)."""
from deltafmi.component import Parameter
from deltafmi.models.circuit_parts import Inductor, MotorNetwork
from deltafmi.runtime.equations import connect

__all__ = ["DCMotorCircuitL"]


class DCMotorCircuitL(MotorNetwork):
    """The same motor with the armature inductance L in series: the current is a second state."""

    model_name = "DCMotorCircuitL"
    L = Parameter(1e-3, unit="H", min=0.0, description="Armature inductance")
    inductor = Inductor(L=L)

    def equations(self):
        return [connect(self.resistor.n, self.inductor.p), connect(self.inductor.n, self.emf.p)]
