"""Equation models built into real FMUs and run by fmpy: the delta robot against the hand-written
plant, the Cartesian pendulum against the elliptic-integral period."""
import ctypes

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Model
from scipy.special import ellipk

from deltafmi.builder.packager import build_cached
from deltafmi.physics import delta
from deltafmi.physics.delta.params import RL5


def _c(values):
    return (ctypes.c_double * len(values))(*[float(v) for v in values])


def _me(path):
    md = read_model_description(path)
    m = FMU2Model(guid=md.guid, unzipDirectory=extract(path), modelIdentifier=md.modelExchange.modelIdentifier,
                  instanceName="test")
    m.instantiate()
    m.setupExperiment(startTime=0.0)
    m.enterInitializationMode()
    m.exitInitializationMode()
    m.enterContinuousTimeMode()
    return m, md, {v.name: v.valueReference for v in md.modelVariables}


def test_delta_robot_equations_derivatives_equal_the_hand_written_plant():
    E, emd, evr = _me(build_cached("DeltaRobotEquations"))
    H, hmd, hvr = _me(build_cached("DeltaRobot"))
    eorder = [d.variable.derivative.name for d in emd.derivatives]
    horder = [d.variable.derivative.name for d in hmd.derivatives]
    # arm2.q[3] is the hand-written plant's q[6]
    perm = [horder.index(f"{n[5]}[{3 * (int(n[3]) - 1) + int(n[7])}]") for n in eorder]
    rng = np.random.default_rng(7)
    worst = 0.0
    for _ in range(1000):
        q = delta.inverse_kinematics(RL5, [rng.uniform(-0.4, 0.4), rng.uniform(-0.4, 0.4), rng.uniform(-1.15, -0.8)])
        null = np.linalg.svd(delta.constraint_jacobian(RL5, q))[2][6:]
        x = np.concatenate([q, 2.0 * null.T @ rng.normal(size=3)])  # on the loops, moving along them
        inputs = list(rng.normal(size=3) * 50.0) + list(rng.normal(size=3) * 20.0)
        out = []
        for m, vr, state in ((H, hvr, x), (E, evr, x[perm])):
            m.setContinuousStates(_c(state), 18)
            m.setReal([vr[f"{n}[{k}]"] for n in "uf" for k in (1, 2, 3)], inputs)
            d = _c([0.0] * 18)
            m.getDerivatives(d, 18)
            out.append(np.array(d[:]))
        worst = max(worst, np.max(np.abs(out[1] - out[0][perm])) / np.max(np.abs(out[0])))
    assert worst < 1e-12


@pytest.mark.parametrize("interface", ["ModelExchange", "CoSimulation"])
def test_cartesian_pendulum_period_and_constraint(interface):
    L, g, phi0 = 1.3, 9.81, 1.2
    period = 4.0 * ellipk(np.sin(phi0 / 2.0) ** 2) * np.sqrt(L / g)
    result = simulate_fmu(build_cached("CartesianPendulum"), fmi_type=interface, stop_time=2.5 * period,
                          start_values={"L": L, "g": g, "phi0": phi0}, output_interval=1e-4,
                          relative_tolerance=1e-12 if interface == "ModelExchange" else None, output=["x", "y"])
    t, x, y = result["time"], result["x"], result["y"]
    assert np.max(np.abs(x ** 2 + y ** 2 - L ** 2)) < 1e-9
    assert x[0] == pytest.approx(L * np.sin(phi0), abs=1e-12)
    # upward zero crossings of x, located by a cubic through four samples around each
    crossings = []
    for i in np.where((x[:-1] < 0.0) & (x[1:] >= 0.0))[0]:
        window = slice(i - 1, i + 3)
        roots = np.roots(np.polyfit(t[window] - t[i], x[window], 3))
        real = [r.real + t[i] for r in roots if abs(r.imag) < 1e-12 and 0.0 <= r.real <= t[i + 1] - t[i]]
        crossings.append(real[0])
    assert len(crossings) == 2
    assert (crossings[1] - crossings[0]) / period == pytest.approx(1.0, abs=1e-7)


def test_flagship_tracks_as_before_with_the_equation_plant(tmp_path):
    import deltafmi
    from deltafmi.shipped import SCENARIOS_DIR

    text = (SCENARIOS_DIR / "delta_tracking.yaml").read_text()
    assert "source: deltafmi.models:DeltaRobot\n" in text
    (tmp_path / "tracking.yaml").write_text(text.replace("source: deltafmi.models:DeltaRobot\n",
                                                         "source: deltafmi.models:DeltaRobotEquations\n"))
    hand = deltafmi.simulate("delta_tracking")
    eq = deltafmi.simulate(tmp_path / "tracking.yaml")
    assert np.array_equal(hand.time, eq.time)
    assert np.max(np.abs(eq["plant.z"] - hand["plant.z"])) < 1e-9
    assert np.max(np.abs(eq["controller.u"] - hand["controller.u"])) < 1e-6
    assert np.max(eq["plant.residual"]) < 1e-9
    tracking = np.max(np.abs(eq["plant.z"] - eq["trajectory.r"]))
    assert tracking < 5e-5  # the reference within 0.05 mm, as the hand-written plant does
    assert abs(tracking - np.max(np.abs(hand["plant.z"] - hand["trajectory.r"]))) < 1e-9


def test_delta_robot_equations_start_where_inverse_kinematics_puts_them():
    """The initial equations (h0 = 0, z = z0, v = 0), solved by Gauss-Newton from the arms' start
    values, find the hand-written plant's branch across the nominal workspace."""
    from deltafmi.models.delta_robot_equations import DeltaRobotEquations

    rng = np.random.default_rng(3)
    for _ in range(50):
        radius, angle = 0.5 * np.sqrt(rng.uniform()), rng.uniform(0.0, 2.0 * np.pi)
        z0 = [radius * np.cos(angle), radius * np.sin(angle), rng.uniform(-1.2, -0.75)]
        robot = DeltaRobotEquations()
        robot.z0 = z0
        robot.initialize(0.0)
        x = np.array(robot.states)
        q = np.concatenate([x[0:3], x[6:9], x[12:15]])  # arm1.q, arm1.v, arm2.q, ...
        assert np.max(np.abs(q - delta.inverse_kinematics(RL5, z0))) < 1e-10
        assert np.max(np.abs(x[[3, 4, 5, 9, 10, 11, 15, 16, 17]])) < 1e-15  # at rest
