"""What keeping the row at each step's start costs (the values an event row shows of the other
units, see docs/scenarios.md "Event rows"): the same run with it and with it switched off.

A textbook ball (Model Exchange: CVODE in the Python loop, RK4 in the C loop) beside a clock and a
follower (tests/master/event_row_parts), 3 s in steps of 1 ms; runs alternate, medians of 7.
Prints each median and the ratio with/without.
"""
from __future__ import annotations

import shutil
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "master"))

from deltafmi import resolve_system  # noqa: E402
from deltafmi.master.scenario.spec import load_scenario  # noqa: E402
from deltafmi.master.stepping.master import Master  # noqa: E402

SCENARIO = """\
experiment: {{start: 0.0, stop: 3.0, step: 0.001}}
components:
  clock: {{source: clock.py:Clock, interface: CS}}
  ball: {{source: bouncing_ball_reinit.py:BouncingBallReinit, interface: ME{solver}}}
  follower: {{source: follower.py:Follower, interface: CS}}
connections:
  - {{from: ball.height, to: follower.u}}
outputs: [clock.y, ball.height, ball.v, follower.u, follower.y]
"""


def _seconds(path: Path, keep: bool) -> float:
    master = Master(resolve_system(load_scenario(path)), result=path.with_suffix(".csv"))
    if not keep:
        wire = master._wire

        def wire_without() -> None:
            wire()
            master._others = {}
        master._wire = wire_without
    begin = time.perf_counter()
    master.run()
    return time.perf_counter() - begin


def main() -> None:
    folder = Path(tempfile.mkdtemp())
    for part in (ROOT / "tests" / "master" / "event_row_parts").glob("*.py"):
        shutil.copy(part, folder)
    shutil.copy(ROOT / "fmu_src" / "bouncing_ball_reinit.py", folder)
    for name, solver in (("python loop (CVODE)", ""), ("C loop (RK4)", ", solver: {method: rk4, max_step: 0.001}")):
        path = folder / f"{name.split()[0]}.yaml"
        path.write_text(SCENARIO.format(solver=solver))
        _seconds(path, True)  # builds and warms up
        times = {True: [], False: []}
        for _ in range(7):
            for keep in (False, True):
                times[keep].append(_seconds(path, keep))
        with_, without = statistics.median(times[True]), statistics.median(times[False])
        print(f"{name}: with the step-start row {with_ * 1e3:.1f} ms, without {without * 1e3:.1f} ms, "
              f"ratio {with_ / without:.3f} (3000 steps, medians of 7)")


if __name__ == "__main__":
    main()
