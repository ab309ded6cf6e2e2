"""The FMU runtime: everything that goes inside an FMU. The Component base class and its
declarations, the FMI instance, the CVODE binding, logging, the boot code and the C runtime sources
(``native/``). It imports the standard library and numpy only; nothing here knows any model."""
from .base import Component
from .clocks import Clock
from .hybrid import HybridSystemComponent
from .native import Function, Kernel, NativeKernels
from .sampled import SampledComponent
from .variables import Experiment, Input, Output, Parameter, State

__all__ = ["Clock", "Component", "HybridSystemComponent", "Experiment", "Function", "Input", "Kernel", "NativeKernels",
           "Output", "Parameter", "SampledComponent", "State"]
