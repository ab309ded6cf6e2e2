"""Linear models for control design (``deltafmi linearize``).

``fmu`` linearizes one Model Exchange FMU at an operating point (A, B, C, D), optionally at an
``equilibrium`` it solves for first; ``closed_loop`` linearizes a scenario's closed loop over one
communication step (Phi, Gamma, C, D), with a ``realization`` of each Co-Simulation unit from its
pulse responses; ``linear_model`` holds the result (poles, damping, files); ``commands`` the CLI.
"""

__all__: list[str] = []
