"""The build cache's fast path: a cached FMU found from the stamps of its files, the key hashed
again only when a stamp changed, a new FMU when a content changed."""
from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest

import deltafmi
from deltafmi.builder import build_stamps, compiler, packager, provider, reach

FMU_SRC = Path(__file__).resolve().parents[2] / "fmu_src"


@pytest.fixture
def source(tmp_path) -> Path:
    copy = tmp_path / "oscillator.py"
    shutil.copy(FMU_SRC / "oscillator.py", copy)
    return copy


@pytest.fixture
def hashed(monkeypatch) -> list:
    """The sources whose content key was computed (from their contents) while the test ran."""
    calls = []
    keyed = packager._keyed

    def counting(source, *rest):
        calls.append(Path(source))
        return keyed(source, *rest)

    monkeypatch.setattr(packager, "_keyed", counting)
    return calls


def test_unchanged_files_find_the_fmu_without_reading_them(source, hashed):
    first = packager.build_cached(source)
    assert hashed and set(hashed) == {source}
    before = len(hashed)
    assert packager.build_cached(source) == first and len(hashed) == before  # stamps only: nothing hashed


def test_a_touched_file_is_hashed_again_and_keeps_its_fmu(source, hashed):
    first = packager.build_cached(source)
    before = len(hashed)
    status = source.stat()
    os.utime(source, ns=(status.st_atime_ns, status.st_mtime_ns + 1_000_000_000))
    assert packager.build_cached(source) == first and len(hashed) == before + 1
    assert packager.build_cached(source) == first and len(hashed) == before + 1  # the record renewed


def test_an_edited_file_gets_a_new_fmu(source, hashed):
    first = packager.build_cached(source)
    before = len(hashed)
    source.write_text(source.read_text().replace('"""', '"""Edited. ', 1))
    second = packager.build_cached(source)
    assert second != first and second.is_file() and len(hashed) > before
    assert packager.content_key(source)[:20] in str(second)


def test_a_module_added_beside_a_reached_one_is_noticed(source, hashed, tmp_path):
    """A folder's stamp changes when a file is added to it (``from P import name`` may reach it)."""
    first = packager.build_cached(source)
    record = build_stamps.recorded(build_stamps.file_request(source, None, 2, []))
    folders = [Path(p) for p, *_ in record[1] if Path(p).is_dir()]
    assert any(folder.name == "runtime" for folder in folders)
    probe = tmp_path / "folder"
    probe.mkdir()
    stamps = build_stamps.stamps_of([probe])
    build_stamps.remember("probe", stamps, first)
    assert build_stamps.lookup("probe") == first
    (probe / "new_module.py").write_text("")
    assert build_stamps.lookup("probe") is None


def test_the_code_that_decides_what_the_key_reads_is_stamped(source):
    """An edit to the binary's flags or sources (compiler.py) or to which modules an FMU carries
    (reach.py) is noticed as one to a file the key read is: the key is computed again."""
    packager.build_cached(source)
    record = build_stamps.recorded(build_stamps.file_request(source, None, 2, []))
    stamped = {Path(p) for p, *_ in record[1]}
    assert {Path(compiler.__file__), Path(reach.__file__), Path(packager.__file__)} <= stamped


def test_a_request_names_the_installation_that_made_it(source, monkeypatch):
    """Another copy of deltafmi (path or version) asks another request: it checks its own files."""
    request = build_stamps.file_request(source, None, 2, [])
    folder, version = build_stamps.installation()
    assert Path(folder) == Path(packager.__file__).resolve().parents[1] and version == deltafmi.__version__
    monkeypatch.setattr(deltafmi, "__version__", version + "+other")
    assert build_stamps.file_request(source, None, 2, []) != request
    monkeypatch.undo()
    monkeypatch.setattr(deltafmi, "__file__", str(source.parent / "elsewhere" / "deltafmi" / "__init__.py"))
    assert build_stamps.file_request(source, None, 2, []) != request


def test_a_packaged_model_is_found_without_importing_it(monkeypatch, tmp_path):
    reference = "deltafmi.models:Oscillator"
    first = provider.scenario_fmu(reference, tmp_path, 2)
    import deltafmi.builder.sources as sources

    def refuse(*_):
        raise AssertionError("the model's module was imported")

    monkeypatch.setattr(sources, "module_component", refuse)
    monkeypatch.setattr(packager, "_keyed", refuse)
    assert provider.scenario_fmu(reference, tmp_path, 2) == first


def test_a_record_of_an_fmu_gone_from_the_cache_is_not_used(source):
    first = packager.build_cached(source)
    request = build_stamps.file_request(source, None, 2, [])
    assert build_stamps.lookup(request) == first
    build_stamps.remember(request, build_stamps.stamps_of([source]), first.parent / "elsewhere.fmu")
    assert build_stamps.lookup(request) is None
    assert packager.build_cached(source) == first


def test_a_cache_in_a_folder_whose_name_is_not_utf8_builds_fmus_that_run(source, tmp_path, monkeypatch):
    """A home folder named in Latin-1: the build cache's keys, the compiler's messages and the
    FMU's start take its name as bytes; the FMU steps as the one from an ordinary cache does."""
    import fmpy
    from fmpy.fmi2 import FMU2Slave

    rows = []
    for cache in ("cache", os.fsdecode(b"c\xe9che")):
        monkeypatch.setenv("DELTAFMI_CACHE", str(tmp_path / cache))
        fmu = packager.build_cached(source)
        assert str(tmp_path / cache) in str(fmu)
        md = fmpy.read_model_description(str(fmu))
        vr = {v.name: v.valueReference for v in md.modelVariables}
        slave = FMU2Slave(guid=md.guid, modelIdentifier="Oscillator",
                          unzipDirectory=fmpy.extract(str(fmu), unzipdir=str(tmp_path / cache / "unpacked")))
        slave.instantiate()
        slave.setupExperiment(startTime=0.0)
        slave.enterInitializationMode()
        slave.exitInitializationMode()
        rows.append([slave.getReal([vr["x"], vr["v"]])])
        for i in range(100):
            slave.doStep(i * 0.01, 0.01)
            rows[-1].append(slave.getReal([vr["x"], vr["v"]]))
        slave.terminate()
        slave.freeInstance()
    assert rows[1] == rows[0] and rows[0][0] == [1.0, 0.0] and rows[0][-1] != rows[0][0]
