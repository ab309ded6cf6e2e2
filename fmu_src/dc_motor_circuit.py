"""The components guide's DC motor built from connected parts (deltafmi.models.circuit_parts)."""
from deltafmi.models.circuit_parts import MotorNetwork
from deltafmi.runtime.equations import connect

__all__ = ["DCMotorCircuit"]


class DCMotorCircuit(MotorNetwork):
    """DC motor as a network: voltage source, armature resistance, EMF, rotor inertia, friction.

    The compiler finds J w' = kt i - b w with i = (V - ke w) / R from the connections: the guide's
    motor without its drive's current limit.
    """

    model_name = "DCMotorCircuit"
    direct_feedthrough = {"current": ["voltage"]}

    def equations(self):
        return [connect(self.resistor.n, self.emf.p)]
