"""The insertion MPC's behaviour figures (docs/assembly.md, section 7; scenarios/peg_in_hole_mpc.yaml's
header; the README's assembly paragraph): no timing, the numbers do not depend on the machine's
speed (the QP's solve is decided by iteration counts and tolerances).

1. ``peg_in_hole_mpc`` as shipped: the MPC-planned insertion beside the impedance program alone
   (10 mm/s through the first contact). For each: the insertion time (the plant's latched success:
   20 mm deep), the peak axial and total contact force on the peg. For the MPC's reference: its
   speed where its depth passes the contact zone's upper edge (2 mm above the nominal top), the
   depth and the delay at which it has braked to the contact speed (10 mm/s, +1 %), the fastest it
   moves in the zone (2 mm above to 3 mm below the top) and in the bore, and the largest planned push.
2. The impedance program at 20 mm/s all the way (``peg_in_hole`` with ``controller.entry_speed``
   0.02, 3 s): its insertion time and peaks.
3. ``--bottom``: the press on the bore's bottom (``--set mpc.goal_depth=0.06 --stop 4.4``): the
   first touch's peak, the planned push's largest value, the contact force's mean over the last 0.2 s.

Usage: python benchmarks/peg_mpc_figures.py [--bottom]
"""
from __future__ import annotations

import argparse
from typing import Sequence

import numpy as np

import deltafmi

ZONE = (0.002, 0.003)         # m above / below the nominal top: the scenario's mpc.contact_zone
CONTACT_SPEED = 0.01          # m/s: mpc.contact_speed


def _columns(result, names: Sequence[str]) -> dict:
    return {name: np.asarray(result[name], dtype=float) for name in ["time", *names]}


def _force_figures(c: dict, plant: str) -> dict:
    """Insertion time (success latched), peak axial and total contact force on the peg."""
    t = c["time"]
    F = np.column_stack([c[f"{plant}.contact_force[{k}]"] for k in (1, 2, 3)])
    success = c[f"{plant}.success"]
    return {"time": float(t[np.argmax(success > 0)]) if success.max() > 0 else float("nan"),
            "axial": float(np.abs(F[:, 2]).max()), "total": float(np.linalg.norm(F, axis=1).max())}


def _reference_figures(c: dict) -> dict:
    """Where the MPC's reference brakes for the contact zone, and how fast it moves in it and in the bore."""
    t, depth = c["time"], c["mpc.depth_ref"]
    speed = np.linalg.norm(np.column_stack([c[f"mpc.rd[{k}]"] for k in (1, 2, 3)]), axis=1)
    enter = int(np.argmax(depth >= -ZONE[0]))
    braked = enter + int(np.argmax(speed[enter:] <= 1.01 * CONTACT_SPEED))
    zone = (depth >= -ZONE[0]) & (depth <= ZONE[1])
    bore = depth > ZONE[1] + 1e-3
    return {"enter_speed": float(speed[enter]), "enter_time": float(t[enter]),
            "braked_depth": float(depth[braked]), "braked_delay": float(t[braked] - t[enter]),
            "zone_max_speed": float(speed[zone].max()), "bore_max_speed": float(speed[bore].max()),
            "planned_push": float(c["mpc.planned_force"].max())}


def side_by_side() -> None:
    names = [f"{p}.contact_force[{k}]" for p in ("plant", "impedance_plant") for k in (1, 2, 3)]
    names += ["plant.success", "impedance_plant.success", "mpc.depth_ref", "mpc.planned_force"]
    names += [f"mpc.rd[{k}]" for k in (1, 2, 3)]
    c = _columns(deltafmi.simulate("peg_in_hole_mpc", record=names), names)
    mpc, imp = _force_figures(c, "plant"), _force_figures(c, "impedance_plant")
    ref = _reference_figures(c)
    print("1. peg_in_hole_mpc (3 s)")
    print(f"{'':34}{'MPC + impedance':>18}{'impedance alone':>18}")
    for key, label in (("time", "insertion time (s)"), ("axial", "peak axial contact force (N)"),
                       ("total", "peak total contact force (N)")):
        print(f"{label:34}{mpc[key]:18.3f}{imp[key]:18.3f}")
    print(f"   MPC reference: {ref['enter_speed'] * 1e3:.1f} mm/s at {ZONE[0] * 1e3:g} mm above the top "
          f"(t = {ref['enter_time']:.3f} s); at {CONTACT_SPEED * 1e3:g} mm/s (+1 %) {ref['braked_delay'] * 1e3:.0f} ms "
          f"later, {-ref['braked_depth'] * 1e3:.2f} mm above the top; fastest in the zone "
          f"{ref['zone_max_speed'] * 1e3:.1f} mm/s, in the bore {ref['bore_max_speed'] * 1e3:.1f} mm/s; "
          f"largest planned push {ref['planned_push']:.4f} N")
    names = [f"plant.contact_force[{k}]" for k in (1, 2, 3)] + ["plant.success"]
    fast = _force_figures(_columns(deltafmi.simulate("peg_in_hole", stop=3.0, parameters={"controller.entry_speed": 0.02},
                                                     record=names), names), "plant")
    print(f"2. impedance program at 20 mm/s all the way: in at {fast['time']:.3f} s, peak axial "
          f"{fast['axial']:.1f} N, total {fast['total']:.1f} N")


def bottom() -> None:
    names = [f"plant.contact_force[{k}]" for k in (1, 2, 3)] + ["mpc.planned_force", "mpc.axial_force"]
    res = deltafmi.simulate("peg_in_hole_mpc", stop=4.4, parameters={"mpc.goal_depth": 0.06}, record=names)
    c = _columns(res, names)
    t, Fz = c["time"], np.abs(c["plant.contact_force[3]"])
    late = Fz[t > t[-1] - 0.2]
    hold = t >= t[np.argmax(c["mpc.planned_force"] >= 15.0 - 0.01)]
    print(f"3. pressing on the bottom (goal 60 mm, 4.4 s): first touch peak {Fz.max():.2f} N, planned push max "
          f"{c['mpc.planned_force'].max():.6f} N, push at the samples over the hold {c['mpc.axial_force'][hold].min():.3f}"
          f"-{c['mpc.axial_force'][hold].max():.3f} N, contact force over the last 0.2 s {late.mean():.4f} N")


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--bottom", action="store_true", help="also the press on the bore's bottom")
    args = parser.parse_args(argv)
    side_by_side()
    if args.bottom:
        bottom()


if __name__ == "__main__":
    main()
