"""Clock declarations: a component's sample period as an FMI 3.0 periodic time-based input Clock.

``sample = Clock(period="sample_period")`` on a sampled component tells an FMI 3.0 importer when
the component must be sampled: at ``t_start + k * period``. FMI 2.0 builds ignore clocks; FMI 3.0
builds declare ``<Clock causality="input" intervalVariability=...>`` after ``time`` (value
references ``time + 1 ...`` in declaration order) and keep the time events, so an importer that
ignores the clock gets the same results. ``period`` names a real Parameter (a ``fixed`` Clock whose
interval the importer reads with fmi3GetIntervalDecimal) or is a number of seconds (a ``constant``
Clock with ``intervalDecimal`` in modelDescription.xml).
"""
from __future__ import annotations

import math
from typing import Any, Optional, Union

__all__ = ["Clock", "check_clock", "clock_driven"]


class Clock:
    """A periodic time-based input Clock: the component is sampled every ``period`` seconds from
    the start time (shift 0).

    ``period`` is the name of a real, non-tunable :class:`~deltafmi.runtime.Parameter` in seconds
    (the Clock's interval follows that parameter) or a positive number of seconds (constant).
    """

    def __init__(self, period: Union[str, float], *, description: str = "",
                 name: Optional[str] = None) -> None:
        if isinstance(period, bool) or not isinstance(period, (str, int, float)):
            raise TypeError(f"Clock period must be a Parameter name or a number of seconds, got {period!r}")
        if not isinstance(period, str) and not (math.isfinite(period) and period > 0.0):
            raise ValueError(f"Clock period must be > 0 s, got {period!r}")
        self.period: Union[str, float] = period if isinstance(period, str) else float(period)
        self.description = description
        self.name = ""
        self.fmi_name = name

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name
        self.fmi_name = self.fmi_name or name

    @property
    def constant(self) -> bool:
        """Whether the interval is a number (``intervalVariability="constant"``), not a Parameter."""
        return not isinstance(self.period, str)

    def __repr__(self) -> str:
        return f"Clock(period={self.period!r})"


def check_clock(cls: type, clock: Clock, declarations: dict[str, Any]) -> None:
    """A Clock's period must name a real, non-tunable Parameter in seconds; else a clear error."""
    if clock.constant:
        return
    where = f"{cls.__qualname__}.{clock.name}"
    decl = declarations.get(clock.period)
    if decl is None or getattr(decl, "causality", None) != "parameter":
        raise ValueError(f"{where}: Clock period {clock.period!r} is not a Parameter of {cls.__qualname__}")
    if decl.type is not float or decl.shape is not None:
        raise ValueError(f"{where}: Clock period {clock.period!r} must be a real scalar Parameter")
    if decl.variability != "fixed":
        raise ValueError(f"{where}: Clock period {clock.period!r} must be a fixed (not tunable) Parameter: "
                         "a fixed Clock's interval cannot change after initialization")
    if decl.unit not in ("", "s"):
        raise ValueError(f"{where}: Clock period {clock.period!r} has unit {decl.unit!r}; a Clock interval is in s")


def clock_driven(cls: Any) -> bool:
    """A clocked component without continuous states or event indicators: its only events are its
    Clocks' ticks. Its FMI 3.0 FMU has Scheduled Execution (fmi3ActivateModelPartition runs what a
    tick does). In Co-Simulation Event Mode the importer activates the Clocks (fmi3SetClock in
    Event Mode), so fmi3DoStep reports no event and never returns early; without Event Mode it
    samples inside fmi3DoStep, and in Model Exchange the ticks are also time events, for
    importers that ignore Clocks."""
    layout = cls._layout
    return bool(layout.n_clocks and not layout.nx and not cls.n_event_indicators)
