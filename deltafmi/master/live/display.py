"""Whether a plot window can open here: what a ``plot:`` stream checks before it starts the scope."""
from __future__ import annotations

import os
from typing import Optional

__all__ = ["display_problem"]

_NON_INTERACTIVE = {"agg", "cairo", "pdf", "pgf", "ps", "svg", "template"}


def display_problem() -> Optional[str]:
    """Why the scope cannot open a window here, or None when it can."""
    if not (os.environ.get("DISPLAY") or os.environ.get("WAYLAND_DISPLAY")):
        return "no display (DISPLAY and WAYLAND_DISPLAY are unset)"
    import matplotlib
    backend = matplotlib.get_backend()
    if backend.lower() in _NON_INTERACTIVE:
        return f"matplotlib's backend {backend} draws no window (see MPLBACKEND)"
    return None
