"""Parameter studies on Dask: many runs of one scenario, with metrics per run.

``spec`` reads study files, ``plan`` checks them against the scenario and its FMUs, ``cases``
generates the cases (grid, zip, Monte Carlo), ``metrics`` computes one number per run,
``pool`` keeps FMUs loaded and resets them, ``runner`` runs one case in-process, ``worker`` is the
Dask side (plugin and task), ``driver`` the client side, ``store`` the result files, ``plot``
the figures, ``commands`` the CLI (``deltafmi sweep``, ``plot-study``, ``study-case``).
"""

__all__: list[str] = []
