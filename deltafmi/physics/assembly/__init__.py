"""Assembly control: 6-D impedance control of the delta robot with its spherical wrist and a
peg-in-hole insertion program (kernel float subset; numpy only in the set-up functions).

Modules: :mod:`.rotation` (3x3 rotations as 9 floats, logarithm map, SO(3) left Jacobian),
:mod:`.wrist_model` (the wrist's inverse dynamics on the moving plate and its load on the
plate), :mod:`.law` (the control law: why the delta's 3-D feedback linearisation with an inner
wrist loop, the closed-loop impedance, sampling, gimbal lock), :mod:`.program` (approach,
descent, bounded push), :mod:`.sampling` (one controller sample: the FMU's kernel).
"""

from .law import (STATUS_GIMBAL_DAMPED, STATUS_WRIST_SATURATED, AssemblyLaw, AssemblyOutput, ImpedanceGains, evaluate,
                  gains, make_assembly_law)
from .program import (PHASE_APPROACH, PHASE_DESCENT, PHASE_HOLD, InsertionProgram, ProgramReference, make_program,
                      reference)
from .sampling import AssemblySettings, AssemblyState, describe_status, initial_state, sample

__all__ = ["STATUS_GIMBAL_DAMPED", "STATUS_WRIST_SATURATED", "AssemblyLaw", "AssemblyOutput", "ImpedanceGains",
           "evaluate", "gains", "make_assembly_law", "PHASE_APPROACH", "PHASE_DESCENT", "PHASE_HOLD",
           "InsertionProgram", "ProgramReference", "make_program", "reference", "AssemblySettings", "AssemblyState",
           "describe_status", "initial_state", "sample"]
