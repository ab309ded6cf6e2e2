"""The MpcController FMU in closed loop with the DeltaRobotContact FMU (mpc_press.yaml), beside the
impedance controller: its model made by ``deltafmi linearize``, its input and force limits kept."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master

ROOT = Path(__file__).resolve().parents[2]
K_SURFACE = 2e5      # N/m, the table's contact spring in mpc_press.yaml
PAYLOAD_WEIGHT = 0.5 * 9.81  # N, the payload neither controller knows
U_MAX, F_MAX = 22.0, 25.0
#: the MPC's force prediction is its linear map from servo angles to the gap times K: exact to second
#: order in the distance from the linearization (1.1 mm above the pressed pose); the curvature of
#: the wrist height in the servo angles (~1/l1 = 2.4 1/m) gives 0.5 x 2.4 x (1.1 mm)^2 = 1.5e-6 m,
#: x K = 0.3 N: the force limit and target hold to that
FORCE_TOLERANCE = 0.3


@pytest.fixture(scope="module")
def linear_model(tmp_path_factory) -> Path:
    """The plant linearized just above the touching height, by the CLI as the scenario says."""
    base = tmp_path_factory.mktemp("mpc") / "mpc_press_linear"
    result = CliRunner().invoke(main, ["linearize", "DeltaRobotContact", "--set", "z0=0,0,-1.049", "--rest",
                                       "--free", "u", "-u", "u", "-u", "f", "-y", "y", "-y", "yd", "-y", "z",
                                       "-y", "zd", "-q", "-o", str(base)])
    assert result.exit_code == 0, result.output
    return base.with_suffix(".npz")


def run_press(folder: Path, linear_model: Path, force: float = 20.0, impedance: bool = True) -> dict:
    spec = yaml.safe_load((ROOT / "scenarios" / "mpc_press.yaml").read_text())
    mpc = spec["components"]["mpc"]
    mpc["resources"] = [str(linear_model)]  # into the FMU: read from there, whatever the folder
    mpc["parameters"].update(linear_model=linear_model.name, force=force)
    if not impedance:
        for name in ("impedance", "impedance_plant"):
            del spec["components"][name]
        spec["connections"] = [c for c in spec["connections"] if "impedance" not in c["from"] + c["to"]]
        spec["outputs"] = [o for o in spec["outputs"] if "impedance" not in o]
    path = folder / "mpc_press.yaml"
    path.write_text(yaml.safe_dump(spec))
    out = path.with_suffix(".csv")
    Master(resolve_system(load_scenario(path)), result=out).run()
    return columns(out)


def settling(t: np.ndarray, fn: np.ndarray, target: float, band: float) -> float:
    """Time after first contact until fn stays within band of target."""
    outside = np.flatnonzero(np.abs(fn - target) > band)
    return float(t[outside[-1] + 1] - t[np.argmax(fn > 0.0)])


def test_mpc_presses_within_its_limits_beside_the_impedance_controller(tmp_path, linear_model):
    """MPC: |u| <= 22 N m (active during the fast move), peak force <= 25 N, resting at the 20 N
    commanded despite the payload (offset-free). Impedance, same reference: rests at
    (10 N + 1000 N/m x 1 cm + m g) / (1 + 1000/2e5) (its stiffness in series with the table's),
    after a peak above the MPC's force limit."""
    c = run_press(tmp_path, linear_model)
    t = c["time"]
    u = np.abs(np.column_stack([c[f"mpc.u[{i}]"] for i in (1, 2, 3)]))
    assert u.max() <= U_MAX
    assert u.max() == pytest.approx(U_MAX, abs=1e-9)  # the input limit was active
    fn = c["mpc_plant.fn"]
    assert c["mpc_plant.mode"][-1] > 0  # touching (it arrives so slowly that COLLISION never rebounds)
    assert fn.max() <= F_MAX + FORCE_TOLERANCE
    assert fn[-1] == pytest.approx(20.0, abs=FORCE_TOLERANCE)
    assert c["mpc.status"][-1] == 0
    imp = c["impedance_plant.fn"]
    assert imp[-1] == pytest.approx((20.0 + PAYLOAD_WEIGHT) / (1.0 + 1000.0 / K_SURFACE), rel=1e-3)
    assert imp.max() > F_MAX  # what the MPC's force limit prevents
    solve, iterations = c["mpc.solve_time"][::4], c["mpc.iterations"][::4]  # held 4 ms, recorded every 1 ms
    print(f"\nMPC: peak {fn.max():.3f} N, final {fn[-1]:.3f} N, settles (2 %) {settling(t, fn, 20.0, 0.4):.3f} s "
          f"after contact; impedance: peak {imp.max():.2f} N, final {imp[-1]:.3f} N, settles "
          f"{settling(t, imp, imp[-1], 0.4):.3f} s; QP solve median {np.median(solve) * 1e3:.2f} ms, "
          f"p99 {np.percentile(solve, 99) * 1e3:.2f} ms (OSQP iterations median {np.median(iterations):.0f}, "
          f"p99 {np.percentile(iterations, 99):.0f}); max |u| {u.max():.3f} N m")


def test_mpc_holds_the_force_limit_against_a_larger_command(tmp_path, linear_model):
    """Commanded 30 N, limit 25 N: the MPC settles on the limit and never passes it (the limit's
    slack stays inside OSQP's tolerance: status 0, not 2)."""
    c = run_press(tmp_path, linear_model, force=30.0, impedance=False)
    fn = c["mpc_plant.fn"]
    print(f"\ncommanded 30 N, limit {F_MAX} N: peak {fn.max():.3f} N, final {fn[-1]:.3f} N")
    assert fn.max() <= F_MAX + FORCE_TOLERANCE
    assert fn[-1] == pytest.approx(F_MAX, abs=FORCE_TOLERANCE)
    assert c["mpc.status"][-1] == 0


def test_a_missing_linear_model_is_named_with_the_command_that_makes_it(tmp_path, monkeypatch):
    """One line naming the parameter, the file and how to make it."""
    from deltafmi.models.mpc_controller import MpcController

    monkeypatch.chdir(tmp_path)
    controller = MpcController()
    controller.linear_model = "missing.npz"
    with pytest.raises(ValueError, match=r"linear_model 'missing.npz' not found .*deltafmi linearize "):
        controller.initialize(0.0)
