"""Damped oscillator bouncing on a wall: the smallest model with state events and a time event."""
from deltafmi.component import Component, Experiment, Input, Kernel, NativeKernels, Output, Parameter, State

__all__ = ["Oscillator"]


# The kernels: plain float Python that ``deltafmi build`` also compiles to C for the FMU (its
# derivatives, CVODE's right-hand side and root function, the energy output); the methods below
# call them, so both paths give the same numbers. The wall impact and the force step stay in
# update() (Python, at events): the kernels take force_on as an argument.

def oscillator_derivatives(x: float, v: float, F: float, F_step: float, force_on: bool, m: float, k: float,
                           c: float) -> tuple[float, float]:
    """(x', v') of m x'' + c x' + k x = F + F_step [force_on]."""
    force = F + (F_step if force_on else 0.0)
    return v, (force - k * x - c * v) / m


def oscillator_energy(x: float, v: float, m: float, k: float) -> float:
    """Kinetic plus spring energy."""
    return 0.5 * m * v ** 2 + 0.5 * k * x ** 2


def wall_gap(x: float, wall: float) -> float:
    """The event indicator: the mass's height above the wall."""
    return x - wall


class Oscillator(Component):
    """Damped mass-spring oscillator that bounces on a wall and gets a force step at t_step.

    m x'' + c x' + k x = F + F_step [t >= t_step]; when x reaches the wall moving towards it,
    v -> -e v (state event). The force step is a time event. Closed-form solution between events.
    """

    default_experiment = Experiment(start=0.0, stop=4.0, step=1e-3, tolerance=1e-8)
    n_event_indicators = 1

    m = Parameter(1.0, unit="kg", description="Mass", min=0.0)
    k = Parameter(39.47841760435743, unit="N/m", description="Spring stiffness (1 Hz natural frequency)")
    c = Parameter(0.2, unit="N.s/m", description="Viscous damping")
    wall = Parameter(-0.5, unit="m", description="Wall position (the mass stays above it)")
    e = Parameter(0.8, description="Coefficient of restitution at the wall", min=0.0, max=1.0)
    t_step = Parameter(2.5, unit="s", description="Time of the force step")
    F_step = Parameter(5.0, unit="N", description="Force step amplitude")
    x = State(1.0, unit="m", description="Position")
    v = State(0.0, unit="m/s", description="Velocity")
    F = Input(0.0, unit="N", description="External force")
    energy = Output(unit="J", description="Kinetic plus spring energy")
    impacts = Output(0, type=int, description="Number of wall impacts so far")
    force_on = Output(False, type=bool, description="Force step applied")

    native = NativeKernels(
        derivatives=Kernel(oscillator_derivatives, "x", "v", "F", "F_step", "force_on", "m", "k", "c"),
        event_indicators=Kernel(wall_gap, "x", "wall"),
        outputs=Kernel(oscillator_energy, "x", "v", "m", "k", returns=("energy",)))

    def initialize(self, t: float) -> None:
        if not self.m > 0.0:
            raise ValueError(f"m must be > 0 (the mass divides the force), got {self.m}")

    def derivatives(self, t: float) -> list:
        return list(oscillator_derivatives(self.x, self.v, self.F, self.F_step, self.force_on, self.m, self.k, self.c))

    def outputs(self, t: float) -> None:
        self.energy = oscillator_energy(self.x, self.v, self.m, self.k)

    def event_indicators(self, t: float) -> list:
        return [wall_gap(self.x, self.wall)]

    def update(self, t: float) -> None:
        if not self.force_on and t >= self.t_step:
            self.force_on = True
        # the root is located to solver accuracy, so allow a hair above the wall
        if self.x - self.wall <= 1e-9 * max(1.0, abs(self.wall)) and self.v < 0.0:
            self.v = -self.e * self.v
            self.impacts += 1

    def next_time_event(self, t: float):
        return self.t_step if not self.force_on and t < self.t_step else None
