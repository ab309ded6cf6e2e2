"""SSP 1.0 archives (System Structure and Parameterization): ``read`` turns one into a scenario,
``write`` packs a resolved scenario and its FMUs into one, ``format`` holds what both share
(namespaces, annotation types, schema validation)."""

from pathlib import Path

__all__ = ["is_ssp"]


def is_ssp(path: "str | Path") -> bool:
    """Whether ``path`` names an SSP archive or an SSD file (by its extension). Here, not in
    ``read``: asking costs no import of lxml."""
    return Path(path).suffix.lower() in (".ssp", ".ssd")
