"""deltafmi: Python components as FMI 2.0 FMUs, and a co-simulation master for them.

This top-level module is deliberately empty of imports: it is bundled into every FMU's
``resources/`` together with the modules of :mod:`deltafmi.component` and :mod:`deltafmi.mechanics`
that the FMU's model reaches (``deltafmi.export.reach``), and must stay cheap to import inside an
embedded interpreter.
"""

__version__ = "0.1.0"
