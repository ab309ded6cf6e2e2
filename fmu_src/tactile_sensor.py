"""Two-pad tactile sensor under the tool: a thin component over deltafmi.physics.delta.tactile."""
import math

from deltafmi.component import Clock, Component, Experiment, Input, Kernel, NativeKernels, Output, Parameter, State
from deltafmi.physics.delta.tactile import (Axis, Readout, TactilePads, sensor_derivatives, sensor_forces,
                                             sensor_outputs)

__all__ = ["TactileSensor"]

#: the kernels' arguments before the states: the pads, the axis, the geometry and the load
_GEOMETRY = ("_pads", "_axis", "tip", "hole_centre", "fn", "hole_width")


class TactileSensor(Component):
    """Touch sensor of two elastic pads under the tool; their force difference measures the offset.

    Pads 1 and 2 sit at -pad_spacing/2 and +pad_spacing/2 from the tool tip along the horizontal
    unit vector `axis`, each pad_width long. The surface has a hole (a slot across the axis) of
    hole_width centred at hole_centre. The normal load fn (from the plant) splits over the pads in
    proportion to the pad length resting on solid surface (the tool only translates, so both pads
    compress alike): near the centre pad 1 - pad 2 = -fn * offset / (pad_width * phi0). The true
    pad forces pass a first-order lag of the sensor's bandwidth; every sample_period the lagged
    forces are read with seeded Gaussian noise and quantized. Outputs pad, difference and total are
    these readings; offset and compression are the true values.
    """

    model_name = "TactileSensor"
    default_experiment = Experiment(start=0.0, stop=1.0, step=1e-3, tolerance=1e-6)

    axis = Parameter([1.0, 0.0, 0.0], description="Horizontal direction of the pad axis (pad 1 -> pad 2)")
    hole_centre = Parameter([0.0, 0.0, -1.15], unit="m", description="Centre of the hole (its height is unused)")
    hole_width = Parameter(0.01, unit="m", min=0.0, description="Width of the hole along the axis (0: flat surface)")
    pad_spacing = Parameter(0.01, unit="m", min=0.0, description="Distance between the pad centres")
    pad_width = Parameter(0.004, unit="m", min=0.0, description="Length of each pad along the axis")
    pad_stiffness = Parameter(1e5, unit="N/m", min=0.0, description="Stiffness of one fully supported pad")
    bandwidth = Parameter(50.0, unit="Hz", min=0.0, description="First-order lag of the pad forces (-3 dB)")
    noise = Parameter(0.02, unit="N", min=0.0, description="Noise of each reading (rms)")
    seed = Parameter(1, type=int, min=0, description="Seed of the noise")
    quantization = Parameter(0.01, unit="N", min=0.0, description="Resolution of a reading (0: none)")
    sample_period = Parameter(1e-3, unit="s", min=0.0, description="Time between readings")
    #: FMI 3.0: the reading instants t_start + k * sample_period as a periodic input Clock
    sample = Clock(period="sample_period", description="Reading instants: t_start + k * sample_period")

    filtered = State([0.0, 0.0], unit="N", description="Pad forces after the sensor's lag")

    tip = Input([0.0, 0.0, -1.15], unit="m", description="Tool tip position (world)")
    fn = Input(0.0, unit="N", description="Normal contact force on the tool")

    pad = Output(shape=2, unit="N", variability="discrete", description="Pad force readings")
    difference = Output(unit="N", variability="discrete", description="Reading of pad 1 - pad 2")
    total = Output(unit="N", variability="discrete", description="Reading of pad 1 + pad 2")
    offset = Output(unit="m", description="True offset of the tool from the hole centre along the axis")
    compression = Output(unit="m", description="True pad compression")

    #: what the FMU's C layer computes itself (generated from the kernels the methods below call);
    #: the sampled readings (seeded noise, quantization) stay Python, in update()
    native = NativeKernels(
        derivatives=Kernel(sensor_derivatives, *_GEOMETRY, "bandwidth", "filtered"),
        outputs=Kernel(sensor_outputs, *_GEOMETRY, returns=("offset", "compression")),
        attributes={"_pads": TactilePads, "_axis": Axis})

    def setup(self) -> None:
        self._pads = None
        self._k = 0

    def initialize(self, t: float) -> None:
        if not (self.sample_period > 0.0 and self.bandwidth > 0.0):
            raise ValueError(f"sample_period ({self.sample_period} s) and bandwidth ({self.bandwidth} Hz) must be > 0")
        ax, ay = self.axis[0], self.axis[1]
        norm = math.hypot(ax, ay)
        if not norm > 0.0:
            raise ValueError(f"axis must have a horizontal component, got {list(self.axis)}")
        self._axis = Axis(ax / norm, ay / norm)
        self._pads = TactilePads(self.pad_spacing, self.pad_width, self.pad_stiffness)
        self._readout = Readout(self.noise, self.quantization, self.seed)
        self._t0, self._k = t, 0
        self.filtered = sensor_forces(*self._geometry())[:2]

    def _geometry(self) -> tuple:
        if self._pads is None:
            self.initialize(0.0)
        return self._pads, self._axis, self.tip, self.hole_centre, self.fn, self.hole_width

    def derivatives(self, t: float) -> list:
        return list(sensor_derivatives(*self._geometry(), self.bandwidth, self.filtered))

    def outputs(self, t: float) -> None:
        self.offset, self.compression = sensor_outputs(*self._geometry())

    def next_time_event(self, t: float) -> float:
        return self._t0 + self._k * self.sample_period

    def update(self, t: float) -> None:
        if t >= self.next_time_event(t) - 1e-9 * self.sample_period:
            p1 = self._readout.read(float(self.filtered[0]), self._k, 0)
            p2 = self._readout.read(float(self.filtered[1]), self._k, 1)
            self.pad, self.difference, self.total = [p1, p2], p1 - p2, p1 + p2
            self._k += 1
            while self.next_time_event(t) <= t:
                self._k += 1
