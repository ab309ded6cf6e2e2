"""One trial instantiation of an FMU (fmi2Instantiate, or FMI 3.0's fmi3Instantiate<Interface>),
the check that needs its binary (``deltafmi validate``)."""
from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Optional

from .unit_base import instantiation_reason, logger_callbacks

__all__ = ["instantiation_problem"]


def instantiation_problem(fmu: Path) -> Optional[str]:
    """Load the FMU's binary and instantiate it once (Co-Simulation if it offers it, else Model
    Exchange), then free it: what went wrong, with what the FMU logged, or None.

    This is what catches a GUID its binary refuses in an FMU of any origin (fmpy's validation
    reads only the XML)."""
    import fmpy
    from fmpy.fmi2 import FMU2Model, FMU2Slave
    from fmpy.fmi3 import FMU3Model, FMU3Slave

    md = fmpy.read_model_description(str(fmu), validate=False)
    interface = md.coSimulation or md.modelExchange
    if interface is None:
        return "it offers neither Co-Simulation nor Model Exchange"
    fmi3 = md.fmiVersion.startswith("3")
    messages: list = []

    def record(status: int, category: str, text: str) -> None:
        messages.append((status, category, text))

    with tempfile.TemporaryDirectory(prefix="deltafmi-validate-") as folder:
        unzipped = fmpy.extract(str(fmu), unzipdir=folder)
        kind = ((FMU3Slave, FMU3Model) if fmi3 else (FMU2Slave, FMU2Model))[0 if md.coSimulation else 1]
        try:
            instance = kind(guid=md.guid, unzipDirectory=unzipped, modelIdentifier=interface.modelIdentifier,
                            instanceName="validate")
        except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions
            return f"its binary does not load: {exc}"
        try:
            if fmi3:
                instance.instantiate(logMessage=lambda env, status, category, text: record(
                    status, (category or b"").decode("utf-8", "replace"), (text or b"").decode("utf-8", "replace")))
            else:
                instance.instantiate(callbacks=logger_callbacks(record))
        except Exception:  # noqa: BLE001 - fmpy raises a plain Exception when the instantiation returns NULL
            call = f"fmi3Instantiate{'CoSimulation' if md.coSimulation else 'ModelExchange'}" if fmi3 \
                else "fmi2Instantiate"
            return f"{call} failed: {instantiation_reason(messages)}"
        instance.freeInstance()
    return None
