"""The compiled value access of ``_values.c`` (bundled in every FMU), or its pure-Python stand-ins.

:class:`ValueHolder` is the base of :class:`~deltafmi.runtime.Component` and
:class:`ValueDescriptor` the base of every variable declaration. Compiled, a declaration reads and
writes its scalar in the component's buffers in C; the stand-ins here do the same through the
declaration's Python accessors. Both behave identically; only the cost differs.
"""
from __future__ import annotations

from typing import Any, Callable, Optional

__all__ = ["ValueDescriptor", "ValueHolder"]

try:
    from ._values import ValueDescriptor, ValueHolder
    COMPILED = True
except ImportError:  # a source checkout, or another Python than the one that built the FMU
    COMPILED = False

    class ValueHolder:  # type: ignore[no-redef]
        """Base of Component (the compiled one holds the buffers' addresses)."""

        __slots__ = ()

        def _bind_buffers(self, real: Any, ints: Any) -> None:
            """Nothing to bind: the Python accessors find the buffers themselves."""

    class ValueDescriptor(property):  # type: ignore[no-redef]
        """Base of Variable: a property on the Python accessors."""

        def _install(self, kind: int, offset: int, span: slice, fget: Callable,
                     fset: Optional[Callable]) -> None:
            """Use ``fget`` and ``fset`` (kind, offset and span serve the compiled fast paths)."""
            property.__init__(self, fget, fset)
