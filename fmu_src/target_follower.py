"""Target follower FMU: a thin sampled component over deltafmi.physics.delta.follower."""
from deltafmi.component import Clock, Component, Experiment, Input, Kernel, NativeKernels, Output, Parameter
from deltafmi.physics.delta.follower import (FollowerSettings, FollowerState, follower_outputs, follower_step,
                                               follower_update, initial_state)
from deltafmi.physics.delta.trajectory import Workspace

__all__ = ["TargetFollower"]

_WORKSPACE = Workspace()


class TargetFollower(Component):
    """Wrist reference r, rd, rdd that follows an operator's target (a joystick, a UDP stream)
    within the trajectory generator's limits.

    The target is clamped to the nominal workspace (r <= 0.5 m, -1.2 <= z <= -0.75 m); the
    reference approaches it critically damped with bandwidth wn (r'' = wn^2 (target - r) - 2 wn r'),
    its speed limited to v_max and its acceleration to a_max (vector norms; near a far target the
    speed also to sqrt(a_max |target - r|), so that it stops without overshoot). Sampled every
    sample_period from the start time: the sample at t_k reads the target and advances r, rd
    exactly to t_k + sample_period with it held (deltafmi.physics.delta.follower documents the
    law); rdd is the law's acceleration there. Co-Simulation: doStep(t, h) takes the samples due in
    [t, t + h) with the target at t, so with h = sample_period it ends with the reference at t + h.
    Model Exchange and FMI 3.0 Clock ticks: the sample at t_k, its outputs held until t_{k+1} (the
    reference at t_{k+1}: one sample ahead, as a sampled controller's torque). It starts at rest
    at r0. status bits: 1 target clamped, 2 speed limited, 4 acceleration limited.
    """

    model_name = "TargetFollower"
    default_experiment = Experiment(start=0.0, stop=2.0, step=1e-3, tolerance=1e-6)

    wn = Parameter(10.0, unit="rad/s", min=0.0, description="Bandwidth of the critically damped approach")
    v_max = Parameter(0.5, unit="m/s", min=0.0, description="Speed limit (norm of rd)")
    a_max = Parameter(5.0, unit="m/s2", min=0.0, description="Acceleration limit (norm of rdd)")
    r0 = Parameter([0.0, 0.0, -1.0], unit="m", description="Start position (at rest)")
    sample_period = Parameter(1e-3, unit="s", min=0.0, description="Time between samples")
    #: FMI 3.0: the sample instants t_start + k * sample_period as a periodic input Clock
    sample = Clock(period="sample_period", description="Sample instants: t_start + k * sample_period")

    #: the default (a target away from r0) makes the default experiment show a limited approach
    target = Input([0.2, 0.1, -0.9], unit="m", description="Where the operator wants the wrist")

    r = Output([0.0, 0.0, -1.0], shape=3, unit="m", variability="discrete", description="Reference wrist position")
    rd = Output(shape=3, unit="m/s", variability="discrete", description="Reference wrist velocity")
    rdd = Output(shape=3, unit="m/s2", variability="discrete", description="Reference wrist acceleration")
    status = Output(0, type=int, description="Status bits: 1 target clamped, 2 speed limited, 4 acceleration limited")

    native = NativeKernels(
        step=Kernel(follower_step, "_settings", "_state", "_t0", "_k", "t", "h", "target",
                    updates=("_state", "_k"), returns=("r", "rd", "rdd", "status")),
        update=Kernel(follower_update, "_settings", "_state", "_t0", "_k", "t", "target",
                      updates=("_state", "_k"), returns=("r", "rd", "rdd", "status")),
        attributes={"_settings": FollowerSettings, "_state": FollowerState, "_t0": float, "_k": int})

    def setup(self) -> None:
        self._settings = self._state = None
        self._t0 = 0.0
        self._k = 0          # index of the next sample instant

    def initialize(self, t: float) -> None:
        for name in ("wn", "v_max", "a_max", "sample_period"):
            if not getattr(self, name) > 0.0:
                raise ValueError(f"{name} must be > 0, got {getattr(self, name)}")
        r0 = tuple(float(c) for c in self.r0)
        reason = _WORKSPACE.violation(r0)
        if reason is not None:
            raise ValueError(f"r0 = {r0} {reason}: the follower must start inside the nominal workspace")
        w = _WORKSPACE
        self._settings = FollowerSettings(float(self.wn), float(self.v_max), float(self.a_max),
                                          float(self.sample_period), w.r_max, w.z_min, w.z_max)
        self._state = initial_state(self._settings, r0, self._target())
        self._t0, self._k = t, 0
        self._publish(follower_outputs(self._settings, self._state))

    def _target(self) -> tuple:
        x, y, z = self.read_reals("target")
        return x, y, z

    def _publish(self, outputs: tuple) -> None:
        r, rd, rdd, status = outputs
        self.write_reals((*r, *rd, *rdd), "r", "rd", "rdd")
        self.status = status

    def update(self, t: float) -> None:
        self._state, self._k, _, *outputs = follower_update(self._settings, self._state, self._t0, self._k, t,
                                                            self._target())
        self._publish(outputs)

    def next_time_event(self, t: float) -> float:
        return self._t0 + self._k * self.sample_period

    def do_step(self, t: float, h: float) -> None:
        self._state, self._k, *outputs = follower_step(self._settings, self._state, self._t0, self._k, t, h,
                                                       self._target())
        self._publish(outputs)
