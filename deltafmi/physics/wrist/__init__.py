"""A 3-DOF direct-drive spherical wrist for the delta's travelling plate (numpy only, no FMI).

Modules: :mod:`.params` (links, rotors, tool; default a compact torque-motor wrist with a peg),
:mod:`.kinematics` (Z-X-Y axes through one centre O, tool frame, J_w and the tip Jacobian,
inverse orientation), :mod:`.dynamics` (M, C by Euler's law and by Christoffel symbols, g,
energy, angular momentum, the wrench on the base), :mod:`.singularity` (gimbal lock at
|q2| = pi/2: distance monitor, damped joint rates) and :mod:`.coupling` (the wrist's load on
the plate with its joints eliminated). Joint vectors q = [q1, q2, q3] (rad), tau (N m).

Plan for the 6-DOF plant (delta + wrist), in the DAE formulation of mechanics/delta/dynamics.py:

1. Coordinates: the delta's nine joint angles (with its six loop closures h(q) = 0, multipliers
   lam, Baumgarte pole p) plus the wrist's three, which add no constraint. The wrist centre is
   O = z(q) + d, z the plate centre (wrist_position) and d a constant mount offset (the plate
   only translates), so O's acceleration is the plate's, zdd = Jv vdot + Jvd v.
2. The wrist loads the plate with F = -Lambda zdd + f0 (coupling.plate_load): Lambda/3 joins
   each arm's plate share exactly as (mp + payload)/3 does (each arm block gains
   Ht_i^T (Lambda/3) Ht_i, exact on the manifold since all arm ends share zdd), and f0 enters as
   the external wrist force f through Jv^T, as today. The arm blocks then lose m23 = 0, so
   _arm_mass_inverse becomes a general symmetric 3x3 inverse; the 6x6 Schur complement on lam,
   the Baumgarte terms and project_to_constraints (same mass metric, blocks augmented) are
   unchanged. Cost: one 3x3 solve with the wrist's M per evaluation.
3. After the delta's solve gives vdot and zdd: qdd_w = accelerations(pw, qw, qdw, tau_w,
   base_accel=zdd), the same elimination run backwards (no iteration: it is exact).
4. Energy check (no damping): E = E_delta + 1/2 m |zd|^2 + zd . J_s qdw + T_w + m g O_z + V_w
   with E_delta the delta alone (without the wrist's mass) and V_w the wrist's potential about O;
   the tool tip in the world is O + tool_tip(q_w), its velocity zd + J_p qdw.
5. Inputs of the 6-DOF FMU: the three servo torques, the three wrist torques, a tool-tip force
   (tau_w += J_p^T f_tip, f_ext = f_tip); outputs: tool-frame pose, gimbal distance, lam.
"""

from .coupling import PlateLoad, plate_load
from .dynamics import (accelerations, angular_momentum, base_wrench, coriolis, coriolis_matrix, energy,
                       first_moment_jacobian, gravity, kinetic_energy, mass_matrix, mass_matrix_derivatives,
                       potential_energy, state_derivative, wrist_state)
from .kinematics import (angular_jacobian, inverse_kinematics, joint_axes, link_rotations, tip_jacobian,
                         tool_rotation, tool_tip)
from .params import WRIST, Body, Tool, WristParams, link_inertias
from .singularity import GimbalDistance, gimbal_distance, joint_rates

__all__ = [
    "Body", "Tool", "WristParams", "WRIST", "link_inertias",
    "link_rotations", "joint_axes", "angular_jacobian", "tool_rotation", "tool_tip", "tip_jacobian",
    "inverse_kinematics",
    "mass_matrix", "mass_matrix_derivatives", "coriolis", "coriolis_matrix", "gravity", "accelerations",
    "state_derivative", "kinetic_energy", "potential_energy", "energy", "angular_momentum",
    "first_moment_jacobian", "base_wrench", "wrist_state",
    "GimbalDistance", "gimbal_distance", "joint_rates", "PlateLoad", "plate_load",
]
