"""The assembly FMUs of issue 27 in a stranger's hands: what the tests parametrized over models
(test_portable_fmus, test_python_hosts, test_fmi3_export) do not reach.

- fmpy's validation and ``deltafmi validate`` of the FMI 2.0 builds no other test validates;
- the plain C host (tests/c_host/host.c, no Python in its process) on DeltaWristPeg and
  AssemblyController, CS and ME, against the same calls made from fmpy (tests/host_loops.py);
- the portable DeltaWristPeg where no Python exists, against the plain FMU here;
- fmi2Reset: a second run equal to the first (DeltaWristPeg's latched success, the sampled
  controller, the EKF, the MPC's OSQP solver); AssemblyController's FMI 3.0 Clock in a plain-C
  Scheduled Execution host;
- another CPython (3.12 or 3.13) with nothing but fmpy running the FMUs built here.

Numbers that must agree are compared bit for bit (tolerance 0): both sides make the same FMI calls
into the same binary and Python code, so any difference is the host process, not the algorithm.
The other CPython runs the same kernels and numpy arithmetic; test_python_hosts' relative
tolerance (1e-6) is kept for a numpy version that sums in another order.

The MPC FMUs carry their own deltafmi.physics.control (imported at module level, so the FMU's trace
packs it), copy their OSQP solver into an FMU state by setting up a new one, and name their
shipped linear model by default.
"""
from __future__ import annotations

import shutil
import site
import subprocess
import sys
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from click.testing import CliRunner
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

from conftest import ROOT, clean_env, unzip
from deltafmi.apps.cli import main
from deltafmi.builder.packager import build_cached
from host_loops import co_simulation, host_rows, me_env, model_exchange_euler, run_c_host
from test_fmi3_binary import host3  # noqa: F401 (fixture)
from test_portable_fmus import no_python, workspace  # noqa: F401 (fixtures)
from test_python_hosts import BUILDER, TOLERANCE, _deviation, _scalarized, _simulate, session_fmpy_venv

EXAMPLES = ROOT / "scenarios"
#: the linear model each MPC FMU reads, shipped in its resources (`deltafmi build X --resource F`)
RESOURCES = {"MpcController": [EXAMPLES / "mpc_press_model.npz"],
             "InsertionMpc": [EXAMPLES / "peg_in_hole_mpc_model.npz"]}
#: string parameter -> value that points an MPC FMU at its shipped model
STRINGS = {"MpcController": {"linear_model": "mpc_press_model.npz"}, "InsertionMpc": {}}
H = 1e-3  # s: every FMU's default step and the controllers' sample period
#: model -> (printed outputs, (stop, step) in CS, (stop, step) in ME). The peg, with no torques,
#: falls into the hole (depth -20 mm -> 38 mm in 0.14 s) and bounces on its bottom; the
#: controller runs its insertion program on constant (zero) measurements.
C_HOST = {"DeltaWristPeg": (["z[3]", "tip[1]", "tip[3]", "depth", "contact_force[1]", "contact_force[3]",
                             "residual", "energy"], (0.2, 1e-3), (0.2, 1e-4)),
          "AssemblyController": (["u[1]", "u[2]", "u[3]", "tau[1]", "tip_est[3]", "r_ref[3]", "depth_ref",
                                  "sigma_min"], (0.05, 1e-3), (0.05, 5e-4))}


def fmu_of(model: str, **options) -> Path:
    """The packaged ``model``'s FMU (with its shipped linear model) from the build cache."""
    return build_cached(model, resources=RESOURCES.get(model, ()), **options)


def value_references(fmu: Path, names: list[str]) -> list[int]:
    """The value references of the FMI 2.0 variables ``names``."""
    vr = {v.name: v.valueReference for v in fmpy.read_model_description(str(fmu)).modelVariables}
    return [vr[n] for n in names]


@pytest.fixture(scope="module")
def unpacked(workspace):  # noqa: F811 (a fixture imported above)
    """``unpacked(model, portable=False) -> Path``: the FMU extracted once, where a hidden-Python
    host still sees it."""
    done: dict = {}

    def get(model: str, portable: bool = False) -> Path:
        if (model, portable) not in done:
            folder = workspace / f"{model}-{'portable' if portable else 'plain'}"
            done[model, portable] = unzip(fmu_of(model, portable=portable), folder)
        return done[model, portable]

    return get


# --- 1. validation ---------------------------------------------------------------------------

@pytest.mark.parametrize("model", ["AssemblyController", "MpcController", "InsertionMpc"])
def test_fmi2_build_validates_in_fmpy_and_the_cli(model):
    """(FMI 3.0 builds: test_fmi3_export; DeltaWrist, DeltaWristPeg and the estimators' FMI 2.0
    builds: their own tests.)"""
    fmu = fmu_of(model)
    assert validate_fmu(str(fmu)) == []
    result = CliRunner().invoke(main, ["validate", str(fmu)])
    assert result.exit_code == 0, result.output
    assert "OK (instantiated and freed once)" in result.output, result.output


# --- 2. the plain C host ---------------------------------------------------------------------

@pytest.mark.parametrize("mode", ["cs", "me"])
@pytest.mark.parametrize("model", list(C_HOST))
def test_c_host_gives_what_fmpy_gives(model, mode, unpacked, c_host):
    directory = unpacked(model)
    names, cs, me = C_HOST[model]
    stop, step = cs if mode == "cs" else me
    vrs = value_references(directory, names)
    rows = host_rows(run_c_host(c_host, directory, mode, stop, step, *vrs, env=me_env(directory)).stdout)
    loop = co_simulation if mode == "cs" else model_exchange_euler
    assert rows.shape == (round(stop / step) + 1, 1 + len(names))
    np.testing.assert_array_equal(rows, loop(directory, stop, step, vrs))
    if model == "DeltaWristPeg":  # it fell into the hole and met its bottom
        depth = rows[:, 1 + names.index("depth")]
        assert depth[0] == pytest.approx(-0.02, abs=1e-12) and depth.max() > 0.03
    else:
        assert np.ptp(rows[:, 1]) > 1.0  # N m: the program moved the torques


def test_controller_samples_at_the_same_instants_in_cs_and_me(unpacked, c_host):
    """ME takes the sample at t in the event at t; CS shows it after the step [t, t + h): the ME row
    at k ms is the CS row at k + 1 ms, bit for bit (the same kernel on the same inputs)."""
    directory = unpacked("AssemblyController")
    names, (stop, h), (_, h_me) = C_HOST["AssemblyController"]
    vrs = value_references(directory, names)
    cs = host_rows(run_c_host(c_host, directory, "cs", stop, h, *vrs).stdout)
    me = host_rows(run_c_host(c_host, directory, "me", stop, h_me, *vrs, env=me_env(directory)).stdout)
    on_the_grid = me[::round(h / h_me)]
    np.testing.assert_array_equal(on_the_grid[:-1, 1:], cs[1:, 1:])


# --- 3. portable, no Python ------------------------------------------------------------------

@pytest.mark.parametrize("mode", ["cs", "me"])
def test_portable_peg_plant_without_python_equals_the_plain_fmu(mode, no_python, unpacked, c_host):  # noqa: F811
    names, cs, me = C_HOST["DeltaWristPeg"]
    stop, step = cs if mode == "cs" else me
    portable, plain = unpacked("DeltaWristPeg", portable=True), unpacked("DeltaWristPeg")
    args = [stop, step, *value_references(plain, names)]
    md = fmpy.read_model_description(str(portable))
    hidden = subprocess.run([*no_python, str(c_host), str(portable), "DeltaWristPeg", md.guid, mode, *map(str, args)],
                            capture_output=True, text=True, env=clean_env(**me_env(portable)),
                            timeout=300)
    assert hidden.returncode == 0, f"exit {hidden.returncode}:\n{hidden.stderr[-3000:]}"
    here = host_rows(run_c_host(c_host, plain, mode, *args, env=me_env(plain)).stdout)
    np.testing.assert_array_equal(host_rows(hidden.stdout), here)
    # the bar test_portable_fmus sets the DeltaRobot (measured: 20.0 MB)
    assert fmu_of("DeltaWristPeg", portable=True).stat().st_size <= 40e6


def test_portable_mpc_carries_osqp_and_scipy_and_runs_without_python(no_python, unpacked, c_host):  # noqa: F811
    fmu = fmu_of("MpcController", portable=True)
    with zipfile.ZipFile(fmu) as archive:
        names = archive.namelist()
    site_packages = "resources/python/site-packages/"
    for part in ("osqp/", "scipy/sparse/", "scipy/linalg/"):
        assert any(n.startswith(site_packages + part) for n in names), part
    carried = {n[len(site_packages):].split("/")[0] for n in names if n.startswith(site_packages) and n.count("/") > 3}
    licensed = {n.split("/")[2] for n in names if n.startswith("documentation/licenses/") and n.count("/") > 2}
    unlicensed = {p for p in carried if not p.endswith(".libs")} - licensed
    assert not unlicensed, f"bundled without a licence: {sorted(unlicensed)}"
    directory = unpacked("MpcController", portable=True)
    md = fmpy.read_model_description(str(directory))
    vrs = value_references(directory, ["u[1]", "predicted_force"])
    hidden = subprocess.run([*no_python, str(c_host), str(directory), "MpcController", md.guid, "cs", "0.02", "0.004",
                             *map(str, vrs)], capture_output=True, text=True, env=clean_env(), timeout=300)
    assert hidden.returncode == 0, hidden.stderr[-3000:]
    here = run_c_host(c_host, directory, "cs", 0.02, 0.004, *vrs).stdout
    assert hidden.stdout == here


# --- 4. fmi2Reset ----------------------------------------------------------------------------

def run_slave(slave: FMU2Slave, md, steps: int, inputs: dict, strings: dict) -> tuple[np.ndarray, list[str]]:
    """Set ``strings`` and the inputs at t = 0, initialize at t = 0, then ``steps`` steps of H with
    ``inputs[name][k]`` set before step k; a row of every output (Real, then Integer; not the wall-clock solve_time) at
    each communication point."""
    vr = {v.name: v.valueReference for v in md.modelVariables}
    reals = [v for v in md.modelVariables if v.causality == "output" and v.type == "Real" and v.name != "solve_time"]
    ints = [v for v in md.modelVariables if v.causality == "output" and v.type == "Integer"]
    if strings:
        slave.setString([vr[k] for k in strings], list(strings.values()))
    if inputs:  # the sample at t = 0 is taken in initialization: on the inputs at t = 0
        slave.setReal([vr[n] for n in inputs], [values[0] for values in inputs.values()])
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    rows = []
    for k in range(steps + 1):
        rows.append([*slave.getReal([v.valueReference for v in reals]),
                     *slave.getInteger([v.valueReference for v in ints])])
        if k < steps:
            if inputs:
                slave.setReal([vr[n] for n in inputs], [values[k] for values in inputs.values()])
            slave.doStep(k * H, H)
    return np.array(rows), [v.name for v in reals + ints]


def run_reset_run(model: str, steps: int, inputs: dict) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """(first run, run after fmi2Reset, output names) of one instance."""
    fmu = fmu_of(model)
    md = fmpy.read_model_description(str(fmu))
    slave = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="reset")
    slave.instantiate()
    first, names = run_slave(slave, md, steps, inputs, STRINGS.get(model, {}))
    slave.terminate()
    slave.reset()
    second, _ = run_slave(slave, md, steps, inputs, STRINGS.get(model, {}))
    slave.terminate()
    slave.freeInstance()
    shutil.rmtree(slave.unzipDirectory, ignore_errors=True)
    return first, second, names


@pytest.fixture(scope="module")
def falling_peg() -> dict:
    """DeltaWristPeg, no torques, 150 ms: its first run and the run after fmi2Reset."""
    first, second, names = run_reset_run("DeltaWristPeg", 150, {})
    return {"first": first, "second": second, "names": names}


def test_reset_peg_plant_runs_again_and_unlatches_success(falling_peg):
    first, second, names = falling_peg["first"], falling_peg["second"], falling_peg["names"]
    success = names.index("success")
    assert first[0, success] == 0 and first[-1, success] == 1  # depth passed target_depth (20 mm)
    np.testing.assert_array_equal(second, first)


def measurements(model: str, peg: dict) -> dict:
    """``model``'s inputs (name -> one value per step) from the falling peg's outputs: servo and
    wrist angles and rates, the F/T sensor (the torques stay zero, as they were)."""
    plant = {name: peg["first"][:, i] for i, name in enumerate(peg["names"])}
    if model == "AssemblyController":
        sources = {**{f"{n}[{i}]": f"{n}[{i}]" for n in ("y", "yd", "qw", "qwd") for i in (1, 2, 3)},
                   **{f"ft[{i}]": f"ft_sensor[{i}]" for i in range(1, 7)}}
    else:
        sources = {f"{n}[{i}]": f"{n}[{i}]" for n in ("y", "qw") for i in (1, 2, 3)}
    return {name: plant[source] for name, source in sources.items()}


@pytest.fixture(scope="module")
def on_the_falling_peg(falling_peg):
    """``get(model) -> (first run, run after fmi2Reset, output names, inputs)``, fed the peg's fall."""
    done: dict = {}

    def get(model: str) -> tuple:
        if model not in done:
            inputs = measurements(model, falling_peg)
            done[model] = (*run_reset_run(model, 150, inputs), inputs)
        return done[model]

    return get


@pytest.mark.parametrize("model", ["AssemblyController", "PegEstimator"])
def test_reset_controller_and_estimator_on_the_falling_peg(model, on_the_falling_peg):
    first, second, names, _ = on_the_falling_peg(model)
    moved = names.index({"AssemblyController": "u[3]", "PegEstimator": "tip[3]"}[model])
    assert np.ptp(first[:, moved]) > 1e-3  # N m, m: it followed the peg's fall
    np.testing.assert_array_equal(second, first)


def test_scheduled_execution_in_plain_c_gives_the_co_simulation_torques(on_the_falling_peg, host3,  # noqa: F811
                                                                          tmp_path):
    """The FMI 3.0 build in host3's Scheduled Execution (the Clock's partition activated at
    t_k = k ms with the peg's measurements at t_k) gives the servo and wrist torques that the FMI 2.0
    build gives in Co-Simulation after the step from t_k, bit for bit."""
    first, _, names, inputs = on_the_falling_peg("AssemblyController")
    directory = unzip(fmu_of("AssemblyController", fmi_version=3), tmp_path / "fmu")
    md = fmpy.read_model_description(str(directory))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    table = tmp_path / "inputs.txt"
    np.savetxt(table, np.column_stack(list(inputs.values()))[:-1], fmt="%.17g")  # y, yd, qw, qwd, ft in order
    done = subprocess.run([str(host3), str(directory), "AssemblyController", md.guid, "se", str(vr["sample"]), "150",
                           str(table), *(f"{vr[n]}:{k}" for n, k in (("y", 3), ("yd", 3), ("qw", 3), ("qwd", 3),
                                                                      ("ft", 6))),
                           "--", f"{vr['u']}:3", f"{vr['tau']}:3"], capture_output=True, text=True, env=clean_env(),
                          timeout=300)
    assert done.returncode == 0, done.stderr[-3000:]
    rows = host_rows("\n".join(done.stdout.split()[2:-1]))
    torques = [names.index(f"{n}[{i}]") for n in ("u", "tau") for i in (1, 2, 3)]
    assert np.array_equal(rows[:, 0], np.arange(150) * H)
    np.testing.assert_array_equal(rows[:, 1:], first[1:, torques])


def test_reset_mpc_rebuilds_its_solver():
    """Servo angles held at the linearization's, the wrist asked 11 mm lower: OSQP's warm start
    of the first run must not leak into the second."""
    y0 = np.load(EXAMPLES / "mpc_press_model.npz")["y0"]
    inputs = {**{f"y[{i}]": np.full(41, y0[i - 1]) for i in (1, 2, 3)}, "r[3]": np.full(41, -1.06)}
    first, second, names = run_reset_run("MpcController", 40, inputs)
    assert np.ptp(first[:, names.index("u[1]")]) > 1.0
    np.testing.assert_array_equal(second, first)


# --- the MPC FMUs where deltafmi is not installed, and their FMU state -------------------------

_WITHOUT_DELTAFMI = r"""
import sys
sys.path += sys.argv[2:]  # the site directories, without their .pth hooks (deltafmi's editable install)
try:
    import deltafmi
    sys.exit("deltafmi is importable: " + deltafmi.__file__)
except ImportError:
    pass
from fmpy import simulate_fmu
simulate_fmu(sys.argv[1], stop_time=0.01, output_interval=1e-3, start_values=dict(STRINGS))
print("ran")
"""


@pytest.mark.parametrize("model", ["MpcController", "InsertionMpc"])
def test_mpc_fmu_runs_in_a_python_with_fmpy_osqp_scipy_but_no_deltafmi(model, tmp_path):
    script = _WITHOUT_DELTAFMI.replace("dict(STRINGS)", repr(STRINGS[model]))
    run = subprocess.run([sys.executable, "-S", "-c", script, str(fmu_of(model)), *site.getsitepackages()],
                         capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert run.returncode == 0 and run.stdout.strip().endswith("ran"), run.stdout[-2000:] + run.stderr[-2000:]


@pytest.mark.parametrize("model", ["MpcController", "InsertionMpc"])
def test_mpc_fmu_state_restores_the_run(model):
    """Save the state after 5 steps, run 5 more, restore, run the 5 again: the same outputs."""
    fmu = fmu_of(model)
    md = fmpy.read_model_description(str(fmu))
    assert md.coSimulation.canGetAndSetFMUstate
    slave = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)),
                      modelIdentifier=md.coSimulation.modelIdentifier)
    outputs = [v.valueReference for v in md.modelVariables if v.causality == "output" and v.type == "Real"
               and v.name != "solve_time"]
    slave.instantiate()
    runs = []
    try:
        run_slave(slave, md, 5, {}, STRINGS[model])
        state = slave.getFMUstate()
        for _ in range(2):
            for k in range(5, 10):
                slave.doStep(k * H, H)
            runs.append(slave.getReal(outputs))
            slave.setFMUstate(state)
        slave.freeFMUstate(state)
        slave.terminate()
    finally:
        slave.freeInstance()
        shutil.rmtree(slave.unzipDirectory, ignore_errors=True)
    assert runs[0] == runs[1]


# --- 5. another CPython ----------------------------------------------------------------------

def test_another_cpython_with_only_fmpy_gives_the_builders_results(tmp_path, tmp_path_factory):
    """A fresh virtual environment of CPython 3.13 (else 3.12) with nothing but fmpy (this session's,
    which tests/builder/test_python_hosts.py uses too) runs the plain FMUs built here (DeltaWrist as
    FMI 2.0 and 3.0, DeltaWristPeg, AssemblyController) in CS and ME."""
    python, why = None, "no CPython 3.12 or 3.13"
    for version in ("3.13", "3.12"):
        if version != BUILDER:
            python, why = session_fmpy_venv(version, tmp_path_factory)
            if python is not None:
                break
    if python is None:
        pytest.skip(why)
    fmus = [fmu_of("DeltaWrist"), fmu_of("DeltaWrist", fmi_version=3), fmu_of("DeltaWristPeg"),
            fmu_of("AssemblyController")]
    reference, _ = _simulate(Path(sys.executable), fmus, tmp_path / "builder.json")
    results, log = _simulate(python, fmus, tmp_path / "host.json")
    version = subprocess.run([str(python), "-c", "import sys; print(sys.version.split()[0])"], capture_output=True,
                             text=True, check=True).stdout.strip()
    failures = []
    for key, expected in reference.items():
        if key == "finder":
            continue
        got = results[key]
        if isinstance(got, str) or isinstance(expected, str):
            failures.append(f"{key}: builder {str(expected)[:300]}, host {str(got)[:300]}")
        elif _deviation(_scalarized(expected), _scalarized(got)) > TOLERANCE:
            failures.append(f"{key}: deviates by {_deviation(_scalarized(expected), _scalarized(got)):.3g}")
    assert not failures, f"CPython {version}:\n" + "\n".join(failures) + f"\n{log[-3000:]}"
