"""Scenario files, from YAML to a runnable system, and the checks on the way.

``spec`` reads a scenario (YAML -> ``scenario.schema.json`` -> :class:`~.spec.Scenario`) with the
help of ``yaml_lines`` (line numbers of every value) and ``schema_check`` (schema violations as
``file:line`` diagnostics, also used for study files); ``modelinfo`` reads what the master needs
from an FMU's modelDescription; ``resolve`` checks a scenario against its FMUs and resolves it
into a :class:`~.resolve.System`, with the stepping order and algebraic loops from ``graph``.
``overrides`` lays run options over a scenario (``run --set/--stop/--step/--tolerance``, the
Python API's values); ``fmu_scenario`` makes the scenario of one FMU run on its own;
``records`` makes the master's dataclasses (of a scenario, a system, a run), cheaper to define.
Nothing here steps an FMU.
"""

__all__: list[str] = []
