"""The packaged model library: one component per module, each built into an FMU on demand.

``from deltafmi.models import DeltaRobot`` imports the module that defines it; a scenario names it
``source: deltafmi.models:DeltaRobot`` and the CLI ``deltafmi build DeltaRobot``. The modules
without a component here (``robot_parameters``, ``contact_plant``, ``wrist_declarations``,
``wrist_parameters``, and the equation model parts ``circuit_parts``, ``delta_arm``) hold declarations
that several models share.

An FMU carries this package's ``__init__`` when its model imports a shared module: it must stay
free of imports (the table below names modules; nothing is loaded until a name is asked for).
"""

#: component class name -> the module of this package that defines it
MODELS = {
    "AssemblyController": "assembly_controller",
    "BouncingBall": "bouncing_ball",
    "BouncingBallEquations": "bouncing_ball_equations",
    "BouncingBallReinit": "bouncing_ball_reinit",
    "BouncingBallRestitution": "bouncing_ball_restitution",
    "BallOnTableEquations": "ball_on_table_equations",
    "BoxOnTable": "box_on_table",
    "CartesianPendulum": "cartesian_pendulum",
    "ContactEstimator": "contact_estimator",
    "DCMotorCircuit": "dc_motor_circuit",
    "DCMotorCircuitL": "dc_motor_circuit_l",
    "DeltaController": "delta_controller",
    "DeltaRobot": "delta_robot",
    "DeltaRobotBox": "delta_robot_box",
    "DeltaRobotContact": "delta_robot_contact",
    "DeltaRobotEquations": "delta_robot_equations",
    "DeltaWrist": "delta_wrist",
    "DeltaWristPeg": "delta_wrist_peg",
    "InsertionMpc": "insertion_mpc",
    "MpcController": "mpc_controller",
    "NewtonsCradle": "newtons_cradle",
    "Oscillator": "oscillator",
    "PegEstimator": "peg_estimator",
    "TactileSensor": "tactile_sensor",
    "TargetFollower": "target_follower",
    "Trajectory": "trajectory",
}

#: the models that run only in Python, no compiled kernels (their cost per sample is in their
#: docstrings): an MPC's QP (OSQP, which needs scipy)
PYTHON_ONLY = ("InsertionMpc", "MpcController")

#: module -> the shipped data files (scenarios/) its FMU carries in resources/ when built
#: with none given: the MPCs' linear models, made by tools/make_mpc_model.py and
#: ``python -m deltafmi.apps.insertion_mpc_model``
RESOURCES = {
    "insertion_mpc": ("peg_in_hole_mpc_model.npz",),
    "mpc_controller": ("mpc_press_model.npz",),
}

__all__ = sorted(MODELS)


def __getattr__(name: str) -> object:
    module = MODELS.get(name)
    if module is None:
        raise AttributeError(f"module 'deltafmi.models' has no attribute '{name}'")
    import importlib

    return getattr(importlib.import_module(f"{__name__}.{module}"), name)


def __dir__() -> list:
    return sorted(set(globals()) | set(MODELS))
