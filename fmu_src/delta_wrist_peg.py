"""The 6-DOF plant with its peg in a chamfered hole: DeltaWrist plus the fixture's contact wrench
(a thin component over deltafmi.physics.peg)."""
from deltafmi.component import Kernel, NativeKernels, Output, Parameter
from deltafmi.physics.delta.params import DeltaParams
from deltafmi.physics.delta_wrist.dynamics import project_state
from deltafmi.physics.delta_wrist.params import WristMount
from deltafmi.physics.peg import Hole, Peg, PegContact, plant
from deltafmi.physics.wrist.kernels import WristConstants
from deltafmi.models.delta_wrist import ARGUMENTS, OUTPUTS, DeltaWrist
from deltafmi.models.wrist_declarations import hole_parameters
from deltafmi.models.wrist_parameters import peg_scene_of

__all__ = ["DeltaWristPeg"]

#: the peg's outputs, in the order plant.plant_outputs returns them after DeltaWrist's
PEG_OUTPUTS = ("depth", "contact_force", "contact_moment", "ft_sensor", "lateral_misalignment",
               "angular_misalignment", "max_normal_force", "active_contacts")
#: the contact kernels' extra arguments (attributes built from the parameters at initialization)
PEG_ARGUMENTS = ("_hole", "_peg", "_contact")


class DeltaWristPeg(hole_parameters("true"), DeltaWrist):
    """DeltaWrist whose tool, a cylindrical peg (tool_radius, tool_length; its bottom face centre
    the tool tip), meets a fixture with a chamfered hole. hole_position and hole_tilt are the TRUE
    hole (a controller has its own nominal). The fixture's wrench on the peg (penalty springs and
    dampers at 32 points of the peg's rim and at the hole's two ring edges, regularised Coulomb
    friction: deltafmi/physics/peg/contact.py) is added to the inputs f and moment.
    success latches to 1 at the event where depth reaches target_depth.
    """

    model_name = "DeltaWristPeg"
    n_event_indicators = 1
    direct_feedthrough = {"lam": ["u", "tau", "f", "moment"]}

    target_depth = Parameter(0.02, unit="m", description="Insertion depth at which success latches to 1")

    depth = Output(unit="m", description="Insertion depth: tool tip below the hole's top plane, along the hole axis")
    contact_force = Output(shape=3, unit="N", description="Total contact force on the peg, world frame")
    contact_moment = Output(shape=3, unit="N.m", description="Moment of the contact forces about the tool tip, world")
    ft_sensor = Output(shape=6, unit="1",
                       description="Wrist F/T sensor: contact force (N) and moment about the tip (N m) in the tool "
                       "frame; peg weight and inertia compensated (zero in free motion)")
    lateral_misalignment = Output(unit="m", description="Distance from the tool tip to the hole axis")
    angular_misalignment = Output(unit="rad", description="Angle between the peg axis and the hole axis")
    max_normal_force = Output(unit="N", description="Largest normal force of one contact point")
    active_contacts = Output(unit="1", description="Number of contact points in contact")
    success = Output(0, type=int, description="1 once depth has reached target_depth (latched), else 0")

    native = NativeKernels(
        derivatives=Kernel(plant.state_derivative, *ARGUMENTS, *PEG_ARGUMENTS),
        event_indicators=Kernel(plant.event_indicators, "_plant", "_wrist", "_mount", "states", "_hole", "success",
                                "target_depth"),
        outputs=Kernel(plant.plant_outputs, *ARGUMENTS, *PEG_ARGUMENTS, returns=OUTPUTS + PEG_OUTPUTS),
        project=Kernel(project_state, "_plant", "_wrist", "states"),
        attributes={"_plant": DeltaParams, "_wrist": WristConstants, "_mount": WristMount, "_hole": Hole,
                    "_peg": Peg, "_contact": PegContact})

    def setup(self) -> None:
        super().setup()
        self._hole = None  # Hole, Peg and PegContact, built from the parameters at initialization
        self._peg = None
        self._contact = None

    def initialize(self, t: float) -> None:
        self._hole, self._peg, self._contact = peg_scene_of(self)
        super().initialize(t)
        self.success = 0
        self.update(t)

    def _contact_args(self) -> tuple:
        return self._hole, self._peg, self._contact

    def derivatives(self, t: float) -> list:
        return plant.state_derivative(self._plant, self._wrist, self._mount, self.states, self.u, self.tau, self.f,
                                      self.moment, self.pole, *self._contact_args())

    def event_indicators(self, t: float) -> list:
        return list(plant.event_indicators(self._plant, self._wrist, self._mount, self.states, self._hole,
                                           int(self.success), self.target_depth))

    def update(self, t: float) -> bool:
        """Latch success once the depth has reached the target (1 nm under it: where the importer
        locates the crossing)."""
        if not self.success:
            depth = plant.plant_wrench(self._plant, self._wrist, self._mount, self.states,
                                       *self._contact_args()).depth
            self.success = int(depth >= self.target_depth - 1e-9)
        return False

    def outputs(self, t: float) -> None:
        values = plant.plant_outputs(self._plant, self._wrist, self._mount, self.states, self.u, self.tau, self.f,
                                     self.moment, self.pole, *self._contact_args())
        self.write_reals([v for item in values for v in (item if isinstance(item, tuple) else (item,))],
                         *OUTPUTS, *PEG_OUTPUTS)
