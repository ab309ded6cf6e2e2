"""The FMU runtime: everything that goes inside an FMU. The Component base class and its
declarations, the FMI instance, the CVODE binding, logging, the boot code and the C runtime sources
(``native/``). It imports the standard library and numpy only; nothing here knows any model.

The names below load their modules when first asked for (PEP 562), all at once: a process that
needs only :mod:`.errors` (the root of every deltafmi error, which the master's modules import)
does not pay for the component machinery. An FMU's boot code asks for them while the FMU's own copy
of the runtime is the one in ``sys.modules``; ``deltafmi.builder.reach`` follows the import
statements in :func:`__getattr__`, so every FMU carries these modules.
"""
from typing import Any, List

__all__ = ["Clock", "Component", "HybridSystemComponent", "Experiment", "Function", "Input", "Kernel", "NativeKernels",
           "Output", "Parameter", "SampledComponent", "State"]


def __getattr__(name: str) -> Any:
    if name not in __all__:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    from .base import Component
    from .clocks import Clock
    from .hybrid import HybridSystemComponent
    from .native import Function, Kernel, NativeKernels
    from .sampled import SampledComponent
    from .variables import Experiment, Input, Output, Parameter, State

    globals().update(Clock=Clock, Component=Component, HybridSystemComponent=HybridSystemComponent,
                     Experiment=Experiment, Function=Function, Input=Input, Kernel=Kernel,
                     NativeKernels=NativeKernels, Output=Output, Parameter=Parameter,
                     SampledComponent=SampledComponent, State=State)
    return globals()[name]


def __dir__() -> List[str]:
    return sorted(set(globals()) | set(__all__))
