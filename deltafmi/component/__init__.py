"""The Python side of a component: declarations, the Component base class, the FMI instance
runtime and the modelDescription.xml writer. Nothing here knows about any particular model."""
from .base import Component
from .clocks import Clock
from .hybrid import HybridSystemComponent
from .native import Kernel, NativeKernels
from .sampled import SampledComponent
from .variables import Experiment, Input, Output, Parameter, State

__all__ = ["Clock", "Component", "HybridSystemComponent", "Experiment", "Input", "Kernel", "NativeKernels", "Output",
           "Parameter", "SampledComponent", "State"]
