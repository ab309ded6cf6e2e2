"""C generated from components' Python kernels (issue 26): our own translator over the AST.

:mod:`.kernel_types` (what a value is in C), :mod:`.translate` (the translator), :mod:`.build`
(compile a unit and call it from Python, for tests and benchmarks), :mod:`.component_kernels`
(a component's declared kernels and the glue between them and the FMU's value buffers).
"""
from .kernel_types import B, D, I, CodegenError, Entry, Obj, Opt, Tup, Vec, named, record
from .translate import generate, signature_of

__all__ = ["B", "CodegenError", "D", "Entry", "I", "Obj", "Opt", "Tup", "Vec", "generate", "named", "record",
           "signature_of", "use_compiled_functions"]


def use_compiled_functions(component_class: type) -> bool:
    """See :func:`.component_kernels.use_compiled_functions`."""
    from .component_kernels import use_compiled_functions as use

    return use(component_class)
