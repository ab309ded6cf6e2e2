"""The two-pad tactile sensor: its statics against the closed forms, the FMU's lag, noise and
quantization, and the tactile loop centring the robot's tool on a hole."""
from __future__ import annotations

import json
import math
import zipfile
from pathlib import Path

import fmpy
import numpy as np
import pytest
from fmpy.validation import validate_fmu

from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.physics.delta.tactile import Readout, TactilePads

ROOT = Path(__file__).resolve().parents[2]
PADS = TactilePads(spacing=0.01, width=0.004, stiffness=1e5)
HOLE = 0.01


def test_pads_split_the_load_by_their_supported_length():
    """Centred, each pad overhangs the rim by (spacing + width - hole)/2 = 2 mm of its 4 mm; near
    the centre the difference is -F xi / (width phi0), the compression F / (k (phi1 + phi2))."""
    F, phi0 = 20.0, (0.01 + 0.004 - HOLE) / (2 * 0.004)
    assert PADS.supported(0.0, HOLE) == pytest.approx((phi0, phi0))
    for xi in (-1.5e-3, -2e-4, 0.0, 7e-4, 1.9e-3):
        f1, f2, compression = PADS.forces(F, xi, HOLE)
        assert f1 + f2 == pytest.approx(F, rel=1e-14)
        assert f1 - f2 == pytest.approx(-F * xi / (0.004 * phi0), rel=1e-12, abs=1e-12)
        assert compression == pytest.approx(F / (1e5 * 2 * phi0), rel=1e-12)
    assert PADS.slope(F, HOLE) == pytest.approx(-F / (0.004 * phi0))
    # beyond the linear range one pad hangs over the hole: the difference saturates at -+F ...
    assert PADS.forces(F, 3e-3, HOLE)[:2] == pytest.approx((0.0, F))
    assert PADS.forces(F, -7.9e-3, HOLE)[:2] == pytest.approx((F, 0.0))
    # ... up to (hole + spacing - width)/2 = 8 mm, then fades as pad 1 leaves the hole, and
    # vanishes past (hole + spacing + width)/2 = 12 mm, both pads on solid surface
    f1, f2, _ = PADS.forces(F, 10e-3, HOLE)
    assert f1 - f2 == pytest.approx(-F * (1 - 0.5) / (1 + 0.5))
    assert PADS.forces(F, 12.1e-3, HOLE)[:2] == pytest.approx((F / 2, F / 2))
    assert PADS.forces(F, 0.0, 0.0)[:2] == pytest.approx((F / 2, F / 2))  # flat surface
    assert PADS.forces(F, 0.0, 0.03) == (0.0, 0.0, 0.0)  # both pads over the hole
    assert PADS.forces(0.0, 1e-3, HOLE) == (0.0, 0.0, 0.0)


def test_readout_noise_is_seeded_and_quantized():
    readout = Readout(noise=0.1, quantization=0.05, seed=7)
    values = np.array([readout.read(1.0, k, 0) for k in range(4000)])
    assert np.allclose(values / 0.05, np.round(values / 0.05), atol=1e-9)
    assert values.mean() == pytest.approx(1.0, abs=0.01)
    # rms of noise plus uniform rounding error (q^2 / 12)
    assert values.std() == pytest.approx(math.sqrt(0.1 ** 2 + 0.05 ** 2 / 12), rel=0.05)
    assert [readout.read(1.0, k, 0) for k in range(5)] == list(values[:5])
    assert readout.read(1.0, 3, 1) != readout.read(1.0, 3, 0) or readout.read(1.0, 4, 1) != readout.read(1.0, 4, 0)


@pytest.fixture(scope="module")
def sensor(build_fmu_from_src):
    return build_fmu_from_src("tactile_sensor.py")


def test_sensor_validates(sensor):
    assert validate_fmu(str(sensor)) == []


def _step_run(sensor, fmi_type, **start):
    """The load steps from 0 to 20 N at t = 10 ms with the tool 0.5 mm off the hole centre."""
    fields = [("time", float), ("fn", float), ("tip[1]", float), ("tip[2]", float), ("tip[3]", float)]
    signal = np.array([(0.0, 0.0, 5e-4, 0.0, -1.15), (0.01, 0.0, 5e-4, 0.0, -1.15),
                       (0.01, 20.0, 5e-4, 0.0, -1.15), (0.2, 20.0, 5e-4, 0.0, -1.15)], dtype=fields)
    r = fmpy.simulate_fmu(str(sensor), fmi_type=fmi_type, stop_time=0.1, output_interval=1e-3,
                          input=signal, relative_tolerance=1e-10, start_values=start,
                          output=["difference", "pad[1]", "pad[2]", "offset", "filtered[1]"])
    last = np.append(np.diff(r["time"]) > 0, True)  # the row after the event at a sample instant
    return r[last]


@pytest.mark.parametrize("fmi_type", ["ModelExchange", "CoSimulation"])
def test_sensor_lags_with_its_bandwidth(sensor, fmi_type):
    """Without noise or quantization the readings are the pad forces through the first-order lag:
    F_i (1 - exp(-2 pi f_c (t - t_step))), read at the sample instants."""
    r = _step_run(sensor, fmi_type, noise=0.0, quantization=0.0, bandwidth=50.0)
    f1, f2, _ = PADS.forces(20.0, 5e-4, HOLE)
    t = r["time"]  # the sample instants, each row after its reading
    lag = 1.0 - np.exp(-2 * math.pi * 50.0 * np.clip(t - 0.01, 0.0, None))
    np.testing.assert_allclose(r["difference"], (f1 - f2) * lag, rtol=1e-6, atol=1e-7)
    assert r["offset"][-1] == pytest.approx(5e-4)


@pytest.mark.parametrize("fmi_type", ["ModelExchange", "CoSimulation"])
def test_compiled_kernels_give_the_python_bits_under_load(sensor, fmi_type, monkeypatch):
    """The FMU's derivatives and outputs run as C generated from the kernels its methods call
    (deltafmi.physics.delta.tactile): the same bits as the Python (DELTAFMI_NATIVE=0) while the
    load steps and the lag moves, not only at the default experiment's unloaded rest."""
    with zipfile.ZipFile(sensor) as archive:
        assert json.loads(archive.read("resources/native_kernels.json"))["kernels"] == ["derivatives", "outputs"]
    runs = {}
    for native in ("1", "0"):
        monkeypatch.setenv("DELTAFMI_NATIVE", native)
        runs[native] = _step_run(sensor, fmi_type)
    # the lagged pad force rose from 0 to the loaded pad's 7.5 N
    assert runs["1"]["filtered[1]"][0] == 0.0
    assert runs["1"]["filtered[1]"][-1] == pytest.approx(PADS.forces(20.0, 5e-4, HOLE)[0], rel=1e-9)
    for name in runs["1"].dtype.names:
        assert np.array_equal(runs["1"][name], runs["0"][name]), name


def test_sensor_noise_is_the_same_in_both_interfaces(sensor):
    """Seeded noise and quantization: identical readings from ME (fmpy's CVODE) and CS."""
    me, cs = (_step_run(sensor, kind, noise=0.05, quantization=0.02, seed=3)
              for kind in ("ModelExchange", "CoSimulation"))
    np.testing.assert_array_equal(me["time"], cs["time"])
    a, b = me["pad[1]"][20:], cs["pad[1]"][20:]
    np.testing.assert_allclose(a, b, atol=1e-9)
    assert np.allclose(a / 0.02, np.round(a / 0.02), atol=1e-9)
    f1 = PADS.forces(20.0, 5e-4, HOLE)[0]
    assert np.std(a[-50:] - f1) == pytest.approx(0.05, rel=0.35)  # 50 samples of the noise


def test_tactile_loop_centres_the_tool_on_the_hole(tmp_path):
    """contact_tactile.yaml: the hole is 3 mm off the tool; pressing with 20 N, the loop from the
    pad difference to the horizontal reference brings the tool within 0.1 mm of its centre."""
    out = tmp_path / "tactile.csv"
    Master(resolve_system(load_scenario(ROOT / "scenarios" / "contact_tactile.yaml")), result=out).run()
    c = columns(out)
    t, offset = c["time"], c["sensor.offset"]
    assert offset[0] == pytest.approx(-3e-3)
    assert np.max(np.abs(offset[t > 2.5])) < 1e-4
    assert c["controller.shift"][-1] == pytest.approx(3e-3, abs=1e-4)
    assert c["plant.fn"][-1] == pytest.approx(20.0 / (1.0 + 1000.0 / 2e5), rel=1e-3)
