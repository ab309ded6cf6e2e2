"""The co-simulation master: YAML or SSP scenarios of connected FMUs, run through fmpy.

``scenario`` reads scenario files and checks them against their FMUs into a runnable system,
``ssp`` reads and writes SSP 1.0 archives of the same, ``stepping`` runs a system (the master,
its Co-Simulation and Model Exchange units, integrators, algebraic loops), ``results`` writes
and reads result files and draws them, ``linearize`` turns an FMU or a closed loop into a
linear model; ``commands`` holds the CLI commands ``run``, ``validate``, ``export-ssp`` and
``plot``, which span them. This package talks to FMUs only through fmpy.
"""

__all__: list[str] = []
