"""The 6-DOF plant: the delta robot with the spherical wrist on its plate (numpy and float kernels, no FMI).

:mod:`.params` (the wrist's mount under the plate, a cylindrical peg tool, the wrist's parameters)
and :mod:`.dynamics` (the 24-state DAE as kernels the DeltaWrist FMU compiles to C: state
derivative, outputs, energy; projection onto the closed loops, start state by inverse kinematics,
holding torques). The wrist's own kernels are :mod:`deltafmi.physics.wrist.kernels`.
State x = [q (9 delta joints), qw (3 wrist joints), v (9), vw (3)].
"""

from .dynamics import (N_STATES, WristLoad, energy, holding_torques, loop_residual, plant_outputs,
                       project_to_constraints, start_state, state_derivative, wrist_load)
from .params import MOUNT, WristMount, peg_tool, wrist_params

__all__ = ["WristMount", "MOUNT", "peg_tool", "wrist_params", "N_STATES", "WristLoad", "wrist_load",
           "state_derivative", "plant_outputs", "energy", "loop_residual", "project_to_constraints",
           "start_state", "holding_torques"]
