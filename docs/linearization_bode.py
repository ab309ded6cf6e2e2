"""Bode plot of the flagship's closed-loop wrist response z / r, from ``deltafmi linearize``.

Linearizes scenarios/delta_tracking.yaml at rest (t = 50 ms) as the 1 ms discrete map with the
reference r as input and the wrist z as output, and plots the three diagonal responses against
the outer loop's continuous design, T(s) = (kP s + kI) / (s + 7)^3 (the reference enters
through kP and kI; kD acts on the measured velocity). Run from the project root:

    python docs/linearization_bode.py            # writes docs/closed_loop_bode.png
"""
from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def main(output: Path = ROOT / "docs" / "closed_loop_bode.png") -> Path:
    from deltafmi.master.linearize.closed_loop import linearize_scenario

    model = linearize_scenario(ROOT / "scenarios" / "delta_tracking.yaml", at=0.05,
                               inputs=[f"controller.r[{i}]" for i in (1, 2, 3)],
                               outputs=[f"plant.z[{i}]" for i in (1, 2, 3)])
    omega = np.logspace(-1, np.log10(np.pi / model.sample_time), 400)
    response = model.frequency_response(omega)
    s = 1j * omega
    design = (147.0 * s + 343.0) / (s + 7.0) ** 3

    fig, (mag, phase) = plt.subplots(2, 1, sharex=True, figsize=(7.5, 6.0))
    for i, axis in enumerate("xyz"):
        g = response[:, i, i]
        mag.semilogx(omega, 20 * np.log10(np.abs(g)), label=f"$z_{axis} / r_{axis}$ (FMUs, 1 ms map)")
        phase.semilogx(omega, np.degrees(np.unwrap(np.angle(g))), label=f"$z_{axis} / r_{axis}$")
    mag.semilogx(omega, 20 * np.log10(np.abs(design)), "k--", lw=1, label="design $(k_P s + k_I)/(s+7)^3$")
    phase.semilogx(omega, np.degrees(np.unwrap(np.angle(design))), "k--", lw=1, label="design")
    cross = np.max(np.abs(response[:, 0, 1]))
    mag.set_ylabel("magnitude [dB]")
    mag.set_ylim(-80, 5)
    phase.set_ylabel("phase [deg]")
    phase.set_xlabel("frequency [rad/s] (up to Nyquist, 3142 rad/s)")
    mag.set_title(f"Flagship closed loop at rest: wrist response to the reference "
                  f"(largest cross-coupling |z_x / r_y| = {cross:.1e})", fontsize=9)
    for ax in (mag, phase):
        ax.grid(True, which="both", alpha=0.3)
    mag.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(output, dpi=110)
    return output


if __name__ == "__main__":
    print(f"wrote {main(*(Path(a) for a in sys.argv[1:]))}")
