"""deltafmi linearize: the robot plant at rest and the flagship closed loop, against physics and
independent formulations (tests/delta_reference.py: Lagrange's equations in the servo angles)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import scipy.io
import scipy.linalg
import yaml
from click.testing import CliRunner

from conftest import FMU_SRC, ROOT
from delta_reference import SERVO, MinimalModel, fk_minimal
from deltafmi.apps.cli import main
from deltafmi.master.linearize.closed_loop import linearize_scenario
from deltafmi.master.linearize.fmu import linearize_fmu
from deltafmi.master.linearize.linear_model import LinearModel
from deltafmi.physics import delta as d

FLAGSHIP = ROOT / "scenarios" / "delta_tracking.yaml"
TS = 1e-3
REST_POINTS = [(0.0, 0.0, -1.0), (0.2, -0.1, -0.9), (-0.25, 0.3, -1.15)]


@pytest.fixture(scope="module")
def robot(build_fmu_from_src):
    return build_fmu_from_src("delta_robot.py")


# --------------------------------------------------------------------------- the independent model

def _servo_model(p, z):
    """At rest at wrist z: servo angles y0, reduced inertia My, control Jacobian Jc = dz/dy and the
    gravity stiffness K = d2V/dy2, all from the minimal-coordinate model (complex steps through its
    own forward kinematics; K by central differences of that exact gradient)."""
    y0 = d.inverse_kinematics(p, z)[SERVO]
    mm = MinimalModel(p, np.zeros(3), np.zeros(3))
    My = mm.mass(y0[None])[0]
    Jc = mm.jac_and_z(y0[None])[1][0]

    def gradient(y):
        yc = y + 1j * mm.CS * np.eye(3)
        return mm.potential(yc, fk_minimal(p, yc)).imag / mm.CS

    h = 1e-5
    K = np.column_stack([(gradient(y0 + h * e) - gradient(y0 - h * e)) / (2 * h) for e in np.eye(3)])
    return y0, My, Jc, 0.5 * (K + K.T), gradient(y0)


def _minimal_poles(p, z):
    """Poles of the minimal model linearized at rest under its holding torque: M y'' = -K y."""
    _, My, _, K, _ = _servo_model(p, z)
    return np.linalg.eigvals(np.block([[np.zeros((3, 3)), np.eye(3)], [-np.linalg.solve(My, K), np.zeros((3, 3))]]))


def _sampled_loop_poles(p, z, kI, kP, kD, ts):
    """The flagship's outer loop computed independently: the linearized robot in servo angles
    (My y'' + K y = u, exactly discretized with u held) closed by the controller's sampled law
    as the controller code states it: e = -Jc y, integral += Ts e (then used), acc = kI i + kP e
    - kD Jc y', u_law = My Jc^-1 acc + K y (inverse dynamics with gravity), held with the
    half-sample lead u = 1.5 u_law - 0.5 u_law(previous). State: y, y', integral, previous u_law."""
    _, My, Jc, K, _ = _servo_model(p, z)
    A = np.block([[np.zeros((3, 3)), np.eye(3)], [-np.linalg.solve(My, K), np.zeros((3, 3))]])
    B = np.vstack([np.zeros((3, 3)), np.linalg.inv(My)])
    E = scipy.linalg.expm(np.block([[A, B], [np.zeros((3, 9))]]) * ts)
    Phi, Gamma = E[:6, :6], E[:6, 6:]
    gain = My @ np.linalg.inv(Jc)

    def step(s):
        y, yd, integral, previous = s[:3], s[3:6], s[6:9], s[9:]
        e = -Jc @ y
        integral = integral + ts * e
        law = gain @ (kI * integral + kP * e - kD * (Jc @ yd)) + K @ y
        x = Phi @ np.concatenate([y, yd]) + Gamma @ (1.5 * law - 0.5 * previous)
        return np.concatenate([x, integral, law])

    return np.linalg.eigvals(np.column_stack([step(e) for e in np.eye(12)]))


def _match(found, expected):
    """Largest relative distance from each expected value to its nearest found one."""
    found = np.asarray(found)
    return max(np.min(np.abs(found - z)) / abs(z) for z in expected)


# ------------------------------------------------------------------------------- the plant at rest

@pytest.mark.parametrize("z", REST_POINTS)
def test_plant_at_rest_under_its_holding_torque(robot, z):
    """Six double poles at -p (the Baumgarte dynamics h'' + 2p h' + p^2 h = 0 of the six loop
    closures, whatever the inputs) and three pole pairs of the mechanism, which the held torque
    makes a gravity stiffness: those equal the minimal-coordinate model's to 1e-6."""
    pole = 7.0 if z[2] < -1.1 else 5.0
    model = linearize_fmu(robot, start_values={"z0": list(z), "pole": pole}, rest=True, free=["u"],
                          inputs=["u"], outputs=["z"])
    p = d.RL5
    q = d.inverse_kinematics(p, z)
    # the equilibrium helper found the seed's gravity-holding torque, [B H^T][tau; lam] = G
    np.testing.assert_allclose(model.u0, d.holding_torque(p, q)[0], rtol=1e-9)
    np.testing.assert_allclose(model.x0[:9], q, atol=1e-12)
    np.testing.assert_allclose(model.y0, z, atol=1e-12)
    poles = model.poles()
    baumgarte = np.abs(poles + pole) < 1e-3 * pole
    assert baumgarte.sum() == 12
    assert np.max(np.abs(poles[baumgarte] + pole)) < 1e-6 * pole
    mechanism = poles[~baumgarte]
    expected = _minimal_poles(p, z)
    assert _match(mechanism, expected) < 1e-6 and _match(expected, mechanism) < 1e-6
    # the wrist's static answer to the torques: C A^-1 B restricted to the mechanism is the
    # inverse of the stiffness in wrist coordinates, Jc K^-1 (My drops out)
    _, _, Jc, K, _ = _servo_model(p, z)
    compliance = -model.C @ np.linalg.solve(model.A, model.B)
    np.testing.assert_allclose(compliance, Jc @ np.linalg.inv(K), rtol=1e-5, atol=1e-9)


# --------------------------------------------------------------------------- the flagship closed loop

def _scenario(tmp_path: Path, **controller) -> Path:
    spec = yaml.safe_load(FLAGSHIP.read_text())
    spec["components"]["controller"]["parameters"].update(controller)
    path = tmp_path / "loop.yaml"
    path.write_text(yaml.safe_dump(spec))
    return path


def test_flagship_closed_loop_at_rest(tmp_path):
    """At rest (t = 50 ms: the reference dwells at the home position) as the 1 ms map: the nine
    outer-loop eigenvalues (triple pole at -7 per axis, split by the sampling into a real one and a
    pair) have mean exp(-7 Ts); every eigenvalue of the loop other than the plant's Baumgarte ones
    is what an independent sampled-data model of the controller's discretisation predicts."""
    model = linearize_scenario(FLAGSHIP, at=0.05, inputs=[f"controller.r[{i}]" for i in (1, 2, 3)],
                               outputs=[f"plant.z[{i}]" for i in (1, 2, 3)])
    assert model.sample_time == TS
    poles = model.poles()
    outer = poles[np.argsort(np.abs(poles - np.exp(-7 * TS)))[:9]]
    assert abs(np.mean(outer) - np.exp(-7 * TS)) < 1e-4 * np.exp(-7 * TS)
    assert np.all(np.abs(outer - np.exp(-7 * TS)) < np.exp(-5 * TS) - np.exp(-7 * TS))  # not Baumgarte
    baumgarte = np.abs(poles - np.exp(-5 * TS)) < 1e-6
    assert baumgarte.sum() == 12
    predicted = _sampled_loop_poles(d.RL5, (0.0, 0.0, -1.0), 343.0, 147.0, 21.0, TS)
    rest = poles[~baumgarte]
    assert _match(rest, predicted) < 1e-6
    # the other eigenvalues are zeros: held values of the step (the torques the plant reads)
    assert np.sum(np.abs(rest) < 1e-9) == len(rest) - len(predicted)
    # integral action: the wrist follows a constant reference exactly, axis by axis
    dc = model.C @ np.linalg.solve(np.eye(len(poles)) - model.A, model.B) + model.D
    np.testing.assert_allclose(dc, np.eye(3), atol=1e-6)


def test_flagship_with_the_seeds_low_gains(tmp_path):
    """kP = 1, kD = 0.25, no integral: three eigenvalue pairs at the sampled poles of
    s^2 + kD s + kP = 0."""
    model = linearize_scenario(_scenario(tmp_path, kP=1.0, kD=0.25, kI=0.0), at=0.05)
    expected = np.exp(np.roots([1.0, 0.25, 1.0]) * TS)
    poles = model.poles()
    for z in expected:
        nearest = poles[np.argsort(np.abs(poles - z))[:3]]
        assert np.max(np.abs(nearest - z)) < 1e-4 * abs(z)


# ------------------------------------------------------------------------------------ the command

def test_command_writes_npz_and_mat_and_prints_poles(tmp_path, robot):
    out = tmp_path / "robot"
    result = CliRunner().invoke(main, ["linearize", str(robot), "--set", "z0=0.2,-0.1,-0.9", "--hold",
                                       "z=0.2,-0.1,-0.95", "--free", "u", "-u", "u", "-y", "z", "-o", str(out)])
    assert result.exit_code == 0, result.output
    assert "18 states, 3 inputs, 3 outputs (continuous)" in result.output and "damping" in result.output
    model = LinearModel.load(out.with_suffix(".npz"))
    np.testing.assert_allclose(model.y0, (0.2, -0.1, -0.95), atol=1e-10)  # held there, states moved
    assert model.states[:2] == ["q[1]", "q[2]"] and model.inputs == ["u[1]", "u[2]", "u[3]"]
    mat = scipy.io.loadmat(out.with_suffix(".mat"))
    np.testing.assert_array_equal(mat["A"], model.A)
    assert [str(n[0][0]) for n in mat["outputs"]] == ["z[1]", "z[2]", "z[3]"]


def test_command_on_a_scenario(tmp_path):
    result = CliRunner().invoke(main, ["linearize", str(FLAGSHIP), "--at", "0.05", "-u", "controller.r",
                                       "-y", "plant.z", "-o", str(tmp_path / "loop"), "-q"])
    assert result.exit_code == 0, result.output
    assert "27 states, 3 inputs, 3 outputs (discrete, Ts = 0.001 s)" in result.output
    model = LinearModel.load(tmp_path / "loop.npz")
    assert model.discrete and model.states[-1] == "controller.u[3] (held)"


@pytest.mark.parametrize("args, message", [
    (["--set", "z9=1"], "has no variable 'z9'"),
    (["--hold", "z=0,0,-3", "--free", "u"], "no equilibrium found"),
    (["-y", "u"], "is a Real input; linearize takes Real outputs"),
    (["--at", "nan"], "--at nan: the operating point's time must be a finite number"),  # was linearized at NaN
    (["--at", "1e400"], "--at inf: the operating point's time must be a finite number"),
])
def test_command_bad_input(robot, args, message):
    result = CliRunner().invoke(main, ["linearize", str(robot), *args])
    assert result.exit_code == 2 and message in result.output, result.output
    assert "Traceback" not in result.output


@pytest.mark.parametrize("at, message", [
    ("1e400", "--at inf: a linearization instant must be a finite number"),  # an internal error (OverflowError)
    ("nan", "--at nan: a linearization instant must be a finite number"),
])
def test_command_on_a_scenario_at_no_reachable_instant(at, message):
    result = CliRunner().invoke(main, ["linearize", str(FLAGSHIP), "--at", at, "-q"])
    assert result.exit_code == 2, result.output
    assert message in result.output.strip().splitlines()[-1], result.output


# ------------------------------------------------------------------------------------ FMI 3.0 builds

def test_fmi3_plant_linearizes_as_its_fmi2_build(robot, tmp_path):
    """The robot built as FMI 3.0 (q, v, u, z arrays; fmi3GetDirectionalDerivative element by
    element of the arrays) gives the FMI 2.0 build's equilibrium and A, B, C, D: both are the same
    exact partial derivatives of the same equations."""
    from deltafmi.builder import build_fmu

    robot3 = build_fmu(FMU_SRC / "delta_robot.py", tmp_path / "delta_robot3.fmu", fmi_version=3)
    arguments = dict(start_values={"z0": [0.2, -0.1, -0.9], "pole": 5.0}, rest=True, free=["u"],
                     inputs=["u[1]", "u[3]"], outputs=["z", "yd[2]"])
    two, three = linearize_fmu(robot, **arguments), linearize_fmu(robot3, **arguments)
    assert three.states == two.states and three.states[9] == "v[1]"
    assert (three.inputs, three.outputs) == (["u[1]", "u[3]"], ["z[1]", "z[2]", "z[3]", "yd[2]"])
    for name in ("u0", "x0", "y0", "A", "B", "C", "D"):
        np.testing.assert_allclose(getattr(three, name), getattr(two, name), rtol=1e-12, atol=1e-12, err_msg=name)
    assert np.abs(two.B).max() > 0.1 and np.abs(two.C).max() > 0.1  # not trivially equal


def test_fmi3_flagship_closed_loop_equals_the_fmi2_one(tmp_path):
    """The flagship with its three FMUs built as FMI 3.0: the same 1 ms closed-loop map (the plant's
    A, B, C, D through fmi3GetDirectionalDerivative; the controller's pulse responses through
    fmi3Get/SetFMUState and array inputs set whole)."""
    fmi3 = tmp_path / "flagship3.yaml"
    fmi3.write_text("fmi_version: 3\n" + FLAGSHIP.read_text())
    arguments = dict(at=0.05, inputs=["controller.r[1]", "controller.r[3]"], outputs=["plant.z[2]", "plant.z[3]"])
    two, three = linearize_scenario(FLAGSHIP, **arguments), linearize_scenario(fmi3, **arguments)
    assert three.states == two.states
    for name in ("D", "x0", "u0", "y0"):
        np.testing.assert_allclose(getattr(three, name), getattr(two, name), rtol=1e-9, atol=1e-12, err_msg=name)
    # the controller's realization comes from central differences of its pulse responses, which
    # magnify the last bits of the operating point (the plants' states agree to 1e-16 m); its basis
    # may turn by that much, so compare what does not depend on the basis: the poles and the
    # map's own pulse responses C A^k B. Its double poles (Baumgarte's, the outer loop's) split by
    # the square root of such a perturbation: 1e-7 for them
    np.testing.assert_allclose(three.poles(), two.poles(), rtol=0, atol=1e-7)
    for k in range(0, 60, 7):
        power = [np.linalg.matrix_power(model.A, k) for model in (two, three)]
        np.testing.assert_allclose(three.C @ power[1] @ three.B, two.C @ power[0] @ two.B, rtol=0, atol=1e-9)


def test_a_save_that_fails_keeps_the_earlier_files_whole(tmp_path, monkeypatch):
    """The .npz and .mat are written to temporary files that replace them only when whole: a
    write that fails half way (a full disk) leaves the earlier model readable, and no stray file."""
    import errno

    earlier = LinearModel(A=-np.eye(2), B=np.ones((2, 1)), C=np.eye(2), D=np.zeros((2, 1)),
                          states=["x", "v"], inputs=["u"], outputs=["x", "v"], source="first")
    written = earlier.save(tmp_path / "m")
    before = [p.read_bytes() for p in written]

    def disk_full(target, *args, **kwargs):
        target.write(b"MATLAB 5.0 half a file")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(scipy.io, "savemat", disk_full)
    later = LinearModel(A=-2 * np.eye(2), B=np.ones((2, 1)), C=np.eye(2), D=np.zeros((2, 1)),
                        states=["x", "v"], inputs=["u"], outputs=["x", "v"], source="second")
    with pytest.raises(OSError) as error:
        later.save(tmp_path / "m")
    assert error.value.filename == str(tmp_path / "m.mat")
    assert written[1].read_bytes() == before[1]
    np.testing.assert_array_equal(scipy.io.loadmat(written[1])["A"], -np.eye(2))
    assert sorted(p.name for p in tmp_path.iterdir()) == ["m.mat", "m.npz"]
