"""The worked example of docs/components.md, from the docs' own text: its files are extracted,
built into FMUs, run in its scenarios through the CLI and checked against closed forms.

The DC motor from rest at a constant voltage has a piecewise closed form (current-limited, then
first order); the sampled speed loop equals an exact sampled-data recursion: the motor's closed
form over each 1 ms hold of the voltage, and the PI law at each sample.
"""
from __future__ import annotations

import csv
import math
import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

DOC = Path(__file__).resolve().parents[2] / "docs" / "components.md"
CLI = [sys.executable, "-c", "from deltafmi.apps.cli import main; main()"]
# the motor's declared defaults and the controller's (read back from the FMUs below)
R, KT, KE, J, B, I_MAX = 1.0, 0.05, 0.05, 1e-4, 1e-4, 2.0
KP, KI, V_MAX, T = 0.1, 2.6, 24.0, 1e-3


def doc_files() -> dict[str, str]:
    """Every code block that a bold file name (**`name`**) introduces, by that name."""
    text = DOC.read_text()
    blocks = re.findall(r"^\*\*`([\w.]+)`\*\*\n\n```[a-z]*\n(.*?)^```", text, flags=re.M | re.S)
    return dict(blocks)


@pytest.fixture(scope="module")
def example(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("worked_example")
    files = doc_files()
    assert set(files) == {"dc_motor.py", "speed_controller.py", "motor_open_loop.yaml",
                          "motor_speed_loop.yaml", "test_dc_motor.py"}
    for name, text in files.items():
        (folder / name).write_text(text)
    return folder


def run(folder: Path, *args: str) -> subprocess.CompletedProcess:
    result = subprocess.run(CLI + list(args), capture_output=True, text=True, cwd=folder, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
    return result


def read(path: Path) -> dict[str, np.ndarray]:
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    data = np.array(rows[1:], dtype=float)
    return {name: data[:, i] for i, name in enumerate(rows[0])}


def motor_after(w: float, volts: float, duration: float) -> float:
    """The motor's speed ``duration`` after ``w`` at a constant voltage: closed form, piecewise
    (at the current limit until the back-EMF brings the demand inside it, then first order)."""
    demand = (volts - KE * w) / R
    elapsed = 0.0
    if abs(demand) > I_MAX:
        sign = math.copysign(1.0, demand)
        w_lim = KT * sign * I_MAX / B            # where the limited motion heads
        w_edge = (volts - sign * R * I_MAX) / KE  # where the demand reaches the limit
        ratio = (w_edge - w_lim) / (w - w_lim)
        t_edge = -J / B * math.log(ratio) if 0.0 < ratio < 1.0 else math.inf
        if t_edge >= duration:
            return w_lim + (w - w_lim) * math.exp(-B * duration / J)
        w, elapsed = w_edge, t_edge
    w_inf, tau = KT * volts / (KT * KE + B * R), J * R / (KT * KE + B * R)
    return w_inf + (w - w_inf) * math.exp(-(duration - elapsed) / tau)


def sampled_loop(reference: float, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Speeds at t_k = k T and voltages held over [t_k, t_k+1), k = 0..n."""
    integral, w = 0.0, 0.0
    speeds, volts = [w], []
    for _ in range(n):
        error = reference - w
        v = KP * error + KI * integral
        if abs(v) < V_MAX:
            integral += error * T
        v = min(max(v, -V_MAX), V_MAX)
        w = motor_after(w, v, T)
        speeds.append(w)
        volts.append(v)
    return np.array(speeds), np.array(volts)


def on_grid(result: dict[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the rows at communication points (not event rows) and their k."""
    k = np.rint(result["time"] / T).astype(int)
    rows = np.flatnonzero(np.abs(result["time"] - k * T) <= 1e-12)
    return rows, k[rows]


@pytest.mark.parametrize("interface", ["ME", "CS"])
def test_open_loop_follows_the_closed_form(example: Path, interface: str) -> None:
    scenario = example / f"open_{interface}.yaml"
    scenario.write_text((example / "motor_open_loop.yaml").read_text().replace("interface: ME",
                                                                               f"interface: {interface}"))
    run(example, "run", str(scenario), "-o", f"open_{interface}.csv")
    result = read(example / f"open_{interface}.csv")
    exact = np.array([motor_after(0.0, 12.0, t) for t in result["time"]])
    speed = result["motor.speed"]
    assert np.max(np.abs(speed - exact)) < 1e-6 * np.max(exact)
    # at the limit until t1, then the demand
    demand = (12.0 - KE * exact) / R
    assert np.max(np.abs(result["motor.current"] - np.minimum(demand, I_MAX))) < 1e-5
    t1 = -J / B * math.log(1.0 - (12.0 - R * I_MAX) / KE / (KT * I_MAX / B))
    assert t1 == pytest.approx(0.2231, abs=1e-4)
    if interface == "ME":  # the master records the state event as two rows at t1
        times, counts = np.unique(result["time"], return_counts=True)
        assert times[counts == 2] == pytest.approx([t1], abs=1e-7)
    assert result["motor.current"][0] == I_MAX and result["motor.current"][-1] < 0.47


@pytest.mark.parametrize("controller", ["CS", "ME"])
def test_speed_loop_equals_the_sampled_data_recursion(example: Path, controller: str) -> None:
    scenario = example / f"loop_{controller}.yaml"
    text = (example / "motor_speed_loop.yaml").read_text()
    if controller == "ME":
        text = text.replace("    parameters: {reference: 50.0}", "    interface: ME\n    parameters: {reference: 50.0}")
    scenario.write_text(text)
    validated = run(example, "validate", str(scenario))
    assert "stepping order (gauss-seidel): motor -> controller" in validated.stdout
    assert "algebraic loop" not in validated.stdout + validated.stderr
    run(example, "run", str(scenario), "-o", f"loop_{controller}.csv")
    result = read(example / f"loop_{controller}.csv")
    rows, k = on_grid(result)
    assert k[-1] == 500
    speeds, volts = sampled_loop(50.0, 500)
    assert np.max(np.abs(result["motor.speed"][rows] - speeds[k])) < 1e-6 * 50.0
    # the voltage held over [t_k, t_k+1) is the one in the last row at t_k (ME: after the event);
    # to kp x the speed's tolerance (0.1 V.s/rad x 5e-5 rad/s), twice for the integral's share
    last = {step: row for row, step in zip(rows, k)}
    held = np.array([result["controller.voltage"][last[step]] for step in range(500)])
    assert np.max(np.abs(held - volts)) < 1e-5
    # what the docs say of it: the current limit, the overshoot, the end
    assert volts[0] == pytest.approx(5.0)
    limited = result["time"][result["motor.current"] >= I_MAX * (1 - 1e-9)]
    assert limited[0] == 0.0 and 0.04 < limited[-1] < 0.045  # from the first row: 5 V at t = 0
    assert speeds.max() == pytest.approx(54.0, abs=0.05)
    assert speeds[-1] == pytest.approx(50.0, abs=0.01)


def test_without_direct_feedthrough_the_loop_is_algebraic(example: Path, tmp_path: Path) -> None:
    motor = (example / "dc_motor.py").read_text()
    declaration = '    direct_feedthrough = {"current": ["voltage"]}\n'
    assert declaration in motor
    (tmp_path / "dc_motor.py").write_text(motor.replace(declaration, ""))
    for name in ("speed_controller.py", "motor_speed_loop.yaml"):
        (tmp_path / name).write_text((example / name).read_text())
    validated = run(tmp_path, "validate", "motor_speed_loop.yaml")
    assert ("algebraic loop controller.voltage -> motor.voltage, motor.speed -> controller.speed "
            "(motor, controller; line 11)") in validated.stdout
    ran = run(tmp_path, "run", "motor_speed_loop.yaml", "-o", "loop.csv")
    solves, evaluations = map(int, re.search(r"algebraic loops: (\d+) solves, (\d+) evaluations",
                                             ran.stdout + ran.stderr).groups())
    assert solves == 501 and evaluations > 2 * solves
    # the loop makes the voltage computed at t + h act over [t, t + h]: not the sampled loop
    result = read(tmp_path / "loop.csv")
    rows, k = on_grid(result)
    speeds, _ = sampled_loop(50.0, 500)
    assert np.max(np.abs(result["motor.speed"][rows] - speeds[k])) > 0.1


def test_the_docs_own_test_passes(example: Path) -> None:
    result = subprocess.run([sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "test_dc_motor.py"],
                            capture_output=True, text=True, cwd=example, timeout=600)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "2 passed" in result.stdout
