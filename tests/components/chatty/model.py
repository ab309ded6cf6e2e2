"""Test component for the FMI logger: it logs at every level, warns, and ends the simulation itself."""
import logging
import warnings

from deltafmi.component import Component, Experiment, Output, Parameter, State

log = logging.getLogger(__name__)


class Chatty(Component):
    """x' = -x / T; says something at every logging level once, warns once, and ends the simulation
    at t = t_end (a time event) through Component.terminate_simulation."""

    default_experiment = Experiment(stop=2.0, step=0.1, tolerance=1e-8)
    T = Parameter(1.0, unit="s", description="Time constant")
    t_end = Parameter(0.55, unit="s", description="Time at which the component ends the simulation")
    x = State(1.0, description="Decaying state")
    y = Output(description="x")

    def setup(self):
        self.said = False
        log.info("setup: the model is loaded")

    def initialize(self, t):
        if not self.said:  # initialization mode may evaluate several times
            self.said = True
            log.debug("debug record from initialize")
            self.logger.info("info record: T = %g s", self.T)
            log.warning("warning record from initialize")
            warnings.warn("a warnings.warn from initialize", UserWarning)
            log.error("error record from initialize (the run goes on)")
            logging.getLogger("some.library").warning("a library's warning")
            self.log("info through Component.log")

    def derivatives(self, t):
        return [-self.x / self.T]

    def outputs(self, t):
        self.y = self.x

    def next_time_event(self, t):
        return self.t_end if t < self.t_end else None

    def update(self, t):
        if t >= self.t_end:
            self.terminate_simulation(f"t_end = {self.t_end:g} s reached")
