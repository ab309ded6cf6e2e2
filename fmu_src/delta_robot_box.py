"""Delta robot pressing a movable box on a table: a thin component over deltafmi.physics.delta.box."""
import numpy as np

from deltafmi.component import Experiment, Input, Output, Parameter, State
from deltafmi.physics.contact import CompliantMaterial
from deltafmi.physics.delta.box import BoxTableSystem, make_robot_box_contact
from deltafmi.physics.delta.contact import robot_start_state
from deltafmi.physics.delta.contact_kernels import BoxTable, box_derivatives, box_indicators, box_outputs
from deltafmi.physics.contact_problems.box_on_table import BoxModel
from deltafmi.models.contact_plant import RobotContactPlant, contact_kernels

__all__ = ["DeltaRobotBox"]


class DeltaRobotBox(RobotContactPlant):
    """RL5 delta robot, a movable box and a table: the talk's cartoon with the robot's tool.

    The DeltaRobotContact plant plus a rigid box lying on the horizontal table (planar in the
    vertical x-z plane, long along y, frictionless: states x, height of its centre of mass above
    the table, rotation theta). Six contacts, each a FREE / COLLISION / CONTACT machine: 1 tool tip -
    table, 2 tool tip - box top face, 3-6 box corners (bottom-left, bottom-right, top-right,
    top-left) - table. The tool's contacts use contact_stiffness / contact_damping / restitution,
    the box's corners box_stiffness / box_damping / box_restitution. An impact's effective mass is
    the response of both bodies, the robot's with its loops closed. The box starts at rest, its
    lowest corner box_drop above the table, tilted by box_angle; the robot at z0 moving at zd0.
    Modes: 0 FREE, 1 COLLISION, 2 CONTACT.
    """

    model_name = "DeltaRobotBox"
    direct_feedthrough = {"lambda": ["u", "f"]}
    default_experiment = Experiment(start=0.0, stop=1.0, step=1e-3, tolerance=1e-8)
    n_event_indicators = 12

    pole = Parameter(5.0, unit="1/s", min=0.0,
                     description="Baumgarte pole p: hdd + 2 p hd + p^2 h = 0 stabilises the loops")
    loop_tolerance = Parameter(
        0.0, unit="m", min=0.0,
        description="Model Exchange: a step event projects onto the closed loops once |h| exceeds this "
        "after an integrator step; 0: never (Co-Simulation projects after every step)")
    z0 = Parameter([0.0, 0.0, -1.0], unit="m", description="Initial wrist (plate centre) position")
    zd0 = Parameter([0.0, 0.0, 0.0], unit="m/s", description="Initial wrist velocity")
    tool = Parameter([0.0, 0.0, -0.1], unit="m",
                     description="Tool tip relative to the plate centre (the plate only translates)")
    surface_height = Parameter(-1.25, unit="m", description="Height of the (horizontal) table")
    contact_stiffness = Parameter(2e5, unit="N/m", min=0.0, description="Tool contact spring (on the box and the table)")
    contact_damping = Parameter(2e3, unit="N.s/m", min=0.0, description="Tool contact damper in CONTACT")
    restitution = Parameter(0.5, min=0.01, max=1.0, description="Coefficient of restitution of the tool's impacts")
    box_mass = Parameter(2.0, unit="kg", min=0.0, description="Mass of the box")
    box_width = Parameter(0.2, unit="m", min=0.0, description="Width of the box (along x)")
    box_height = Parameter(0.1, unit="m", min=0.0, description="Height of the box")
    box_inertia = Parameter(0.0, unit="kg.m2", min=0.0,
                            description="Inertia of the box about its centre of mass (0: uniform plate)")
    box_x = Parameter(0.0, unit="m", description="Initial x of the box's centre")
    box_drop = Parameter(0.0, unit="m", min=0.0, description="Initial height of the box's lowest corner above the table")
    box_angle = Parameter(0.0, unit="rad", description="Initial rotation of the box about y")
    box_stiffness = Parameter(1e6, unit="N/m", min=0.0, description="Corner contact spring")
    box_damping = Parameter(4e3, unit="N.s/m", min=0.0, description="Corner contact damper in CONTACT")
    box_restitution = Parameter(0.3, min=0.01, max=1.0, description="Coefficient of restitution of the corners")
    capture_speed = Parameter(0.05, unit="m/s", min=0.0,
                              description="Rebound speed below which a loaded impact stays in CONTACT")

    q = State([0.0] * 9, unit="rad", initial="calculated", nominal=0.01,
              description="Joint angles per arm: servo q_i1, forearm polar q_i2, azimuth q_i3")
    # declared in this order so that the states are the contact system's [q, box, v, box_rate]
    box = State([0.0, 0.05, 0.0], initial="calculated", nominal=0.01,
                description="Box: x (m), height of its centre of mass above the table (m), rotation (rad)")
    v = State([0.0] * 9, unit="rad/s", initial="calculated", nominal=0.01, description="Joint rates dq/dt")
    box_rate = State([0.0, 0.0, 0.0], initial="calculated", nominal=0.01,
                     description="Box velocities: x (m/s), height (m/s), rotation (rad/s)")

    u = Input([0.0] * 3, unit="N.m", description="Servo torques")
    f = Input([0.0] * 3, unit="N", description="External force on the wrist, world frame")

    y = Output(shape=3, unit="rad", description="Servo angles q_i1 (measured)")
    yd = Output(shape=3, unit="rad/s", description="Servo rates")
    z = Output(shape=3, unit="m", description="Wrist (plate centre) position")
    zd = Output(shape=3, unit="m/s", description="Wrist velocity, Jv v")
    tip = Output(shape=3, unit="m", description="Tool tip position")
    lam = Output(shape=6, unit="N", name="lambda", description="Loop-closure forces (world), as in DeltaRobot")
    residual = Output(unit="m", description="Loop-closure residual |h(q)| (Euclidean norm)")
    energy = Output(unit="J", description="Kinetic + potential + elastic contact energy")
    mode = Output([0] * 6, type=int, description="Contact modes (tool-table, tool-box, corners 1-4): 0 FREE, 1 COLLISION, 2 CONTACT")
    fn = Output(shape=6, unit="N", description="Normal contact forces (>= 0), same order")
    gap = Output(shape=6, unit="m", description="Gaps, same order")
    penetration = Output(shape=6, unit="m", description="Penetrations (0 when apart), same order")
    normal_force = Output(shape=3, unit="N", description="Force of the table and the box on the tool, world frame")

    #: what the FMU's C layer computes itself between events, and the methods too (contact_plant)
    native = contact_kernels(box_derivatives, box_indicators, box_outputs, BoxTable,
                             returns=("y", "yd", "z", "zd", "tip", "lam", "residual", "energy", "fn", "gap",
                                      "penetration", "normal_force"))

    def build_system(self, t: float) -> BoxTableSystem:
        params = self.robot_params()
        box = BoxModel(self.box_mass, self.box_width, self.box_height,
                       self.box_inertia if self.box_inertia > 0.0 else None, g=self.g)
        system = make_robot_box_contact(
            params, self.surface_height, box,
            CompliantMaterial(self.contact_stiffness, self.contact_damping, self.restitution),
            CompliantMaterial(self.box_stiffness, self.box_damping, self.box_restitution),
            tuple(self.tool), self.pole, self.capture_speed)
        robot = robot_start_state(params, self.z0, self.zd0)
        lift = self.box_drop - float(np.min(box.rotated_corners(self.box_angle)[:, 1]))
        x = np.concatenate([robot[:9], [self.box_x, lift, self.box_angle]])
        if min(system.model.gaps(x)[:2]) < 0.0:
            raise ValueError(f"the tool tip starts inside the table or the box (z0 = "
                             f"{[float(c) for c in self.z0]}, tool = {[float(c) for c in self.tool]}, "
                             f"table at {float(self.surface_height):.6g} m, box top at "
                             f"{float(self.surface_height) + lift + self.box_height / 2:.6g} m): start it above")
        self.q, self.box, self.v, self.box_rate = robot[:9], x[9:], robot[9:], [0.0, 0.0, 0.0]
        return system

