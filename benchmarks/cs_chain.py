"""A chain of Co-Simulation units in our master (issue 26, item 4): does it scale?

50 Oscillator FMUs (Co-Simulation, fmu_src/oscillator.py: CVODE inside each FMU, wall
impacts, a force step at 2.5 s), Jacobi at 1 ms, run three ways in the same process, rounds
interleaved (the machine is shared):

- chained: each unit's ``energy`` drives the next one's ``F`` (factor 0.05, as benchmarks/cosim.py);
- unconnected: the same 50 units, no connections;
- chained, restarted: the chain with every unit's CVODE restarted at each input change
  (``cs_options = {"input_jump_tolerance": 0}``, the behaviour before: a cold start per step).

Prints the stepping cost per unit-step (medians of ``--repeats`` rounds) and the ratios; target:
chained <= 1.5x unconnected. Then the accuracy of the chain:

- against restarted integration (the same chain, the restarted FMU): max and end |x|, |v|
  differences over all units, with the default walls and force step (events inside steps);
- both against the exact zero-order-hold solution of the chain (no wall contact, no force
  step: each unit is linear, so one step is x <- Phi x + Gamma F with the matrix exponential).

Usage: python benchmarks/cs_chain.py [--units 50] [--stop 1.0] [--repeats 5]
"""
from __future__ import annotations

import argparse
import statistics
import tempfile
from pathlib import Path

import numpy as np
from scipy.linalg import expm

from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.models.oscillator import Oscillator

ROOT = Path(__file__).resolve().parents[1]
OSCILLATOR = ROOT / "fmu_src" / "oscillator.py"
STEP, FACTOR = 1e-3, 0.05
RESTARTED = '''\
from deltafmi.models.oscillator import Oscillator


class OscillatorRestarted(Oscillator):
    """The Oscillator with its CS solver restarted at every input change (the behaviour before)."""

    cs_options = {"input_jump_tolerance": 0.0}
'''
LINEAR = {"wall": -100.0, "t_step": 100.0}  # no impact, no force step: closed form per step


def scenario(source: Path, units: int, stop: float, chained: bool, parameters: dict | None = None) -> str:
    """A scenario of ``units`` CS oscillators from ``source``, chained or not."""
    params = f", parameters: {parameters}" if parameters else ""
    lines = [f"experiment: {{stop: {stop}, step: {STEP}}}", "master: {algorithm: jacobi}", "components:"]
    lines += [f"  o{i}: {{source: {source}, interface: CS{params}}}" for i in range(units)]
    if chained:
        lines.append("connections:")
        lines += [f"  - {{from: o{i}.energy, to: o{i + 1}.F, factor: {FACTOR}}}" for i in range(units - 1)]
    lines.append("outputs: [" + ", ".join(f"o{i}.x, o{i}.v" for i in range(units)) + "]")
    return "\n".join(lines) + "\n"


def run(folder: Path, name: str, text: str) -> tuple[float, np.ndarray]:
    """(stepping seconds, states [rows, units, 2]) of one master run of the scenario ``text``."""
    path = folder / f"{name}.yaml"
    path.write_text(text)
    out = folder / f"{name}.csv"
    summary = Master(resolve_system(load_scenario(path)), result=out).run()
    c = columns(out)
    units = sum(1 for key in c if key.endswith(".x"))
    states = np.stack([np.stack([c[f"o{i}.x"], c[f"o{i}.v"]], axis=1) for i in range(units)], axis=1)
    return summary.stepping_time, states


def exact_chain(units: int, stop: float) -> np.ndarray:
    """The chain's exact zero-order-hold solution (Jacobi: inputs from the outputs at t_k)."""
    m, k, c = (Oscillator.m.start[0], Oscillator.k.start[0], Oscillator.c.start[0])
    augmented = np.zeros((3, 3))
    augmented[:2, :2] = [[0.0, 1.0], [-k / m, -c / m]]
    augmented[1, 2] = 1.0 / m
    transition = expm(augmented * STEP)
    phi, gamma = transition[:2, :2], transition[:2, 2]
    x = np.tile([Oscillator.x.start[0], Oscillator.v.start[0]], (units, 1))
    rows = [x.copy()]
    for _ in range(int(round(stop / STEP))):
        energy = 0.5 * m * x[:, 1] ** 2 + 0.5 * k * x[:, 0] ** 2
        force = np.concatenate([[0.0], FACTOR * energy[:-1]])
        x = x @ phi.T + np.outer(force, gamma)
        rows.append(x.copy())
    return np.array(rows)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--units", type=int, default=50)
    parser.add_argument("--stop", type=float, default=1.0)
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    n, stop = args.units, args.stop
    unit_steps = n * int(round(stop / STEP))
    with tempfile.TemporaryDirectory() as tmp:
        folder = Path(tmp)
        restarted = folder / "oscillator_restarted.py"
        restarted.write_text(RESTARTED)
        cases = {"chained": scenario(OSCILLATOR, n, stop, True),
                 "unconnected": scenario(OSCILLATOR, n, stop, False),
                 "chained, restarted": scenario(restarted, n, stop, True)}
        for name, text in cases.items():  # builds (or finds) the FMUs, warms up
            run(folder, "warm", text)
        seconds: dict = {name: [] for name in cases}
        states: dict = {}
        for _ in range(args.repeats):
            for name, text in cases.items():
                wall, states[name] = run(folder, "timed", text)
                seconds[name].append(wall)
        us = {name: 1e6 * statistics.median(s) / unit_steps for name, s in seconds.items()}
        print(f"{n} Oscillator CS units, {stop} s at {STEP * 1e3:g} ms, Jacobi; medians of {args.repeats} rounds, "
              f"us per unit-step (stepping, result file included):")
        for name, value in us.items():
            print(f"  {name:20s} {value:7.1f} us   ({value / us['unconnected']:.2f}x unconnected)")
        print(f"  target: chained <= 1.5x unconnected -> {us['chained'] / us['unconnected']:.2f}x")

        diff = np.abs(states["chained"] - states["chained, restarted"])
        print("accuracy of the chain against restarted integration (default walls and force step, "
              "all units):")
        print(f"  max |x| difference {diff[..., 0].max():.2e} m, |v| {diff[..., 1].max():.2e} m/s; "
              f"at the end {diff[-1, :, 0].max():.2e} m, {diff[-1, :, 1].max():.2e} m/s")
        exact = exact_chain(n, stop)
        print("against the exact zero-order-hold solution (no wall contact, no force step):")
        for name, source in (("chained", OSCILLATOR), ("chained, restarted", restarted)):
            _, linear = run(folder, "linear", scenario(source, n, stop, True, LINEAR))
            error = np.abs(linear - exact)
            print(f"  {name:20s} max |x| error {error[..., 0].max():.2e} m, |v| {error[..., 1].max():.2e} m/s; "
                  f"at the end {error[-1, :, 0].max():.2e} m")


if __name__ == "__main__":
    main()
