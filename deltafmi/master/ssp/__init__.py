"""SSP 1.0 archives (System Structure and Parameterization): ``read`` turns one into a scenario,
``write`` packs a resolved scenario and its FMUs into one, ``format`` holds what both share
(namespaces, annotation types, schema validation)."""

__all__: list[str] = []
