"""Issue 26 item 2: the flagship's kernels GENERATED from their Python source, against the hand C.

benchmarks/kernel_codegen generates C from deltafmi/physics/delta/*.py: the plant's
``state_derivative`` and ``evaluate_plant``, the controller's ``control_law.evaluate`` (Newton
forward kinematics, constraint Jacobian, gravity solve, PID with feed-forward and anti-windup),
``hold`` and ``warm_start``, and ``MinimumJerkPath.evaluate_flat``; a hand-written driver
(benchmarks/kernel_codegen/flagship_loop.c: the controller's state between samples, the master's
RK4, the Gauss-Seidel loop) closes them as benchmarks/native/flagship.c closes its hand
transcription. Both compiled with ``-std=c99 -O2`` (the generated C also with -ffp-contract=off
-fno-builtin-pow, the flags that keep Python's arithmetic).

Checked at every run: the generated closed loop against the hand transcription's over the whole
flagship (which tests/builder/test_native_baseline.py holds bit for bit to the flagship's CSV), and the
generated controller's torques on the replayed samples. Measured in the same run, medians over
``--repeats`` rounds (ratios: medians of the rounds' ratios):

- closed-loop step: a whole flagship run (3.5 s of 1 ms steps: RK4 of the plant, outputs,
  path, controller sample) / steps;
- controller sample: the flagship's samples replayed through a fresh controller;
- plant derivative: bursts of ``--calls`` derivatives on the flagship's state at a few instants;
- for context, the controller sample in Python (``DeltaController.step`` run by the interpreter).

Usage: python benchmarks/kernel_codegen_flagship.py [--repeats 5] [--calls 20000]
"""
from __future__ import annotations

import argparse
import statistics
import sys
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))

import native  # noqa: E402  (the hand transcription and the flagship's data)
from kernel_codegen.flagship import GeneratedFlagship  # noqa: E402


def agreement(got: np.ndarray, want: np.ndarray) -> str:
    if np.array_equal(got, want):
        return "bit for bit"
    return f"NOT bit for bit: max rel {native.gap(got, want):.1e}"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5, help="rounds; figures are medians over them")
    parser.add_argument("--calls", type=int, default=20000, help="plant derivatives per C-loop burst")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix="deltafmi-kcf-") as scratch:
        run(Path(scratch), args.repeats, args.calls)


def run(tmp: Path, repeats: int, calls: int) -> None:
    system = native.load_flagship()
    spec = native.flagship_spec(system)
    baseline = native.Baseline(native.compile_baseline(tmp))
    generated = GeneratedFlagship(native.flagship_models(system), tmp)
    steps = int(round(3.5 / spec.h))
    rows, states, _ = baseline.run(spec, steps)
    inputs = native.controller_inputs(baseline, spec, rows, states)
    print(f"generated closed loop vs hand C, {steps} steps, all 15 columns: "
          f"{agreement(generated.run(spec.start, spec.h, steps), rows)}")
    print(f"generated controller vs hand C, {len(inputs)} samples' torques: "
          f"{agreement(generated.replay_controller(inputs)[0], baseline.replay_controller(spec, inputs)[0])}")
    instants = [int(round(f * steps)) for f in (0.0, 0.2, 0.4, 0.6, 0.8)]
    points = [(states[k], rows[min(k + 1, steps), 10:13]) for k in instants]

    figures: dict[str, list[float]] = {}
    ratios: dict[str, list[float]] = {}

    def note(key: str, hand_ns: float, gen_ns: float) -> None:
        figures.setdefault(key + " hand", []).append(hand_ns)
        figures.setdefault(key + " generated", []).append(gen_ns)
        ratios.setdefault(key, []).append(gen_ns / hand_ns)

    python_ns = []
    for _ in range(repeats):
        _, _, wall_hand = baseline.run(spec, steps)
        wall_gen = _timed(lambda: generated.run(spec.start, spec.h, steps))
        note("closed-loop step", 1e9 * wall_hand / steps, 1e9 * wall_gen / steps)
        _, hand = baseline.replay_controller(spec, inputs)
        _, gen = generated.replay_controller(inputs)
        note("controller sample", 1e9 * hand / len(inputs), 1e9 * gen / len(inputs))
        hand = statistics.median(baseline.repeat_derivative(spec, x, u, calls) for x, u in points)
        gen = statistics.median(generated.repeat_derivative(x, u, calls) for x, u in points)
        note("plant derivative", 1e9 * hand / calls, 1e9 * gen / calls)
        _, wall = native.python_controller(native.flagship_models(system).controller, inputs[:500])
        python_ns.append(1e9 * wall / 500)

    print(f"medians of {repeats} rounds (ns); generated / hand C measured in the same round:")
    print(f"{'':20s} {'hand C':>9s} {'generated':>10s} {'ratio':>7s}")
    for key in ratios:
        print(f"{key:20s} {statistics.median(figures[key + ' hand']):9.0f} "
              f"{statistics.median(figures[key + ' generated']):10.0f} {statistics.median(ratios[key]):7.2f}")
    print(f"controller sample in Python (DeltaController.step, interpreted): {statistics.median(python_ns):.0f} ns")


def _timed(action) -> float:
    import time

    begin = time.perf_counter()
    action()
    return time.perf_counter() - begin


if __name__ == "__main__":
    main()
