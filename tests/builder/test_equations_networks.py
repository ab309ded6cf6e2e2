"""Acausal networks: the components guide's DC motor from connected parts against the guide's
hand-written motor (its code block in docs/components.md) and against closed forms."""
import re
from pathlib import Path

import numpy as np
from fmpy import simulate_fmu
from scipy.linalg import expm

from deltafmi.builder.packager import build_cached, build_fmu

DOC = Path(__file__).resolve().parents[2] / "docs" / "components.md"
R, KT, KE, J, B = 1.0, 0.05, 0.05, 1e-4, 1e-4
VOLTS = 1.5  # below R i_max = 2 V: the guide's drive never limits the current


def _run(fmu, **start):
    result = simulate_fmu(fmu, fmi_type="ModelExchange", stop_time=0.5, output_interval=1e-3,
                          start_values={"voltage": VOLTS, **start}, relative_tolerance=1e-12,
                          output=["speed", "current"])
    return result["time"], result["speed"], result["current"]


def test_motor_from_parts_equals_the_guides_motor(tmp_path):
    text = DOC.read_text()
    source = re.search(r"^\*\*`dc_motor.py`\*\*\n\n```python\n(.*?)^```", text, flags=re.M | re.S).group(1)
    (tmp_path / "dc_motor.py").write_text(source)
    t, w_hand, i_hand = _run(build_fmu(tmp_path / "dc_motor.py", tmp_path / "DCMotor.fmu"))
    t2, w, i = _run(build_cached("DCMotorCircuit"))
    assert np.array_equal(t, t2)
    w_inf, tau = KT * VOLTS / (KT * KE + B * R), J * R / (KT * KE + B * R)
    exact = w_inf * (1.0 - np.exp(-t / tau))
    assert np.max(np.abs(w - w_hand)) < 1e-9 * w_inf
    assert np.max(np.abs(i - i_hand)) < 1e-9 * VOLTS / R
    assert np.max(np.abs(w - exact)) < 1e-9 * w_inf
    assert np.allclose(i, (VOLTS - KE * w) / R, rtol=0.0, atol=1e-13)


def test_motor_with_inductance_follows_the_linear_closed_form():
    L = 1e-3
    t, w, i = _run(build_cached("DCMotorCircuitL"), L=L)
    # x = [w, i]: J w' = kt i - b w, L i' = V - R i - ke w, from rest
    A = np.array([[-B / J, KT / J], [-KE / L, -R / L]])
    forcing = np.array([0.0, VOLTS / L])
    steady = -np.linalg.solve(A, forcing)
    exact = np.array([steady - expm(A * tk) @ steady for tk in t])
    assert np.max(np.abs(w - exact[:, 0])) < 1e-8 * np.max(np.abs(exact[:, 0]))
    assert np.max(np.abs(i - exact[:, 1])) < 1e-8 * np.max(np.abs(exact[:, 1]))
