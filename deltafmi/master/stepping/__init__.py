"""Running a resolved system: ``master`` instantiates, initializes and steps its units.

``units`` (Co-Simulation, fmi2DoStep) and ``me_integrator`` (Model Exchange, CVODE or
``explicit_rk``) are the units, on the shared ``unit_base``; ``jacobians`` their partial
derivatives; ``loops`` solves algebraic loops, ``adaptive`` steps with error control and
rollback, ``native_loop`` runs plain fixed steps in C (``native/``), ``stop_signals`` turns
Ctrl-C and SIGTERM into a clean stop between steps.
"""

__all__: list[str] = []
