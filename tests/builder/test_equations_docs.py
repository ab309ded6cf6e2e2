"""The examples of docs/equations.md, from the guide's own text: each file is extracted, built into
an FMU and run, and its results checked against closed forms."""
import re
from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu

from deltafmi.builder.packager import build_fmu

DOC = Path(__file__).resolve().parents[2] / "docs" / "equations.md"


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("equations_guide")
    blocks = dict(re.findall(r"^\*\*`([\w.]+)`\*\*\n\n```python\n(.*?)^```", DOC.read_text(), flags=re.M | re.S))
    assert set(blocks) == {"spring.py", "rc.py", "ball.py"}
    for name, text in blocks.items():
        (folder / name).write_text(text)
    return folder


def _run(files, name, interface, **options):
    fmu = build_fmu(files / name, files / name.replace(".py", f"_{interface}.fmu"))
    return simulate_fmu(fmu, fmi_type=interface, output_interval=1e-4 if name != "rc.py" else 1e-6,
                        relative_tolerance=1e-12 if interface == "ModelExchange" else None, **options)


@pytest.mark.parametrize("interface", ["ModelExchange", "CoSimulation"])
def test_spring(files, interface):
    r = _run(files, "spring.py", interface, output=["position"])
    m, c, k, x0 = 1.0, 0.4, 40.0, 0.1
    wd, zeta_w = np.sqrt(k / m - (c / (2 * m)) ** 2), c / (2 * m)
    t = r["time"]
    exact = x0 * np.exp(-zeta_w * t) * (np.cos(wd * t) + zeta_w / wd * np.sin(wd * t))
    assert np.max(np.abs(r["position"] - exact)) < 1e-8 * x0


@pytest.mark.parametrize("interface", ["ModelExchange", "CoSimulation"])
def test_rc(files, interface):
    r = _run(files, "rc.py", interface, output=["vc"])
    exact = 5.0 * (1.0 - np.exp(-r["time"] / (1000.0 * 1e-6)))
    assert np.max(np.abs(r["vc"] - exact)) < 1e-8 * 5.0


def test_ball(files):
    r = _run(files, "ball.py", "ModelExchange", output=["bounces", "height"])
    g, e, h0 = 9.81, 0.7, 2.0
    first = np.sqrt(2 * h0 / g)
    exact = [first, first + 2 * e * np.sqrt(2 * g * h0) / g]
    found = r["time"][1:][np.diff(r["bounces"]) == 1]
    assert np.max(np.abs(found[:2] - exact)) < 1e-9
    assert np.min(r["height"]) > -1e-9
