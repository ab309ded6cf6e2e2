"""The components guide's DC motor built from connected parts (deltafmi.models.circuit_parts)."""
from deltafmi.component import Experiment, Input, Output, Parameter
from deltafmi.models.circuit_parts import EMF, Damper, Fixed, Ground, Inductor, Inertia, Resistor, SignalVoltage
from deltafmi.runtime.equations import EquationComponent, connect


class _MotorNetwork(EquationComponent):
    """What both motors share: source, resistor, EMF, rotor, friction and their connections."""

    partial = True
    default_experiment = Experiment(start=0.0, stop=0.5, step=1e-3, tolerance=1e-8)

    R = Parameter(1.0, unit="Ohm", min=0.0, description="Armature resistance")
    kt = Parameter(0.05, unit="N.m/A", min=0.0, description="Torque constant")
    ke = Parameter(0.05, unit="V.s/rad", min=0.0, description="Back-EMF constant")
    J = Parameter(1e-4, unit="kg.m2", min=0.0, description="Rotor inertia")
    b = Parameter(1e-4, unit="N.m.s/rad", min=0.0, description="Viscous friction")
    voltage = Input(0.0, unit="V", description="Voltage command")
    speed = Output(unit="rad/s", description="Rotor speed")
    current = Output(unit="A", description="Armature current")

    source = SignalVoltage(u=voltage)
    resistor = Resistor(R=R)
    emf = EMF(kt=kt, ke=ke)
    rotor = Inertia(J=J)
    friction = Damper(d=b)
    ground, fixed = Ground(), Fixed()

    def equations(self):
        return [connect(self.source.p, self.resistor.p), connect(self.emf.n, self.source.n),
                connect(self.source.n, self.ground.p), connect(self.emf.flange, self.rotor.flange_a),
                connect(self.rotor.flange_b, self.friction.flange_a), connect(self.friction.flange_b, self.fixed.flange),
                self.speed == self.rotor.w, self.current == self.resistor.i]


class DCMotorCircuit(_MotorNetwork):
    """DC motor as a network: voltage source, armature resistance, EMF, rotor inertia, friction.

    The compiler finds J w' = kt i - b w with i = (V - ke w) / R from the connections: the guide's
    motor without its drive's current limit.
    """

    model_name = "DCMotorCircuit"
    direct_feedthrough = {"current": ["voltage"]}

    def equations(self):
        return [connect(self.resistor.n, self.emf.p)]


class DCMotorCircuitL(_MotorNetwork):
    """The same motor with the armature inductance L in series: the current is a second state."""

    model_name = "DCMotorCircuitL"
    L = Parameter(1e-3, unit="H", min=0.0, description="Armature inductance")
    inductor = Inductor(L=L)

    def equations(self):
        return [connect(self.resistor.n, self.inductor.p), connect(self.inductor.n, self.emf.p)]
