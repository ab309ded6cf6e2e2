"""Test component for Enumeration variables: a gearbox whose gear is an enum.IntEnum."""
import enum

from deltafmi.component import Component, Experiment, Input, Output, Parameter


class Gear(enum.IntEnum):
    """The gears (FMI Enumeration items)."""

    LOW = 1
    HIGH = 2
    REVERSE = 3


RATIOS = {Gear.LOW: 1.0, Gear.HIGH: 3.0, Gear.REVERSE: -1.0}


class Gearbox(Component):
    """y = ratio(gear) u, with the gear an Enumeration parameter the model reads as a Gear."""

    default_experiment = Experiment(stop=1.0, step=0.1)
    gear = Parameter(Gear.LOW, description="Selected gear")
    u = Input(2.0, unit="rad/s", description="Input speed")
    y = Output(unit="rad/s", description="Output speed")
    engaged = Output(type=Gear, description="The gear engaged (an Enumeration output)")
    direct_feedthrough = {"y": ["u"], "engaged": []}

    def outputs(self, t):
        if not isinstance(self.gear, Gear):
            raise TypeError(f"gear reads as {type(self.gear).__name__}, not Gear")
        self.y = RATIOS[self.gear] * self.u
        self.engaged = self.gear
