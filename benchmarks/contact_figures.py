"""The contact scenarios' figures (docs/robot_contact.md, section 5's table; the README's contact
paragraph): each scenario run as shipped, its figures printed. No timing: the numbers do not depend
on the machine.

- contact_press: the speed at the touch, the impact's peak (largest fn in COLLISION), the resting
  force and penetration at the end, the overshoot of the resting force;
- contact_approach, contact_stiff, contact_soft: the resting force (and penetration);
- contact_slide: the normal force's range while the reference slides;
- contact_friction: the breakaway (first SLIP) and the static limit 0.35 fn there, the friction
  force and the wrist's lag behind the reference while cruising at 20 mm/s, the lag at the end;
- contact_tactile: the tool's offset from the hole's centre at the end, and its largest over the
  last 0.5 s;
- contact_box: the two corners' forces at the end;
- inertia: the wrist's inertia with the loops closed (``1 / (H Y)``, the impact's effective mass)
  along z and x at the workspace's centre (z = -1.0 m) and at the touching height of the contact
  scenarios (z = -1.05 m), without and with their 0.5 kg payload (docs/robot_contact.md, sections
  1 and 9; docs/assembly.md, section 3).

Usage: python benchmarks/contact_figures.py [SCENARIO ...]
"""
from __future__ import annotations

import dataclasses
import sys
from typing import Callable

import numpy as np

import deltafmi
from deltafmi.physics import delta
from deltafmi.physics.delta.contact import DeltaToolModel, Plane

COLLISION = 1
SLIP = 2
MU_S = 0.35                  # contact_friction.yaml's plant.mu_s


def _run(name: str, record: list[str]) -> dict:
    res = deltafmi.simulate(name, record=record)
    return {key: np.asarray(res[key], dtype=float) for key in ["time", *record]}


def press() -> str:
    c = _run("contact_press", ["plant.fn", "plant.mode", "plant.zd[3]", "plant.penetration"])
    touch = int(np.argmax(c["plant.mode"] > 0))
    fn = c["plant.fn"]
    impact = fn[c["plant.mode"] == COLLISION].max()
    return (f"touches at {abs(c['plant.zd[3]'][touch]) * 1e3:.1f} mm/s; impact peak {impact:.1f} N; rests on "
            f"{fn[-1]:.3f} N, penetration {c['plant.penetration'][-1] * 1e3:.4f} mm; overshoot of the resting force "
            f"{(fn.max() / fn[-1] - 1) * 100:.1f} %")


def resting(name: str) -> Callable[[], str]:
    def figures() -> str:
        c = _run(name, ["plant.fn", "plant.penetration"])
        return f"rests on {c['plant.fn'][-1]:.3f} N, {c['plant.penetration'][-1] * 1e3:.2f} mm into the surface"
    return figures


def slide() -> str:
    c = _run("contact_slide", ["plant.fn", "trajectory.rd[1]"])
    sliding = np.abs(c["trajectory.rd[1]"]) > 1e-6
    fn = c["plant.fn"][sliding]
    return f"normal force while the reference slides {fn.min():.3f}-{fn.max():.3f} N"


def friction() -> str:
    c = _run("contact_friction", ["plant.fn", "plant.friction_mode", "plant.friction_force[1]", "plant.z[1]",
                                  "trajectory.r[1]", "trajectory.rd[1]"])
    t = c["time"]
    slip = int(np.argmax(c["plant.friction_mode"] == SLIP))
    cruise = np.abs(c["trajectory.rd[1]"] - np.median(c["trajectory.rd[1]"][c["trajectory.rd[1]"] > 1e-6])) < 1e-9
    cruise &= t > t[slip] + 0.2               # past the breakaway's transient
    lag = c["trajectory.r[1]"] - c["plant.z[1]"]
    return (f"breaks away at {t[slip]:.3f} s (0.35 fn = {MU_S * c['plant.fn'][slip]:.3f} N); cruising: friction "
            f"{np.median(np.abs(c['plant.friction_force[1]'][cruise])):.3f} N, lag {np.median(lag[cruise]) * 1e3:.3f} mm; "
            f"lag at the end {lag[-1] * 1e3:.3f} mm")


def tactile() -> str:
    c = _run("contact_tactile", ["plant.tip[1]"])
    off = np.abs(c["plant.tip[1]"] - 0.003)    # the hole's centre: sensor.hole_centre[1]
    late = c["time"] > c["time"][-1] - 0.5
    return f"offset from the hole's centre at the end {off[-1] * 1e6:.2f} um, over the last 0.5 s at most {off[late].max() * 1e6:.2f} um"


def box() -> str:
    c = _run("contact_box", [f"plant.fn[{i}]" for i in range(1, 7)])
    corners = sorted(c[f"plant.fn[{i}]"][-1] for i in range(3, 7))
    return f"corner forces at the end {', '.join(f'{f:.3f}' for f in corners)} N"


def inertia() -> str:
    rows = []
    for payload in (0.0, 0.5):
        params = dataclasses.replace(delta.RL5, payload=payload)
        for height in (-1.0, -1.05):
            q = np.asarray(delta.inverse_kinematics(params, [0.0, 0.0, height]), float)
            z, x = (DeltaToolModel(params, Plane(-1.15, n)).effective_mass(q) for n in ((0, 0, 1), (1, 0, 0)))
            rows.append(f"payload {payload} kg, z = {height} m: {z:.3f} kg along z, {x:.3f} kg along x")
    return "; ".join(rows)


FIGURES = {"inertia": inertia, "contact_press": press, "contact_approach": resting("contact_approach"),
           "contact_stiff": resting("contact_stiff"), "contact_soft": resting("contact_soft"),
           "contact_slide": slide, "contact_friction": friction, "contact_tactile": tactile, "contact_box": box}


def main(names: list[str]) -> None:
    for name in names or FIGURES:
        print(f"{name}: {FIGURES[name]()}", flush=True)


if __name__ == "__main__":
    main(sys.argv[1:])
