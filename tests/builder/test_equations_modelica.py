"""``deltafmi build model.mo``: Modelica files parsed and flattened by rumoca, translated into an
equation model and compiled by the same pipeline; built through the CLI and run by fmpy."""
import subprocess
import sys

import numpy as np
import pytest
from fmpy import simulate_fmu
from scipy.special import ellipk

pytest.importorskip("rumoca", reason="rumoca (the test extra) parses the Modelica files")

BALL = """\
model Ball "A ball bouncing with restitution"
  parameter Real g = 9.81 "gravity";
  parameter Real e = 0.8 "coefficient of restitution";
  parameter Real h0 = 1.0 "drop height";
  Real h(start = 1.0);
  Real v(start = 0.0);
  output Real height;
  output Integer n(start = 0);
initial equation
  h = h0;
  v = 0;
equation
  der(h) = v;
  der(v) = -g;
  height = h;
  when h <= 0 then
    reinit(v, -e*pre(v));
    n = pre(n) + 1;
  end when;
end Ball;
"""
PENDULUM = """\
model Pendulum "The Cartesian pendulum, index 3"
  parameter Real L = 1.0;
  parameter Real g = 9.81;
  parameter Real phi0 = 0.7;
  Real x(start = 0.6);
  Real y(start = -0.8);
  Real vx;
  Real vy;
  Real lambda;
  output Real px;
initial equation
  x = L*sin(phi0);
  vx = 0;
equation
  der(x) = vx;
  der(y) = vy;
  der(vx) = -lambda*x;
  der(vy) = -lambda*y - g;
  x^2 + y^2 = L^2;
  px = x;
end Pendulum;
"""


def _build(tmp_path, name, text):
    (tmp_path / f"{name}.mo").write_text(text)
    return subprocess.run([sys.executable, "-c", "from deltafmi.apps.cli import main; main()", "build", f"{name}.mo",
                           "-o", f"{name}.fmu"], cwd=tmp_path, capture_output=True, text=True, timeout=300)


def test_modelica_ball(tmp_path):
    result = _build(tmp_path, "ball", BALL)
    assert result.returncode == 0, result.stderr
    r = simulate_fmu(str(tmp_path / "ball.fmu"), fmi_type="ModelExchange", stop_time=2.0, output=["n", "height"],
                     relative_tolerance=1e-12, output_interval=1e-3)
    first = np.sqrt(2.0 / 9.81)
    exact = [first, first + 2.0 * 0.8 * np.sqrt(2.0 * 9.81) / 9.81]
    found = r["time"][1:][np.diff(r["n"]) == 1]
    assert np.max(np.abs(found[:2] - exact)) < 1e-9


def test_modelica_pendulum_is_reduced_and_keeps_its_period(tmp_path):
    result = _build(tmp_path, "pendulum", PENDULUM)
    assert result.returncode == 0, result.stderr
    period = 4.0 * ellipk(np.sin(0.35) ** 2) * np.sqrt(1.0 / 9.81)
    r = simulate_fmu(str(tmp_path / "pendulum.fmu"), fmi_type="CoSimulation", stop_time=1.5 * period,
                     output=["px"], output_interval=1e-3)
    k = np.argmin(np.abs(r["time"] - period))
    assert abs(r["px"][k] - np.sin(0.7)) < 1e-6  # back where it started after one period


def test_outside_the_subset_is_one_line(tmp_path):
    result = _build(tmp_path, "arrays", "model Arrays\n  Real x[2](each start = 1);\nequation\n"
                    "  der(x) = -x;\nend Arrays;\n")
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "the array x is outside the Modelica subset" in lines[0], result.stderr
