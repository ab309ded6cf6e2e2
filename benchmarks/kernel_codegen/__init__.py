"""Issue 26: C code generated from the kernels' Python source (our own translator over the AST).

:mod:`.kernel_types` (what a value is in C), :mod:`.codegen` (the translator), :mod:`.build`
(compile and call from Python), :mod:`.flagship` (the flagship's kernels and their C driver);
measured by ``benchmarks/kernel_compilers.py`` and ``benchmarks/kernel_codegen_flagship.py``.
"""
from .codegen import generate, signature_of
from .kernel_types import B, D, I, CodegenError, Entry, Obj, Opt, Tup, Vec, named, record

__all__ = ["B", "CodegenError", "D", "Entry", "I", "Obj", "Opt", "Tup", "Vec", "generate", "named", "record",
           "signature_of"]
