"""What the packaged components (``fmu_src/``) share: declarations that several FMUs make alike.

Each module here joins :mod:`deltafmi.component` (how a component declares its variables) with
:mod:`deltafmi.mechanics` (the physics), which know nothing of each other. An FMU carries the
modules its component imports, so they must stay importable inside the FMU: no imports here.
"""
