"""The FMUs' Python side needs numpy and SUNDIALS only: neither fmpy nor scipy (issue 25).

A Python host with nothing but fmpy (and its numpy) used to fail on the DeltaRobot FMU ("No module
named 'scipy'"), and every FMU that integrates imported fmpy for its SUNDIALS binding. Here each
FMU's own boot code runs in a fresh ``python -I -S`` whose only third-party packages are numpy and
fmpy, Co-Simulation and Model Exchange, and must import neither and give exactly what it gives with
the full development environment. SUNDIALS itself comes from the FMU's ``resources/python/sundials``
when present (a portable FMU), else from fmpy's copy, else a clear error; its messages reach Python
logging, never stdout or stderr.
"""
from __future__ import annotations

import json
import math
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from conftest import MODEL_FILES, ROOT, unzip

#: every FMU of deltafmi/models: the flagship ones, and the contact ones (whose collision law calibrates
#: itself with deltafmi.physics.contact.dopri, no longer with scipy)
#: models whose sample is a QP solved by OSQP (which takes scipy.sparse matrices): their host's Python
#: needs osqp and scipy (a --portable FMU carries them); their tests are tests/models/test_mpc_controller.py
#: and tests/models/test_insertion_mpc.py
NEEDS_SCIPY = ("mpc_controller.py", "insertion_mpc.py")
SCIPY_FREE = [source for source in MODEL_FILES if source not in NEEDS_SCIPY]

_RUN = r'''
import json, math, runpy, sys
resources, out = sys.argv[1], sys.argv[2]
sys.path += sys.argv[3:]
load = runpy.run_path(resources + "/deltafmi_boot.py")["load"]
rows = {}
for fmu_type, name in ((1, "cs"), (0, "me")):
    instance = load(resources, "probe", "", fmu_type)
    instance.enter_initialization(0.0, math.nan, math.nan)
    instance.exit_initialization()
    rows[name] = []
    h = instance.component_class.default_experiment.stop / 20  # across the whole default experiment
    for k in range(20):
        if fmu_type == 1:
            instance.do_step(k * h, h)
        else:
            instance.evaluate(k * h)
        rows[name].append([float(x) for x in instance.component._real])
    instance.terminate()
    instance.free()
loaded = sorted({n.split(".")[0] for n in sys.modules if n.split(".")[0] in ("fmpy", "scipy")})
json.dump({"rows": rows, "loaded": loaded}, open(out, "w"))
'''


def _site_with(tmp: Path, *packages: str) -> Path:
    """A site directory holding only ``packages`` (symlinks to the installed ones, with their
    wheels' bundled-library folders): a stand-in for an environment where nothing else is installed."""
    import importlib.util
    site = tmp / "site"
    site.mkdir(parents=True, exist_ok=True)
    for name in packages:
        location = Path(importlib.util.find_spec(name).origin).parent
        for path in (location, location.with_name(f"{name}.libs")):
            if path.exists() and not (site / path.name).exists():
                (site / path.name).symlink_to(path)
    return site


def _run(resources: Path, out: Path, *paths: Path) -> dict:
    result = subprocess.run([sys.executable, "-I", "-S", "-c", _RUN, str(resources), str(out), *map(str, paths)],
                            capture_output=True, text=True, timeout=600)
    assert result.returncode == 0, result.stderr[-3000:]
    assert result.stdout == "", result.stdout[-2000:]  # the FMU prints nothing
    return json.loads(out.read_text())


@pytest.fixture(scope="module")
def full_site() -> list[Path]:
    """The development environment's site directories (fmpy, scipy, ... all importable)."""
    import site
    return [Path(p) for p in site.getsitepackages()] + [ROOT]


@pytest.mark.parametrize("source", SCIPY_FREE)
def test_fmu_runs_with_numpy_and_fmpy_only(source, build_fmu_from_src, full_site, tmp_path):
    resources = unzip(build_fmu_from_src(source), tmp_path / "fmu") / "resources"
    reference = _run(resources, tmp_path / "full.json", *full_site)
    assert reference["loaded"] == [], f"{source} imported {reference['loaded']} with everything installed"
    bare = _run(resources, tmp_path / "bare.json", _site_with(tmp_path, "numpy", "fmpy"))
    assert bare["loaded"] == []
    for kind in ("cs", "me"):
        got, want = np.array(bare["rows"][kind]), np.array(reference["rows"][kind])
        assert np.isfinite(want).all()
        np.testing.assert_array_equal(got, want)  # the same code and libraries: bit for bit
    cs = np.array(reference["rows"]["cs"])
    if source != "delta_controller.py":  # with its inputs at zero, the controller holds still
        assert np.ptp(cs, axis=0).max() > 0.0, "the run must exercise something"


_SOLVE = r'''
import json, logging, math, sys
sys.path[:0] = sys.argv[2:]
records = []
class Keep(logging.Handler):
    def emit(self, record):
        records.append([record.name, record.levelname, record.getMessage()])
logging.getLogger("deltafmi").addHandler(Keep())
logging.getLogger("deltafmi").setLevel(logging.DEBUG)
import numpy as np
from deltafmi.runtime import sundials
from deltafmi.runtime.cvode import Cvode, CvodeError
decay = Cvode(lambda t, x, xd: xd.__setitem__(0, -x[0]), np.array([1.0]), 0.0, rtol=1e-10, atol=1e-12)
decay.advance(1.0)
def blow_up(t, x, xd):
    xd[0] = x[0] * x[0]  # x = 1 / (1 - t): no solution past t = 1
error = ""
try:
    Cvode(blow_up, np.array([1.0]), 0.0, rtol=1e-10, atol=1e-12).advance(2.0)
except CvodeError as exc:
    error = str(exc)
json.dump({"directory": str(sundials.library_directory()), "decay": float(decay.x[0]), "error": error,
           "records": records, "routed": sundials.ROUTED,
           "loaded": sorted({n.split(".")[0] for n in sys.modules if n.split(".")[0] in ("fmpy", "scipy")})},
          open(sys.argv[1], "w"))
'''


def _solve(tmp: Path, *paths: Path) -> tuple[subprocess.CompletedProcess, Path]:
    out = tmp / "solve.json"
    result = subprocess.run([sys.executable, "-I", "-S", "-c", _SOLVE, str(out), *map(str, paths)],
                            capture_output=True, text=True, timeout=600)
    return result, out


def test_sundials_messages_go_to_logging_not_to_stdout(tmp_path):
    result, out = _solve(tmp_path, ROOT, _site_with(tmp_path, "numpy", "fmpy"))
    assert result.returncode == 0, result.stderr[-3000:]
    # SUNDIALS' default logger prints warnings on stdout and errors on stderr: none may show
    assert result.stdout == "" and result.stderr == ""
    found = json.loads(out.read_text())
    assert found["routed"] and found["loaded"] == []
    assert found["decay"] == pytest.approx(math.exp(-1.0), rel=1e-8)
    warnings = [r for r in found["records"] if r[:2] == ["deltafmi.solver", "WARNING"]]
    errors = [r for r in found["records"] if r[:2] == ["deltafmi.solver", "ERROR"]]
    # CVODE warns (at most mxhnil = 10 times, then once more that it stops) that t + h = t near t = 1
    assert any("t + h = t" in r[2] and "Internal t = 0.99999" in r[2] for r in warnings), found["records"]
    assert len(errors) == 1 and "At t = 0.99999" in errors[0][2]
    assert "CVODE failed" in found["error"] and errors[0][2].split(": ", 1)[1] in found["error"]


def test_sundials_from_the_fmu_else_fmpy_else_a_clear_error(build_fmu_from_src, tmp_path):
    resources = unzip(build_fmu_from_src("oscillator.py"), tmp_path / "fmu") / "resources"
    numpy_only = _site_with(tmp_path / "numpy", "numpy")
    # neither bundled nor fmpy installed: one clear ImportError naming both places and the way out
    result, _ = _solve(tmp_path, resources / "python", numpy_only)
    assert result.returncode != 0 and result.stdout == ""
    last = result.stderr.strip().splitlines()[-1]
    assert last.startswith("deltafmi.runtime.sundials.SundialsNotFound: the SUNDIALS libraries (CVODE)")
    assert str((resources / "python" / "sundials").resolve()) in last and "pip install fmpy" in last and "--portable" in last
    # bundled the way a portable FMU carries them: found there, without fmpy
    import fmpy
    bundled = resources / "python" / "sundials"
    shutil.copytree(Path(fmpy.__file__).parent / "sundials" / "x86_64-linux", bundled)
    result, out = _solve(tmp_path, resources / "python", numpy_only)
    assert result.returncode == 0 and result.stdout == "" and result.stderr == "", result.stderr[-3000:]
    found = json.loads(out.read_text())
    assert Path(found["directory"]) == bundled.resolve() and found["loaded"] == []
    assert found["decay"] == pytest.approx(math.exp(-1.0), rel=1e-8)
    # the bundled copy comes first even where fmpy is installed
    result, out = _solve(tmp_path, resources / "python", _site_with(tmp_path / "both", "numpy", "fmpy"))
    assert result.returncode == 0, result.stderr[-3000:]
    assert Path(json.loads(out.read_text())["directory"]) == bundled.resolve()


@pytest.mark.parametrize("e, p", [(0.5, 3.0), (0.8, 1.5), (0.3, 1.0), (0.95, 3.0)])
def test_collision_law_calibration_agrees_with_scipy(e, p):
    """The calibration integrates with our own Dormand-Prince now; scipy's DOP853, given the chi it
    found, must rebound with the same restitution after the same duration."""
    from scipy.integrate import solve_ivp
    from deltafmi.physics.contact.collision_law import _end_function, calibrate

    c = calibrate(e, p)
    q = 0.5 * (p - 1.0)

    def rhs(_t, y):
        s = max(y[0], 0.0)
        return [y[1], -max(s ** p + c.chi * s ** q * y[1], 0.0)]

    def force_zero(_t, y):
        return _end_function(y[0], y[1], p - q, c.chi)

    force_zero.terminal, force_zero.direction = True, -1
    sol = solve_ivp(rhs, (0.0, 20.0), [0.0, 1.0], method="DOP853", rtol=1e-12, atol=1e-14, events=force_zero)
    assert -sol.y_events[0][0][1] == pytest.approx(e, rel=1e-9)
    assert sol.t_events[0][0] == pytest.approx(c.tau, rel=1e-9)
    assert c.restitution == pytest.approx(e, rel=1e-12)
