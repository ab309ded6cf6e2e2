"""The packaged model library: one component per module, each built into an FMU on demand.

``from deltafmi.models import DeltaRobot`` imports the module that defines it; a scenario names it
``source: deltafmi.models:DeltaRobot`` and the CLI ``deltafmi build DeltaRobot``. The modules
without a component here (``robot_parameters``, ``contact_plant``) hold declarations that several
models share.

An FMU carries this package's ``__init__`` when its model imports a shared module: it must stay
free of imports (the table below names modules; nothing is loaded until a name is asked for).
"""

#: component class name -> the module of this package that defines it
MODELS = {
    "BouncingBall": "bouncing_ball",
    "BouncingBallRestitution": "bouncing_ball_restitution",
    "BoxOnTable": "box_on_table",
    "DeltaController": "delta_controller",
    "DeltaRobot": "delta_robot",
    "DeltaRobotBox": "delta_robot_box",
    "DeltaRobotContact": "delta_robot_contact",
    "NewtonsCradle": "newtons_cradle",
    "Oscillator": "oscillator",
    "TactileSensor": "tactile_sensor",
    "TargetFollower": "target_follower",
    "Trajectory": "trajectory",
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
