"""A linear(ized) model with named states, inputs and outputs: poles, damping, and files.

Continuous: x' = A x + B u, y = C x + D u. Discrete with sample time Ts:
x[k+1] = Phi x[k] + Gamma u[k], y[k] = C x[k] + D u[k]. Every vector is the deviation from the
operating point (x0, u0, y0) the model was taken at.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

import numpy as np
import scipy.io

from deltafmi.files import replaced_atomically

__all__ = ["LinearModel"]


@dataclass
class LinearModel:
    """A, B, C, D (``sample_time`` None) or Phi, Gamma, C, D (discrete) with names."""

    A: np.ndarray
    B: np.ndarray
    C: np.ndarray
    D: np.ndarray
    states: list[str]
    inputs: list[str]
    outputs: list[str]
    sample_time: Optional[float] = None
    time: float = 0.0
    x0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    u0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    y0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    source: str = ""
    notes: list[str] = field(default_factory=list)

    @property
    def discrete(self) -> bool:
        """True for a sampled (discrete-time) model."""
        return self.sample_time is not None

    def poles(self) -> np.ndarray:
        """Eigenvalues of A (or Phi), sorted by real part then imaginary part."""
        poles = np.linalg.eigvals(self.A) if self.A.size else np.zeros(0, dtype=complex)
        return poles[np.lexsort((poles.imag, poles.real))]

    def continuous_poles(self) -> np.ndarray:
        """The poles as points of the s-plane: log(z) / Ts for a discrete model (z = 0: -inf)."""
        poles = self.poles().astype(complex)
        if not self.discrete:
            return poles
        with np.errstate(divide="ignore"):
            return np.log(poles) / self.sample_time  # type: ignore[operator]

    def pole_table(self) -> list[str]:
        """One line per pole: value, damping ratio, natural frequency (rad/s and Hz)."""
        if self.discrete:
            lines = [f"{'pole z':>32}  {'|z|':>9}  {'damping':>9}  {'wn [rad/s]':>11}  {'f [Hz]':>10}"]
        else:
            lines = [f"{'pole s':>32}  {'damping':>9}  {'wn [rad/s]':>11}  {'f [Hz]':>10}"]
        for z, s in zip(self.poles(), self.continuous_poles()):
            wn = abs(s)
            damping = -s.real / wn if wn > 0 and math.isfinite(wn) else (1.0 if not math.isfinite(wn) else math.nan)
            text = f"{z.real:+.9g} {z.imag:+.9g}j"
            mag = f"  {abs(z):9.6f}" if self.discrete else ""
            lines.append(f"{text:>32}{mag}  {damping:9.4f}  {wn:11.5g}  {wn / (2 * math.pi):10.5g}")
        return lines

    def matrices(self) -> dict[str, np.ndarray]:
        """The four matrices by their usual names (Phi, Gamma for a discrete model)."""
        first = ("Phi", "Gamma") if self.discrete else ("A", "B")
        return {first[0]: self.A, first[1]: self.B, "C": self.C, "D": self.D}

    def save(self, path: Path) -> list[Path]:
        """Write ``<path>.npz`` (numpy) and ``<path>.mat`` (MATLAB, scipy.io); returns both paths."""
        base = Path(path)
        if base.suffix in (".npz", ".mat"):
            base = base.with_suffix("")
        content = dict(self.matrices(), states=np.array(self.states, dtype=object),
                       inputs=np.array(self.inputs, dtype=object), outputs=np.array(self.outputs, dtype=object),
                       Ts=np.array(self.sample_time if self.discrete else 0.0), time=np.array(self.time),
                       x0=self.x0, u0=self.u0, y0=self.y0, source=np.array(self.source))
        npz, mat = base.with_suffix(".npz"), base.with_suffix(".mat")
        # MATLAB strings are UTF-8: a file name that is not (bytes the OS allows) is shown with U+FFFD there
        shown = self.source.encode("utf-8", "surrogateescape").decode("utf-8", "replace")
        with replaced_atomically(npz) as part, open(part, "wb") as out:
            np.savez(out, **{k: (v.astype(str) if v.dtype == object else v) for k, v in content.items()})  # type: ignore[arg-type]
        with replaced_atomically(mat) as part, open(part, "wb") as out:
            scipy.io.savemat(out, dict(content, source=np.array(shown)), oned_as="column")
        return [npz, mat]

    @classmethod
    def load(cls, path: Path) -> "LinearModel":
        """Read a model written by :meth:`save` (the ``.npz``)."""
        data = np.load(Path(path).with_suffix(".npz"))
        discrete = float(data["Ts"]) > 0.0
        A = data["Phi"] if discrete else data["A"]
        B = data["Gamma"] if discrete else data["B"]
        return cls(A, B, data["C"], data["D"], [str(s) for s in data["states"]], [str(s) for s in data["inputs"]],
                   [str(s) for s in data["outputs"]],
                   float(data["Ts"]) if discrete else None, float(data["time"]), data["x0"], data["u0"], data["y0"],
                   str(data["source"]))

    def frequency_response(self, omega: np.ndarray) -> np.ndarray:
        """G(j w) (continuous) or G(exp(j w Ts)) (discrete), shape (len(omega), ny, nu)."""
        points = np.exp(1j * omega * float(self.sample_time)) if self.sample_time is not None else 1j * omega
        n = self.A.shape[0]
        out = np.empty((len(omega), self.C.shape[0], self.B.shape[1]), dtype=complex)
        for k, p in enumerate(points):
            out[k] = self.C @ np.linalg.solve(p * np.eye(n) - self.A, self.B) + self.D
        return out
