"""The talk's Modelica bouncing ball (``myBouncingBall``) as an FMU, statement for statement."""
import numpy as np

from deltafmi.component import Component, Experiment, Kernel, NativeKernels, Output, Parameter, State
from deltafmi.physics.contact_problems.ball_kernels import (ModelicaBall, modelica_derivatives, modelica_indicators,
                                                      modelica_outputs)
from deltafmi.physics.contact_problems.bouncing_ball import ModelicaBouncingBall

__all__ = ["BouncingBall"]


class BouncingBall(Component):
    """Modelica myBouncingBall from the talk: contact states 0 free / 1 contact law / 2 released.

    In state 1 the floor force solves 0 = h'' + a1 h' + a0 h + a2 h^3; transitions follow the
    model's algorithm with edge() semantics. With a1 = 0 each bounce gains energy (the talk's
    "does not conserve energy" slide).
    """

    model_name = "BouncingBall"
    default_experiment = Experiment(start=0.0, stop=3.0, step=1e-3, tolerance=1e-8)
    n_event_indicators = 3
    cs_options = dict(rtol=1e-9, atol=1e-11)

    g = Parameter(9.81, unit="m/s2", description="Gravity")
    m = Parameter(1.0, unit="kg", description="Mass of the ball", min=0.0)
    a0 = Parameter(100.0, description="Contact law stiffness a0 (1/s2)")
    a1 = Parameter(20.0, description="Contact law damping a1 (1/s)")
    a2 = Parameter(1e6, description="Contact law cubic stiffening a2 (1/(m2.s2))")
    linFlag = Parameter(False, description="Always apply the contact equation (linear model)")
    q = State(1.0, unit="m", description="Height of the ball (h = q)")
    v = State(0.0, unit="m/s", description="Vertical velocity")
    contact = Output(0, type=int, description="Contact state: 0 free, 1 contact law, 2 released")
    f = Output(unit="N", description="Force of the floor on the ball, f = contact*lambda")
    lam = Output(unit="N", description="Multiplier lambda of the contact equation")
    energy = Output(unit="J", description="Mechanical energy m v^2/2 + m g q")

    #: the continuous part runs as generated C in the FMU; the algorithm (events) stays in Python
    #: and sets ``contact``, which the kernels read
    native = NativeKernels(
        derivatives=Kernel(modelica_derivatives, "_params", "contact", "states"),
        event_indicators=Kernel(modelica_indicators, "_params", "contact", "states"),
        outputs=Kernel(modelica_outputs, "_params", "contact", "states", returns=("lam", "f", "energy")),
        attributes={"_params": ModelicaBall})

    def setup(self) -> None:
        self.ball = None
        self._params = None

    def initialize(self, t: float) -> None:
        self.ball = ModelicaBouncingBall(g=self.g, m=self.m, a0=self.a0, a1=self.a1, a2=self.a2,
                                         lin_flag=self.linFlag)
        self._params = self.ball.params
        self.ball.initialize(t, np.array(self.states))
        self.contact = self.ball.contact

    def _model(self) -> ModelicaBouncingBall:
        if self.ball is None:
            self.initialize(0.0)
        return self.ball

    def derivatives(self, t: float) -> list:
        self._model()
        return modelica_derivatives(self._params, int(self.contact), self.states.tolist())

    def event_indicators(self, t: float) -> list:
        self._model()
        return modelica_indicators(self._params, int(self.contact), self.states.tolist())

    def update(self, t: float) -> bool:
        self._model().update(t, np.array(self.states))
        self.contact = self.ball.contact
        return False

    def outputs(self, t: float) -> None:
        self._model()
        self.lam, self.f, self.energy = modelica_outputs(self._params, int(self.contact), self.states.tolist())
