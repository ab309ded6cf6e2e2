"""Delta robot with a tool touching a plane: a thin component over deltafmi.physics.delta.contact."""
from deltafmi.component import Experiment, Input, Output, Parameter, State
from deltafmi.physics.contact import CompliantMaterial
from deltafmi.physics.friction import FrictionParams
from deltafmi.physics.delta.contact import Plane, ToolPlaneSystem, make_robot_contact, robot_start_state
from deltafmi.physics.delta.contact_kernels import ToolPlane, plane_derivatives, plane_indicators, plane_outputs
from deltafmi.models.contact_plant import RobotContactPlant, contact_kernels

__all__ = ["DeltaRobotContact"]


class DeltaRobotContact(RobotContactPlant):
    """RL5 delta robot whose tool touches a rigid plane: the robot's DAE plus a unilateral contact.

    The DeltaRobot plant (nine joint angles, loop closures solved at every evaluation) with a tool
    fixed to the travelling plate, its tip at `tool` from the plate centre, above a plane through
    (0, 0, surface_height) with normal surface_normal. The gap h = n.(tip - plane point) >= 0 is one
    constraint of the FREE / COLLISION / CONTACT machine: an impact is a compliant collision that
    rebounds with `restitution` (effective mass frozen at the impact: the wrist's inertia along n
    with the loops closed); a rebound slower than capture_speed under load is captured into CONTACT,
    a spring-damper (contact_stiffness, contact_damping) that lets go when its force turns
    negative. The contact force acts on the wrist along n, as the external force f does. The robot
    starts at z0 moving at zd0 (loops closed). Modes: 0 FREE, 1 COLLISION, 2 CONTACT.

    In CONTACT the plane has Coulomb friction (mu_s, mu_k, viscous; all 0: frictionless): the tool
    sticks (a tangential constraint whose multiplier is the friction force) while that force is
    inside the static cone mu_s fn, slips with the force mu_k fn + viscous |v_t| against its
    velocity, and sticks again where its velocity reaches zero with the sticking force inside the
    cone. friction_mode: 0 no friction force, 1 STICK, 2 SLIP. Collisions are frictionless.
    """

    model_name = "DeltaRobotContact"
    direct_feedthrough = {"lambda": ["u", "f"]}
    default_experiment = Experiment(start=0.0, stop=1.0, step=1e-3, tolerance=1e-8)
    n_event_indicators = 2

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
    surface_height = Parameter(-1.15, unit="m", description="Height at which the plane crosses the robot axis")
    surface_normal = Parameter([0.0, 0.0, 1.0], description="Plane normal, pointing towards the robot")
    contact_stiffness = Parameter(2e5, unit="N/m", min=0.0,
                                  description="Contact spring (tool, pads and surface in series)")
    contact_damping = Parameter(2e3, unit="N.s/m", min=0.0, description="Contact damper in CONTACT")
    restitution = Parameter(0.5, min=0.01, max=1.0, description="Coefficient of restitution of an impact")
    capture_speed = Parameter(0.05, unit="m/s", min=0.0,
                              description="Rebound speed below which a loaded impact stays in CONTACT")
    mu_s = Parameter(0.0, min=0.0, description="Static Coulomb friction coefficient of the tool on the plane")
    mu_k = Parameter(0.0, min=0.0, description="Kinetic Coulomb friction coefficient (<= mu_s)")
    viscous = Parameter(0.0, unit="N.s/m", min=0.0, description="Viscous friction coefficient while slipping")

    q = State([0.0] * 9, unit="rad", initial="calculated", nominal=0.01,
              description="Joint angles per arm: servo q_i1, forearm polar q_i2, azimuth q_i3")
    v = State([0.0] * 9, unit="rad/s", initial="calculated", nominal=0.01, description="Joint rates dq/dt")

    u = Input([0.0] * 3, unit="N.m", description="Servo torques")
    f = Input([0.0] * 3, unit="N", description="External force on the wrist, world frame")

    y = Output(shape=3, unit="rad", description="Servo angles q_i1 (measured)")
    yd = Output(shape=3, unit="rad/s", description="Servo rates")
    z = Output(shape=3, unit="m", description="Wrist (plate centre) position")
    zd = Output(shape=3, unit="m/s", description="Wrist velocity, Jv v")
    tip = Output(shape=3, unit="m", description="Tool tip position")
    lam = Output(shape=6, unit="N", name="lambda",
                 description="Loop-closure forces (world), as in DeltaRobot")
    residual = Output(unit="m", description="Loop-closure residual |h(q)| (Euclidean norm)")
    energy = Output(unit="J", description="Kinetic + potential + elastic contact energy")
    mode = Output(0, type=int, description="Contact mode: 0 FREE, 1 COLLISION, 2 CONTACT")
    normal_force = Output(shape=3, unit="N", description="Force of the plane on the tool, world frame")
    fn = Output(unit="N", description="Normal contact force (magnitude, >= 0)")
    gap = Output(unit="m", description="Signed distance of the tool tip from the plane")
    penetration = Output(unit="m", description="Depth of the tool tip below the plane (0 when apart)")
    friction_force = Output(shape=3, unit="N",
                            description="Tangential (friction) force of the plane on the tool, world frame")
    friction_mode = Output(0, type=int, description="Friction: 0 no friction force, 1 STICK, 2 SLIP")

    #: what the FMU's C layer computes itself between events, and the methods too (contact_plant)
    native = contact_kernels(plane_derivatives, plane_indicators, plane_outputs, ToolPlane,
                             returns=("y", "yd", "z", "zd", "tip", "lam", "residual", "energy", "normal_force", "fn",
                                      "gap", "penetration", "friction_force"))

    def build_system(self, t: float) -> ToolPlaneSystem:
        params = self.robot_params()
        plane = Plane(self.surface_height, tuple(self.surface_normal))
        material = CompliantMaterial(self.contact_stiffness, self.contact_damping, self.restitution)
        friction = FrictionParams(self.mu_s, self.mu_k, self.viscous)
        system = make_robot_contact(params, plane, material, tuple(self.tool), self.pole, self.capture_speed,
                                    friction if any(c > 0.0 for c in friction) else None)
        x0 = robot_start_state(params, self.z0, self.zd0)
        start_gap = float(system.model.gaps(x0[:9])[0])
        if start_gap < 0.0:
            tip = ", ".join(f"{float(a) + float(b):.6g}" for a, b in zip(self.z0, self.tool))
            raise ValueError(f"the tool tip starts {-start_gap:.6g} m below the surface (tip at ({tip}) m "
                             f"from z0 + tool; the plane crosses the axis at surface_height = "
                             f"{float(self.surface_height):.6g} m): start it above")
        self.q, self.v = x0[:9], x0[9:]
        return system

    def needs_projection(self, t: float) -> bool:
        """Also a step event when the friction mode no longer holds without its indicator having
        crossed zero: an input jump (the f input, a controller's torques) that put it past its
        limit at a communication point, which importers that read the indicators after setting
        the inputs cannot see as a sign change (the event then runs after that integrator step)."""
        return super().needs_projection(t) or self._friction_overdue(t)

    def _friction_overdue(self, t: float) -> bool:
        system = self.system
        if system is None or system.friction is None or self._contact is None or self._contact.friction.mode == 0:
            return False
        return float(self.event_indicators(t)[1]) <= 0.0

    def publish_modes(self, modes) -> None:
        """The one contact's mode as the scalar ``mode``, its friction's as ``friction_mode`` (and
        the kernels' state, as the base)."""
        super().publish_modes(int(modes[0]))
        self.friction_mode = self.system.friction_mode
