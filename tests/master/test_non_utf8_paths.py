"""Files whose names are not UTF-8 (bytes Linux allows, Python holds as surrogate escapes): an FMU,
a scenario and a linear model in such a folder are read, run and written like any other."""
from __future__ import annotations

import os
import shutil

import numpy as np
import scipy.io
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.master.linearize.fmu import linearize_fmu
from deltafmi.master.linearize.linear_model import LinearModel

FOLDER = os.fsdecode(b"caf\xe9")  # Latin-1 e-acute: not UTF-8


def _scenario(folder) -> str:
    text = f"experiment: {{stop: 0.5, step: 1.0e-3}}\ncomponents:\n  osc: {{fmu: Oscillator.fmu}}\noutputs: ['osc.x']\n"
    (folder / "s.yaml").write_text(text)
    return str(folder / "s.yaml")


def test_an_fmu_in_a_folder_whose_name_is_not_utf8_runs_as_in_any_other(build_fmu_from_src, tmp_path):
    fmu = build_fmu_from_src("oscillator.py")
    plain, odd = tmp_path / "plain", tmp_path / FOLDER
    results = []
    for folder in (plain, odd):
        folder.mkdir()
        shutil.copy(fmu, folder / "Oscillator.fmu")
        done = CliRunner().invoke(main, ["run", _scenario(folder), "-q", "-o", str(folder / "r.csv")])
        assert done.exit_code == 0, done.output
        results.append(np.loadtxt(folder / "r.csv", delimiter=",", skiprows=1))
        info = CliRunner().invoke(main, ["info", str(folder / "Oscillator.fmu")])
        assert info.exit_code == 0 and "Oscillator  (FMI 2.0" in info.output, info.output
    np.testing.assert_array_equal(results[1], results[0])
    assert results[1][0, 1] == 1.0 and len(results[1]) == 501  # x starts at 1 m; 500 steps


def test_a_linear_model_of_such_an_fmu_is_saved_in_such_a_folder(build_fmu_from_src, tmp_path):
    folder = tmp_path / FOLDER
    folder.mkdir()
    fmu = shutil.copy(build_fmu_from_src("oscillator.py"), folder / "Oscillator.fmu")
    model = linearize_fmu(fmu, inputs=["F"], outputs=["energy"])
    written = model.save(folder / "lin")
    k, c, m = 39.47841760435743, 0.2, 1.0  # the Oscillator's parameters: m x'' = F - k x - c v
    np.testing.assert_allclose(model.A, [[0.0, 1.0], [-k / m, -c / m]], rtol=1e-6, atol=1e-9)
    np.testing.assert_allclose(model.B, [[0.0], [1.0 / m]], rtol=1e-6, atol=1e-9)
    assert LinearModel.load(written[0]).source == model.source  # the .npz keeps the name as it is
    mat = scipy.io.loadmat(written[1])
    np.testing.assert_array_equal(mat["A"], model.A)
    assert "caf\ufffd" in str(mat["source"][0])  # MATLAB's UTF-8 shows the byte as U+FFFD


def test_an_fmi3_fmu_fmpy_cannot_hand_its_folder_says_so(build_fmu_from_src, tmp_path, monkeypatch):
    """fmpy encodes an FMI 3.0 resource path as UTF-8: from a cache so named it raises before the
    FMU is called, and the run says that, not that the FMU logged no reason."""
    monkeypatch.setenv("DELTAFMI_CACHE", str(tmp_path / FOLDER))
    (tmp_path / "s.yaml").write_text("experiment: {stop: 0.1, step: 1.0e-3}\ncomponents:\n"
                                     "  osc: {source: 'deltafmi.models:Oscillator', fmi_version: 3}\n")
    done = CliRunner().invoke(main, ["run", str(tmp_path / "s.yaml"), "-q", "-o", str(tmp_path / "r.csv")])
    if done.exit_code == 0:  # an fmpy that encodes file names as bytes: the run is what it should be
        assert np.loadtxt(tmp_path / "r.csv", delimiter=",", skiprows=1)[0, 0] == 0.0
        return
    assert done.exit_code == 1, done.output
    assert ("osc (Oscillator.fmu): fmi3InstantiateCoSimulation failed: fmpy could not call it: "
            "UnicodeEncodeError") in done.output, done.output
