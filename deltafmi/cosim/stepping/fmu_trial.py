"""One trial fmi2Instantiate of an FMU, the check that needs its binary (``deltafmi validate``)."""
from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Optional

from .unit_base import instantiation_reason, logger_callbacks


def instantiation_problem(fmu: Path) -> Optional[str]:
    """Load the FMU's binary and instantiate it once (Co-Simulation if it offers it, else Model
    Exchange), then free it: what went wrong, with what the FMU logged, or None.

    This is what catches a GUID its binary refuses in an FMU of any origin (fmpy's validation
    reads only the XML)."""
    import fmpy
    from fmpy.fmi2 import FMU2Model, FMU2Slave

    md = fmpy.read_model_description(str(fmu), validate=False)
    interface = md.coSimulation or md.modelExchange
    if interface is None:
        return "it offers neither Co-Simulation nor Model Exchange"
    messages: list = []
    callbacks = logger_callbacks(lambda status, category, text: messages.append((status, category, text)))
    with tempfile.TemporaryDirectory(prefix="deltafmi-validate-") as folder:
        unzipped = fmpy.extract(str(fmu), unzipdir=folder)
        try:
            instance = (FMU2Slave if md.coSimulation else FMU2Model)(
                guid=md.guid, unzipDirectory=unzipped, modelIdentifier=interface.modelIdentifier,
                instanceName="validate")
        except Exception as exc:  # noqa: BLE001 - fmpy raises plain exceptions
            return f"its binary does not load: {exc}"
        try:
            instance.instantiate(callbacks=callbacks)
        except Exception:  # noqa: BLE001 - fmpy raises a plain Exception when fmi2Instantiate returns NULL
            return f"fmi2Instantiate failed: {instantiation_reason(messages)}"
        instance.freeInstance()
    return None
