"""Test component for ending the simulation from a component that steps itself."""
from deltafmi.component import Component, Experiment, Output, Parameter


class Stopper(Component):
    """Counts its Co-Simulation steps and ends the simulation in the step that reaches n_max."""

    default_experiment = Experiment(stop=1.0, step=0.1)
    n_max = Parameter(3, type=int, description="Steps after which the component ends the simulation")
    n = Output(0, type=int, description="Steps taken")

    def do_step(self, t, h):
        self.n += 1
        if self.n >= self.n_max:
            self.terminate_simulation(f"{self.n} steps taken")
