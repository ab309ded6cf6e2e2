"""The Python side of a component: declarations, the Component base class, the FMI instance
runtime and the modelDescription.xml writer. Nothing here knows about any particular model."""
from .base import Component
from .variables import Experiment, Input, Output, Parameter, State

__all__ = ["Component", "Experiment", "Input", "Output", "Parameter", "State"]
