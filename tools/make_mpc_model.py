"""Write scenarios/mpc_press_model.npz: the linear model mpc_press.yaml's MPC predicts with.

The delta robot with its contact plane (DeltaRobotContact) linearized at rest with the wrist at
z = -1.049 m, 1 mm above the touching height, its servo torques u solved to hold it there; inputs
the servo torques u and the force on the wrist f, outputs the servo angles y and rates yd and the
wrist position z and velocity zd. It runs the command

    deltafmi linearize DeltaRobotContact --set z0=0,0,-1.049 --rest --free u -u u -u f
        -y y -y yd -y z -y zd -o mpc_press_model

(in a temporary folder: the command writes a .mat beside the .npz, which the example does not
need) and keeps the .npz. Run it again whenever the robot's model changes:

    python tools/make_mpc_model.py [OUT]
"""
from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

from deltafmi.apps.cli import main as deltafmi_main

OUT = Path(__file__).resolve().parents[1] / "scenarios" / "mpc_press_model.npz"
ARGUMENTS = ["linearize", "DeltaRobotContact", "--set", "z0=0,0,-1.049", "--rest", "--free", "u",
             "-u", "u", "-u", "f", "-y", "y", "-y", "yd", "-y", "z", "-y", "zd", "-q"]


def make_model(out: Path = OUT) -> Path:
    """Run the linearization above and copy its .npz to ``out``; returns ``out``."""
    with tempfile.TemporaryDirectory() as folder:
        base = Path(folder) / "mpc_press_model"
        deltafmi_main(ARGUMENTS + ["-o", str(base)], standalone_mode=False)
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(base.with_suffix(".npz"), out)
    return out


if __name__ == "__main__":
    written = make_model(Path(sys.argv[1]) if len(sys.argv) > 1 else OUT)
    print(f"wrote {written} ({written.stat().st_size} bytes)")
