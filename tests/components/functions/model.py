"""A damped oscillator whose Python methods call compiled functions (``NativeKernels(functions=...)``):
what tests/builder/test_native_functions.py builds and runs."""
import math
from dataclasses import dataclass
from typing import NamedTuple

from deltafmi.component import Component, Function, Input, NativeKernels, Output, Parameter, State


@dataclass(frozen=True)
class Spring:
    omega: float
    zeta: float


class Drive(NamedTuple):
    force: float
    scale: float


def rate(p: Spring, x, drive: Drive, steps: int):
    """x' of x'' + 2 zeta omega x' + omega^2 x = force * scale, by ``steps`` equal pieces summed
    (an int argument the C loops over)."""
    acceleration = 0.0
    for _ in range(steps):
        acceleration += (drive.force * drive.scale - 2.0 * p.zeta * p.omega * x[1] - p.omega * p.omega * x[0]) / steps
    return (x[1], acceleration)


def energy_parts(p: Spring, x):
    """((kinetic, potential), total, (x, x')): a nested result, flattened by the caller."""
    kinetic, potential = 0.5 * x[1] * x[1], 0.5 * p.omega * p.omega * x[0] * x[0]
    return ((kinetic, potential), kinetic + potential, [x[0], x[1]])


def root(value: float) -> float:
    if value < 0.0:
        raise ValueError(f"root of a negative number {value}")
    return math.sqrt(value)


class FunctionOscillator(Component):
    """x'' + 2 zeta omega x' + omega^2 x = u, x(0) = 1: its derivatives and outputs computed by
    compiled functions."""

    omega = Parameter(3.0)
    zeta = Parameter(0.1)
    x = State([1.0, 0.0])
    u = Input(0.0)
    energy = Output(0.0)
    amplitude = Output(0.0)
    compiled = Output(0, type=int, description="1 while the functions are the compiled ones")

    native = NativeKernels(functions={"rate": Function(rate, Spring, 2, Drive, int),
                                      "energy_parts": Function(energy_parts, Spring, 2),
                                      "root": Function(root, float)})

    def initialize(self, t):
        self._spring = Spring(float(self.omega), float(self.zeta))
        self._functions = self.native_functions  # kept, as an estimator keeps its kernels: in its FMU state

    def derivatives(self, t):
        return self._functions.rate(self._spring, self.x, Drive(float(self.u), 1.0), 3)

    def outputs(self, t):
        functions = getattr(self, "_functions", self.native_functions)  # before initialize
        parts = functions.energy_parts(self._spring, self.x)
        self.energy = parts[2]
        self.amplitude = functions.root(2.0 * parts[2]) / float(self.omega)
        self.compiled = int(functions.compiled)
