"""Prototype for issue 26 item 1, candidate (c): C code generated from a kernel module's AST.

See :mod:`.codegen` (the translator) and ``benchmarks/kernel_compilers.py`` (the measurement).
"""
from .codegen import CodegenError, Entry, Obj, Vec, generate

__all__ = ["CodegenError", "Entry", "Obj", "Vec", "generate"]
