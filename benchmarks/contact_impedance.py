"""The delta robot touching a table: the same approach at several impedance levels, and what
contact costs a run.

1. scenarios/contact_approach.yaml (the tool comes down at 20 mm/s; the reference ends 1 cm below
   the touching height) under: a high-gain position controller (poles at -30), the seed's pole
   placement (-7) and its low gains (kp = 1.0, kd = 0.25, no integral), and impedance mode with
   stiffness K along z from 20000 down to 200 N/m (damping
   critical for the wrist's 17 kg, 2 sqrt(K m)), in order of falling stiffness along z (a position
   loop's is the wrist inertia times kP = 3 p^2, plus the integral). For each: the peak impact force (largest contact
   force in the first 50 ms after the first touch), the largest force of the run, the time to
   settle (first touch until the force stays within 2 % of its final value), the steady force and,
   in impedance mode, its error against the commanded K d. The peak impact force must fall as the
   impedance falls (exit code 1 otherwise).
2. scenarios/contact_press.yaml: real-time factor of the whole run (median of --repeats, FMU
   loading included, and of the stepping alone), the events, and the share of the stepping spent
   handling events (locating them plus event mode); the baseline is the same run with the table
   lowered out of reach (no contact, no events), measured now on this machine.

Usage: python benchmarks/contact_impedance.py [--repeats 3]
"""
from __future__ import annotations

import argparse
import math
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping import me_integrator
from deltafmi.master.stepping.explicit_rk import ExplicitRungeKutta
from deltafmi.master.stepping.master import Master

ROOT = Path(__file__).resolve().parents[1]
WRIST_MASS = 17.0         # kg: the wrist's inertia along z at the contact (tests/models/test_robot_contact.py)
DEPTH = 0.01              # m: the reference ends this far below the touching height
K_SURFACE = 2e5           # N/m: the scenarios' contact stiffness

#: (label, controller parameters, commanded stiffness K in impedance mode, stiffness along z)
LEVELS = sorted(
    [(f"position, poles at -{p:g}" + (" (seed)" if p == 7 else ""), {"impedance": False, "pole": p}, None,
      WRIST_MASS * 3.0 * p * p) for p in (30.0, 7.0)]
    + [("position, kp = 1, kd = 0.25 (seed)", {"impedance": False, "kP": 1.0, "kD": 0.25, "kI": 0.0}, None,
        WRIST_MASS * 1.0)]
    + [(f"impedance K = {K:g} N/m", {"impedance": True, "stiffness": [5000.0, 5000.0, K],
                                      "task_damping": [400.0, 400.0, 2.0 * math.sqrt(K * WRIST_MASS)]}, K, K)
       for K in (20000.0, 5000.0, 1000.0, 200.0)],
    key=lambda level: -level[3])


def variant(name: str, folder: Path, tag: str, **changes: dict) -> Path:
    """scenarios/<name>.yaml with ``changes[component]`` merged into its parameters."""
    spec = yaml.safe_load((ROOT / "scenarios" / f"{name}.yaml").read_text())
    for component in spec["components"].values():
        component["source"] = str(ROOT / component["source"])
    for component, parameters in changes.items():
        spec["components"][component]["parameters"].update(parameters)
    path = folder / f"{name}-{tag}.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


class EventClock:
    """Wall time inside event location (Runge-Kutta bisection) and event mode (the ME units)."""

    def __init__(self) -> None:
        self.seconds = 0.0
        self._patches = [(ExplicitRungeKutta, "_locate"), (me_integrator.ModelExchangeUnit, "_event")]
        self._saved = [getattr(owner, name) for owner, name in self._patches]

    def __enter__(self) -> "EventClock":
        for (owner, name), original in zip(self._patches, self._saved):
            setattr(owner, name, self._timed(original))
        return self

    def __exit__(self, *exc) -> None:
        for (owner, name), original in zip(self._patches, self._saved):
            setattr(owner, name, original)

    def _timed(self, function):
        def timed(*args, **kwargs):
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                self.seconds += time.perf_counter() - start
        return timed


def approach_row(path: Path, stiffness) -> dict:
    out = path.with_suffix(".csv")
    Master(resolve_system(load_scenario(path)), result=out).run()
    c = columns(out)
    t, fn = c["time"], c["plant.fn"]
    touch = int(np.argmax(c["plant.mode"] > 0))
    final = float(fn[-1])
    outside = np.flatnonzero(np.abs(fn - final) > 0.02 * abs(final))
    settle = float(t[outside[-1] + 1] - t[touch]) if len(outside) and outside[-1] + 1 < len(t) else math.nan
    if c["plant.mode"][-1] == 0:
        settle = math.nan  # bounced off and still in the air: never settled on the table
    row = {"impact": float(fn[(t >= t[touch]) & (t <= t[touch] + 0.05)].max()), "peak": float(fn.max()),
           "settle": settle, "final": final, "error": None}
    if stiffness is not None:
        row["error"] = final / (stiffness * DEPTH) - 1.0
    return row


def time_run(path: Path) -> tuple[float, float, int, float]:
    """(whole run, stepping, events, event handling) wall seconds of one run of ``path``."""
    with tempfile.TemporaryDirectory() as tmp, EventClock() as clock:
        start = time.perf_counter()
        summary = Master(resolve_system(load_scenario(path)), result=Path(tmp) / "run.csv").run()
        whole = time.perf_counter() - start
    return whole, whole - summary.setup_time, summary.events, clock.seconds


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    ok = True
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        print("1. contact_approach.yaml: 20 mm/s onto the table, reference 1 cm below the touching height")
        print(f"   {'controller':34s} {'z stiffness':>11s} {'impact peak':>11s} {'run peak':>9s} {'settle':>8s} "
              f"{'steady':>9s} {'K d':>8s} {'error':>8s}")
        impacts = []
        for label, parameters, stiffness, along_z in LEVELS:
            row = approach_row(variant("contact_approach", folder, str(len(impacts)), controller=parameters),
                               stiffness)
            impacts.append(row["impact"])
            kd = f"{stiffness * DEPTH:8.2f}" if stiffness is not None else f"{'-':>8s}"
            error = f"{100 * row['error']:7.2f}%" if row["error"] is not None else f"{'-':>8s}"
            settle = f"{row['settle']:6.3f} s" if math.isfinite(row["settle"]) else f"{'in air':>8s}"
            print(f"   {label:34s} {along_z:7.0f} N/m {row['impact']:9.1f} N {row['peak']:7.1f} N {settle} "
                  f"{row['final']:7.2f} N {kd} {error}")
        falling = all(a > b for a, b in zip(impacts, impacts[1:]))
        ok &= falling
        print(f"   peak impact force falls as the impedance falls: {'yes' if falling else 'NO'}")
        print(f"   (the impedance-mode error is the contact's give: -K / (k + K) with k = {K_SURFACE:g} N/m)")

        print(f"\n2. contact_press.yaml: real-time factor, median of {args.repeats}")
        press = variant("contact_press", folder, "press")
        baseline = variant("contact_press", folder, "free", plant={"surface_height": -1.4})
        stop = yaml.safe_load(press.read_text())["experiment"]["stop"]
        for label, path in (("pressing (contact)", press), ("baseline: table out of reach", baseline)):
            runs = [time_run(path) for _ in range(args.repeats)]
            whole = statistics.median(r[0] for r in runs)
            stepping = statistics.median(r[1] for r in runs)
            events = runs[0][2]
            handling = statistics.median(r[3] / r[1] for r in runs)
            print(f"   {label:34s} real-time factor {stop / whole:5.2f}x (stepping alone {stop / stepping:5.2f}x), "
                  f"{events} events, {100 * handling:5.2f}% of the stepping in event handling")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
