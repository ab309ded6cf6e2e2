"""Test component for compiled kernels (issue 26): a driven damped oscillator whose derivatives and
outputs run as generated C in its FMU, with a Python path that counts its own calls."""
from dataclasses import dataclass
from typing import NamedTuple, Sequence

from deltafmi.component import Component, Experiment, Input, Kernel, NativeKernels, Output, Parameter, State


@dataclass(frozen=True)
class Coefficients:
    omega: float
    zeta: float


class Gains(NamedTuple):
    gain: float
    offset: float


def oscillator_derivatives(c: Coefficients, x: Sequence[float], u: float, limit: float) -> list[float]:
    """x'' + 2 zeta omega x' + omega^2 x = u, for |u| <= limit."""
    if abs(u) > limit:
        raise ValueError(f"input {u} is beyond the limit {limit}")
    return [x[1], u - 2.0 * c.zeta * c.omega * x[1] - c.omega ** 2 * x[0]]


def oscillator_outputs(g: Gains, x: Sequence[float], u: float) -> tuple[float, float, int, bool]:
    """y = gain x + offset, its rate, the sign of x as an int and as a bool."""
    sign = 1 if x[0] > 0.0 else (-1 if x[0] < 0.0 else 0)
    return g.gain * x[0] + g.offset, g.gain * x[1], sign, x[0] > 0.0


class CompiledOscillator(Component):
    """x'' + 2 zeta omega x' + omega^2 x = u; y = gain x + offset (kernels compiled to C)."""

    default_experiment = Experiment(stop=2.0, step=0.01, tolerance=1e-10)
    omega = Parameter(3.0, unit="rad/s", description="Natural frequency")
    zeta = Parameter(0.1, description="Damping ratio")
    gain = Parameter(2.0, description="Output gain")
    offset = Parameter(0.5, description="Output offset")
    limit = Parameter(10.0, description="Largest |u| the model accepts")
    x = State([1.0, 0.0], description="Position and velocity")
    u = Input(0.0, description="Force per unit mass")
    y = Output(description="gain x + offset")
    yd = Output(description="gain x'")
    sign = Output(0, type=int, description="sign of x")
    positive = Output(False, description="x > 0")
    python_calls = Output(0, type=int, description="Calls of the Python derivatives so far")

    native = NativeKernels(
        derivatives=Kernel(oscillator_derivatives, "_coefficients", "states", "u", "limit"),
        outputs=Kernel(oscillator_outputs, "_gains", "x", "u", returns=("y", "yd", "sign", "positive")),
        attributes={"_coefficients": Coefficients, "_gains": Gains})

    def setup(self) -> None:
        self._coefficients = self._gains = None
        self._calls = 0

    def initialize(self, t: float) -> None:
        self._coefficients = Coefficients(self.omega, self.zeta)
        self._gains = Gains(self.gain, self.offset)

    def derivatives(self, t: float) -> list:
        self._calls += 1
        return oscillator_derivatives(self._coefficients, self.x, self.u, self.limit)

    def outputs(self, t: float) -> None:
        self.y, self.yd, self.sign, self.positive = oscillator_outputs(self._gains, self.x, self.u)
        self.python_calls = self._calls
