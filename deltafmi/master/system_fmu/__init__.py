"""A scenario as one Co-Simulation FMU: the master runs inside it (:mod:`.inside`), stepping the
scenario's units for each ``doStep``; :mod:`.source` writes the component and the files it carries.
``deltafmi export-fmu`` (deltafmi.apps) builds it with the builder."""

__all__: list[str] = []
