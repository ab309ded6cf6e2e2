"""A linear model file of ``deltafmi linearize -o`` read with numpy alone (what an MPC FMU needs of it)."""
from __future__ import annotations

from typing import NamedTuple, Optional

import os

import numpy as np

__all__ = ["LinearModelFile", "find_model_file"]


class LinearModelFile(NamedTuple):
    """What the MPC takes of a ``deltafmi linearize -o`` model file (the .npz of
    deltafmi.master.linearize.linear_model.LinearModel.save: x' = A x + B u, y = C x + D u about
    x0, u0, y0), read with numpy alone: an FMU carries no co-simulation code (it needs fmpy)."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    inputs: list
    outputs: list
    u0: np.ndarray
    y0: np.ndarray
    sample_time: Optional[float]

    @property
    def discrete(self) -> bool:
        """True for a sampled model (the MPC refuses it: it discretises the continuous one)."""
        return self.sample_time is not None

    @classmethod
    def read(cls, path: str) -> "LinearModelFile":
        """The model in ``path``; ValueError naming the file when it is not such a model."""
        try:
            with np.load(path) as data:
                ts = float(data["Ts"])
                a, b = ("Phi", "Gamma") if ts > 0.0 else ("A", "B")
                return cls(data[a], data[b], data["C"], [str(n) for n in data["inputs"]],
                           [str(n) for n in data["outputs"]], data["u0"], data["y0"], ts if ts > 0.0 else None)
        except (OSError, ValueError, KeyError) as exc:
            raise ValueError(f"linear_model {path!r}: not a model file of `deltafmi linearize -o` ({exc})") from None


def find_model_file(name: str, resources_dir: str, how: str) -> str:
    """The model file ``name`` (``.npz`` optional) of a component: the FMU's own copy in its
    resources folder first (a scenario's ``resources:`` or ``deltafmi build --resource`` put it
    there; a file of that name in the working directory is not the one it was built with), then
    the working directory. ValueError naming both places and ``how`` to make one when absent."""
    candidates = [os.path.join(resources_dir, name), name]
    for candidate in candidates + [c + ".npz" for c in candidates if not c.endswith(".npz")]:
        if os.path.isfile(candidate):
            return candidate
    raise ValueError(f"linear_model {name!r} not found (looked in the FMU's resources {resources_dir!r} "
                     f"and the working directory): make it with {how}")
