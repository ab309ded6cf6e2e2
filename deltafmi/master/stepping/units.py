"""The units a master steps: :func:`unit_for` picks the Co-Simulation :class:`CoSimulationUnit`
(fmpy ``FMU2Slave``, stepped with fmi2DoStep) or the Model Exchange unit of
:mod:`.me_integrator` for a component, or their FMI 3.0 counterparts of :mod:`.fmi3_units`.
What they share lives in :mod:`.unit_base`.
"""
from __future__ import annotations

from typing import Any, Optional

from fmpy.fmi1 import FMICallException
from fmpy.fmi2 import FMU2Slave, fmi2Discard, fmi2LastSuccessfulTime, fmi2Terminated

from ..scenario.system import ResolvedComponent
from .unit_base import TYPES, FmuFailure, Terminated, Unit, bare_function, new_bus

__all__ = ["TYPES", "CoSimulationUnit", "FmuFailure", "Terminated", "Unit", "new_bus", "unit_for"]


class CoSimulationUnit(Unit):
    """A Co-Simulation FMU stepped with fmi2DoStep."""

    interface = "CS"
    fmu_class = FMU2Slave

    def __init__(self, component: ResolvedComponent, unzip_dir: str, fmu: Any = None) -> None:
        super().__init__(component, unzip_dir, fmu)
        self._do_step = bare_function(self.fmu, "fmi2DoStep")
        self._handle = None
        self.no_prior_state = 1

    def instantiate(self, start: float, stop: float) -> None:
        super().instantiate(start, stop)
        self._handle = self.fmu.component

    def do_step(self, time: float, step: float) -> None:
        """fmi2DoStep; fmi2Discard with fmi2Terminated raises :class:`Terminated`, any other
        fmi2Discard (the FMU could not complete the step) is a failure."""
        try:
            self._do_step(self._handle, time, step, self.no_prior_state)
        except FMICallException as exc:
            self.step_failed(exc, time)

    def step_failed(self, exc: FMICallException, time: float) -> None:
        """Raise what a failed fmi2DoStep from ``time`` means: :class:`Terminated` or a failure."""
        if exc.status == fmi2Discard:
            reached = self._terminated_at(time)
            if reached is not None:
                raise Terminated(self.name, reached) from None
        raise self.failure(exc) from None

    def _terminated_at(self, time: float) -> Optional[float]:
        """After fmi2Discard: the time the FMU terminated at (fmi2LastSuccessfulTime, else the
        step's start ``time``), or None when it did not terminate."""
        try:
            if not self.fmu.getBooleanStatus(fmi2Terminated):
                return None
        except FMICallException:
            return None
        try:
            return float(self.fmu.getRealStatus(fmi2LastSuccessfulTime))
        except FMICallException:
            return time


def unit_for(component: ResolvedComponent, unzip_dir: str, fmu: Any = None) -> Unit:
    """The right unit class for the component's interface and FMI version (``fmu``: see :class:`Unit`)."""
    if component.info.fmi3:
        from .fmi3_units import CoSimulationUnit3, ModelExchangeUnit3  # late: it loads SUNDIALS
        return (CoSimulationUnit3 if component.interface == "CS" else ModelExchangeUnit3)(component, unzip_dir, fmu)
    if component.interface == "CS":
        return CoSimulationUnit(component, unzip_dir, fmu)
    from .me_integrator import ModelExchangeUnit  # late: it loads SUNDIALS
    return ModelExchangeUnit(component, unzip_dir, fmu)
