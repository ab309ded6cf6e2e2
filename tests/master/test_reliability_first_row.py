"""The first row right: at t = 0 every connected input holds its source's value, the one its unit
integrates with over the first step, in every algorithm (Gauss-Seidel, Jacobi, an algebraic loop,
Model Exchange and Co-Simulation units); event rows hold the inputs in force at the event.

The docs' worked example (docs/components.md): a sampled PI controller asks for 5 V at t = 0
(50 rad/s of error, kp = 0.1); the motor's drive clips the 5 A this asks for to 2 A. Before, the
first row showed the motor's voltage as set in initialization mode, before the controller's
first sample: 0 V and 0 A, while the motor integrated its first step with 5 V.
"""
from __future__ import annotations

import csv
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from test_component_docs import doc_files

R, KE, I_MAX = 1.0, 0.05, 2.0
RECORDED = ["motor.voltage", "motor.current", "motor.speed", "controller.voltage", "controller.speed"]


@pytest.fixture(scope="module")
def example(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("first_row")
    for name, text in doc_files().items():
        (folder / name).write_text(text)
    return folder


def _variant(example: Path, name: str, motor: str = "ME", controller: str = "CS", algorithm: str = "gauss-seidel",
             feedthrough: bool = True) -> Path:
    folder = example / name
    folder.mkdir()
    motor_source = (example / "dc_motor.py").read_text()
    if not feedthrough:  # the current no longer follows the voltage at once: an algebraic loop
        motor_source = motor_source.replace('    direct_feedthrough = {"current": ["voltage"]}\n', "")
    (folder / "dc_motor.py").write_text(motor_source)
    (folder / "speed_controller.py").write_text((example / "speed_controller.py").read_text())
    text = (example / "motor_speed_loop.yaml").read_text()
    text = text.replace("    interface: ME\n", f"    interface: {motor}\n", 1)
    text = text.replace("    parameters: {reference: 50.0}", f"    interface: {controller}\n    parameters: {{reference: 50.0}}")
    text = text.replace("components:", f"master: {{algorithm: {algorithm}}}\ncomponents:", 1)
    (folder / "loop.yaml").write_text(text)
    return folder / "loop.yaml"


def _run(scenario: Path, stop: str = "0.06") -> dict:
    out = scenario.with_suffix(".csv")
    args = ["run", str(scenario), "-o", str(out), "-q", "--stop", stop]
    for name in RECORDED:
        args += ["--record", name]
    done = CliRunner().invoke(main, args)
    assert done.exit_code == 0, done.output
    with open(out, newline="") as f:
        rows = list(csv.reader(f))
    data = np.array(rows[1:], dtype=float)
    return {name: data[:, i] for i, name in enumerate(rows[0])}


@pytest.mark.parametrize("name, options", [
    ("gauss_seidel", {}),
    ("jacobi", {"algorithm": "jacobi"}),
    ("cs_motor", {"motor": "CS"}),
    ("me_controller", {"controller": "ME"}),
    ("both_cs_jacobi", {"motor": "CS", "algorithm": "jacobi"}),
])
def test_the_first_row_holds_the_inputs_of_the_first_step(example, name, options):
    r = _run(_variant(example, name, **options))
    assert r["time"][0] == 0.0
    assert r["controller.voltage"][0] == pytest.approx(5.0)  # kp x 50 rad/s, the first sample
    assert r["motor.voltage"][0] == r["controller.voltage"][0]  # the connection, at t = 0 too
    assert r["motor.current"][0] == I_MAX  # 5 A asked for, clipped by the drive (was 0 A)
    assert r["controller.speed"][0] == r["motor.speed"][0] == 0.0
    # what the motor integrated over the first step: the row that ends it holds the same voltage
    first_end = np.flatnonzero(np.isclose(r["time"], 1e-3, rtol=1e-9, atol=0))[0]
    assert r["motor.voltage"][first_end] == r["motor.voltage"][0]


def test_the_first_row_of_an_algebraic_loop_is_its_solution(example):
    r = _run(_variant(example, "loop", feedthrough=False))
    v, w = r["motor.voltage"][0], r["motor.speed"][0]
    assert v == r["controller.voltage"][0] == pytest.approx(5.0)
    assert r["motor.current"][0] == pytest.approx(min(max((v - KE * w) / R, -I_MAX), I_MAX))


def test_event_rows_hold_the_inputs_in_force_at_the_event(example):
    """The current limit releases at about 43 ms, when a new voltage comes in at the start of a
    step: the event rows there hold that voltage, the one the motor integrates with over the step
    they begin, and every row's current is the drive's law of its own voltage and speed."""
    r = _run(_variant(example, "events"))
    t = r["time"]
    repeated = np.flatnonzero(np.diff(t) == 0) + 1  # the rows of an event: a time written again
    assert len(repeated) >= 1 and 0.04 < t[repeated[0]] < 0.045
    for row in repeated:
        if row + 1 < len(t) and t[row + 1] > t[row]:  # the last row at the event's time
            assert r["motor.voltage"][row] == r["motor.voltage"][row + 1]  # held over the next step
    demand = (r["motor.voltage"] - KE * r["motor.speed"]) / R
    np.testing.assert_allclose(r["motor.current"], np.clip(demand, -I_MAX, I_MAX), rtol=0, atol=1e-9)
