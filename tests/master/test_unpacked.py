"""FMUs of the build cache are unpacked once and the copy is kept for later runs; any other FMU
is unpacked for its run only. A run on the kept copy gives the results of a run on a fresh one.
An FMU's model description, once read, and fmpy's validation of it are kept under the FMU's stamp."""
from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

import deltafmi
from deltafmi.errors import BadInput
from deltafmi.builder.packager import build_cached
from deltafmi.master.stepping.unpacked import kept_unpacked

FMU_SRC = Path(__file__).resolve().parents[2] / "fmu_src"


def test_a_built_fmu_is_unpacked_once(tmp_path):
    fmu = build_cached(FMU_SRC / "oscillator.py")
    folder = kept_unpacked(fmu)
    assert folder is not None and (Path(folder) / "modelDescription.xml").is_file()
    marker = Path(folder) / "resources" / "kept.marker"
    marker.write_text("")
    try:
        assert kept_unpacked(fmu) == folder and marker.exists()  # the same copy, not unpacked again
    finally:
        marker.unlink()
    assert not [p for p in Path(folder).parent.iterdir() if p.name.startswith(".")]  # no half copy left
    elsewhere = tmp_path / fmu.name
    shutil.copy(fmu, elsewhere)
    assert kept_unpacked(elsewhere) is None


def test_runs_on_the_kept_copy_and_on_a_fresh_one_agree(tmp_path):
    fmu = build_cached(FMU_SRC / "oscillator.py")
    elsewhere = tmp_path / fmu.name
    shutil.copy(fmu, elsewhere)
    kept = deltafmi.simulate(fmu, stop=0.5)
    fresh = deltafmi.simulate(elsewhere, stop=0.5)
    again = deltafmi.simulate(fmu, stop=0.5)
    names = [n for n in kept.names if n != "time"]
    assert names
    for name in names:
        assert np.array_equal(kept[name], fresh[name]) and np.array_equal(kept[name], again[name])


def test_a_model_description_read_before_is_not_parsed_again(tmp_path, monkeypatch):
    from deltafmi.master.scenario import modelinfo

    fmu = tmp_path / "osc.fmu"
    shutil.copy(build_cached(FMU_SRC / "oscillator.py"), fmu)
    first = modelinfo.model_info(str(fmu))

    def refuse(*_args, **_kwargs):
        raise AssertionError("parsed again")

    with monkeypatch.context() as patch:
        patch.setattr(modelinfo, "read_model_description", refuse)
        again = modelinfo.model_info(str(fmu))
    assert again.md.guid == first.md.guid
    assert [v.name for v in again.md.modelVariables] == [v.name for v in first.md.modelVariables]
    fmu.write_bytes(b"not a zip any more")  # a changed file is read again, and its problem told
    with pytest.raises(BadInput, match="not a zip archive"):
        modelinfo.model_info(str(fmu))


def test_an_fmu_validated_before_is_not_validated_again(tmp_path, monkeypatch):
    import zipfile

    import fmpy.validation

    from deltafmi.master.scenario.fmu_checks import validation_problems

    fmu = tmp_path / "osc.fmu"
    shutil.copy(build_cached(FMU_SRC / "oscillator.py"), fmu)
    assert validation_problems(fmu) == []

    def refuse(*_args, **_kwargs):
        raise AssertionError("validated again")

    with monkeypatch.context() as patch:
        patch.setattr(fmpy.validation, "validate_fmu", refuse)
        assert validation_problems(fmu) == []
    # the same file changed (a variable name the structured naming convention refuses) is validated anew
    with zipfile.ZipFile(fmu) as archive:
        entries = {item.filename: archive.read(item) for item in archive.infolist()}
    entries["modelDescription.xml"] = entries["modelDescription.xml"].replace(b'name="x"', b'name="x["', 1)
    with zipfile.ZipFile(fmu, "w") as archive:
        for name, data in entries.items():
            archive.writestr(name, data)
    problems = validation_problems(fmu)
    assert problems and any('"x["' in problem for problem in problems), problems
