"""Nonlinear algebraic loops: torn and solved by Newton in the generated kernels, against scipy."""
import numpy as np
from fmpy import simulate_fmu
from scipy.integrate import solve_ivp
from scipy.optimize import fsolve

from deltafmi.builder.packager import build_fmu

MODEL = '''\
from deltafmi.component import Experiment, Output, Parameter
from deltafmi.runtime.equations import EquationComponent, Real, der, sin


class Loop(EquationComponent):
    """A state driven through a nonlinear algebraic loop in y and z."""

    default_experiment = Experiment(start=0.0, stop=2.0, step=1e-3, tolerance=1e-10)
    a = Parameter(0.5)
    s = Real(1.0)
    y = Real(0.5)
    z = Real(0.0)
    out = Output()

    def equations(self):
        return [der(self.s) == -self.y,
                self.y ** 3 + self.y + self.a * sin(self.z) == self.s,
                self.z + self.a * self.y ** 3 == 0.2,
                self.out == self.y]
'''


def _algebraic(s, a=0.5):
    return fsolve(lambda w: [w[0] ** 3 + w[0] + a * np.sin(w[1]) - s, w[1] + a * w[0] ** 3 - 0.2],
                  [0.5, 0.0], xtol=1e-12)


def test_nonlinear_loop(tmp_path):
    (tmp_path / "loop.py").write_text(MODEL)
    fmu = build_fmu(tmp_path / "loop.py", tmp_path / "Loop.fmu")
    reference = solve_ivp(lambda t, s: [-_algebraic(s[0])[0]], (0.0, 2.0), [1.0], rtol=1e-12, atol=1e-14,
                          dense_output=True)
    for interface in ("ModelExchange", "CoSimulation"):
        r = simulate_fmu(fmu, fmi_type=interface, output=["out"], output_interval=1e-2,
                         relative_tolerance=1e-12 if interface == "ModelExchange" else None)
        expected = [_algebraic(s)[0] for s in reference.sol(r["time"])[0]]
        assert np.max(np.abs(r["out"] - expected)) < 1e-7, interface
