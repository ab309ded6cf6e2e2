"""The delta robot as a numpy library: plant, controller, trajectories.

This package re-exports the plant: the parameters and frame (:mod:`.params`), the kinematics in
the seed talk's nine joint angles (:mod:`.kinematics`) and the stabilised DAE dynamics
(:mod:`.dynamics`). Its other modules: the feedback-linearising control law (:mod:`.control_law`)
and the sampled controller around it (:mod:`.control`), wrist reference trajectories
(:mod:`.trajectory`), the robot in contact: its tool against a plane (:mod:`.contact`) and against
a movable box on a table (:mod:`.box`), and a two-pad tactile sensor (:mod:`.tactile`). Conventions (frame, psi, branches, RL5 defaults) follow DESIGN.md.
Joint vectors are arm-major: q = [q11, q12, q13, q21, q22, q23, q31, q32, q33].
"""

from .dynamics import (PlantEvaluation, accelerations, coriolis, energy, evaluate_plant, gravity, plant_outputs,
                       holding_torque, loop_residual, mass_matrix, project_to_constraints,
                       state_derivative)
from .kinematics import (arm_bias, arm_jacobian, arm_psi, constraint, constraint_bias,
                         constraint_jacobian, forward_kinematics, inverse_kinematics, joint_rates,
                         stretched_height, virtual_jacobian, wrist_position, wrist_velocity)
from .params import ARM_ROTATIONS, R2, R3, RL5, DeltaParams, rot_z

__all__ = [
    "DeltaParams", "RL5", "R2", "R3", "ARM_ROTATIONS", "rot_z",
    "arm_psi", "arm_jacobian", "arm_bias", "stretched_height",
    "inverse_kinematics", "joint_rates", "forward_kinematics", "wrist_position", "wrist_velocity",
    "constraint", "constraint_jacobian", "constraint_bias", "virtual_jacobian",
    "mass_matrix", "coriolis", "gravity", "accelerations", "state_derivative", "energy", "holding_torque",
    "PlantEvaluation", "evaluate_plant", "plant_outputs", "loop_residual", "project_to_constraints",
]
