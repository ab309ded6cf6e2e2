"""A Component whose dynamics come from a hybrid-system object (e.g. a multi-mode contact model).

The object provides ``initialize(t, x)``, ``derivatives(t, x)``, ``event_indicators(t, x)``,
``update(t, x)`` and ``modes``; the component builds it from its parameters, feeds it the inputs,
and publishes its modes as outputs. Nothing here knows what the system models.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from .base import Component

__all__ = ["HybridSystemComponent"]


class HybridSystemComponent(Component):
    """Base class: implement :meth:`build_system`; optionally :meth:`apply_inputs`."""

    def setup(self) -> None:
        self.system = None

    def build_system(self, t: float) -> Any:
        """Create the system from the parameters (may also set calculated start states)."""
        raise NotImplementedError

    def apply_inputs(self, system: Any) -> None:
        """Pass the current inputs to the system (default: no inputs)."""

    def publish_modes(self, modes: Sequence[int]) -> None:
        """Copy the system's modes to outputs (default: an Integer array output ``mode``)."""
        self.mode = modes

    def initialize(self, t: float) -> None:
        self.system = self.build_system(t)
        self.apply_inputs(self.system)
        self.system.initialize(t, np.array(self.states))
        self.publish_modes(self.system.modes)

    def current_system(self) -> Any:
        """The system with the current inputs applied (built on first use)."""
        if self.system is None:
            self.initialize(0.0)
        self.apply_inputs(self.system)
        return self.system

    def derivatives(self, t: float) -> np.ndarray:
        return self.current_system().derivatives(t, np.array(self.states))

    def event_indicators(self, t: float) -> np.ndarray:
        return self.current_system().event_indicators(t, np.array(self.states))

    def update(self, t: float) -> bool:
        self.current_system().update(t, np.array(self.states))
        self.publish_modes(self.system.modes)
        return False
