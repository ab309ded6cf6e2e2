"""Parts of electrical and rotational networks for equation models (Modelica.Electrical.Analog and
Modelica.Mechanics.Rotational, the few that a DC motor needs), connected with ``connect``; and
the network both DC motor models extend (a partial model)."""
from deltafmi.component import Experiment, Input, Output, Parameter
from deltafmi.runtime.equations import Connector, EquationComponent, Flow, Model, Potential, Real, connect, der

__all__ = ["Inductor", "MotorNetwork"]


class Pin(Connector):
    """An electrical pin: potential v, current i into the part."""

    v = Potential(unit="V")
    i = Flow(unit="A")


class Flange(Connector):
    """A rotational flange: angle phi, torque tau on the part."""

    phi = Potential(unit="rad")
    tau = Flow(unit="N.m")


class TwoPin(Model):
    """A part between pins p and n: voltage drop v = p.v - n.v, current i from p through to n."""

    p, n = Pin(), Pin()
    v = Real(unit="V")
    i = Real(unit="A")

    def equations(self):
        return [self.v == self.p.v - self.n.v, 0.0 == self.p.i + self.n.i, self.i == self.p.i]


class Ground(Model):
    """Zero potential."""

    p = Pin()

    def equations(self):
        return [self.p.v == 0.0]


class Resistor(TwoPin):
    """v = R i."""

    R = Parameter(1.0, unit="Ohm")

    def equations(self):
        return [self.v == self.R * self.i]


class Inductor(TwoPin):
    """v = L di/dt."""

    L = Parameter(1e-3, unit="H")

    def equations(self):
        return [self.v == self.L * der(self.i)]


class SignalVoltage(TwoPin):
    """A voltage source whose voltage is the signal u."""

    u = Real(unit="V")

    def equations(self):
        return [self.v == self.u]


class EMF(TwoPin):
    """Electro-mechanical conversion: v = ke w, the flange's torque kt i (drives the rotor)."""

    kt = Parameter(0.05, unit="N.m/A")
    ke = Parameter(0.05, unit="V.s/rad")
    flange = Flange()
    w = Real(unit="rad/s")

    def equations(self):
        return [self.w == der(self.flange.phi), self.v == self.ke * self.w, self.flange.tau == -self.kt * self.i]


class Inertia(Model):
    """J dw/dt = the torques on its two flanges."""

    J = Parameter(1e-4, unit="kg.m2")
    flange_a, flange_b = Flange(), Flange()
    phi = Real(unit="rad")
    w = Real(unit="rad/s")

    def equations(self):
        return [self.flange_a.phi == self.phi, self.flange_b.phi == self.phi, self.w == der(self.phi),
                self.J * der(self.w) == self.flange_a.tau + self.flange_b.tau]


class Damper(Model):
    """Viscous torque d (w_b - w_a) between two flanges."""

    d = Parameter(1e-4, unit="N.m.s/rad")
    flange_a, flange_b = Flange(), Flange()
    tau = Real(unit="N.m")

    def equations(self):
        return [self.tau == self.d * der(self.flange_b.phi - self.flange_a.phi), self.flange_b.tau == self.tau,
                self.flange_a.tau == -self.tau]


class Fixed(Model):
    """A flange held at angle 0."""

    flange = Flange()

    def equations(self):
        return [self.flange.phi == 0.0]


class MotorNetwork(EquationComponent):
    """What both motors share: source, resistor, EMF, rotor, friction and their connections."""

    partial = True
    default_experiment = Experiment(start=0.0, stop=0.5, step=1e-3, tolerance=1e-8)

    R = Parameter(1.0, unit="Ohm", min=0.0, description="Armature resistance")
    kt = Parameter(0.05, unit="N.m/A", min=0.0, description="Torque constant")
    ke = Parameter(0.05, unit="V.s/rad", min=0.0, description="Back-EMF constant")
    J = Parameter(1e-4, unit="kg.m2", min=0.0, description="Rotor inertia")
    b = Parameter(1e-4, unit="N.m.s/rad", min=0.0, description="Viscous friction")
    voltage = Input(1.5, unit="V", description="Voltage across the motor's terminals")
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
