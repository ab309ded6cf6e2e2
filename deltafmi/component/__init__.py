"""What a component's source imports: the Component base class and its declarations.

``from deltafmi.component import Component, Parameter, State, ...`` is the public way to write a
model (the packaged models in ``fmu_src/`` do it too); the classes live in :mod:`deltafmi.runtime`,
the code that goes inside every FMU.
"""
from deltafmi.runtime import (Clock, Component, Experiment, Function, HybridSystemComponent, Input, Kernel,
                              NativeKernels, Output, Parameter, SampledComponent, State)

__all__ = ["Clock", "Component", "HybridSystemComponent", "Experiment", "Function", "Input", "Kernel", "NativeKernels",
           "Output", "Parameter", "SampledComponent", "State"]
