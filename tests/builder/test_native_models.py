"""Issue 26: every shipped model has compiled kernels, and its FMU gives the same numbers with them
as with its Python methods (``DELTAFMI_NATIVE=0``), bit for bit, in Model Exchange (fmpy's CVODE)
and Co-Simulation, FMI 2.0 and 3.0 builds, over its default experiment."""
from __future__ import annotations

import zipfile

import fmpy
import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu

import deltafmi.models
from deltafmi.builder import build_cached

PYTHON_ONLY = deltafmi.models.PYTHON_ONLY  # an EKF's numpy linear algebra, an MPC's OSQP
MODELS = sorted(set(deltafmi.models.MODELS) - set(PYTHON_ONLY))


@pytest.mark.parametrize("name", sorted(PYTHON_ONLY))
def test_python_only_models_say_so(name):
    """The list above stays true: these declare no kernels (a model that gains them leaves it)."""
    assert getattr(getattr(deltafmi.models, name), "native", None) is None, name


@pytest.mark.parametrize("name", MODELS)
def test_the_model_declares_compiled_kernels_and_its_fmu_carries_them(name):
    cls = getattr(deltafmi.models, name)
    assert cls.native is not None and cls.native.mode != "off" and (cls.native.kernels() or cls.native.functions), name
    with zipfile.ZipFile(build_cached(name)) as archive:
        assert "resources/native_kernels.json" in archive.namelist()


@pytest.fixture(scope="module")
def unpacked(tmp_path_factory):
    """``unpacked(name, fmi_version) -> str``: the folder of the packaged model's FMU, unzipped once
    for the runs of both interfaces, both kernels (fmpy would unzip it for each run)."""
    done: dict = {}

    def get(name: str, fmi_version: int) -> str:
        if (name, fmi_version) not in done:
            folder = tmp_path_factory.mktemp(f"{name}{fmi_version}")
            fmu = build_cached(name, fmi_version=fmi_version)
            done[name, fmi_version] = str(fmpy.extract(str(fmu), unzipdir=folder))
        return done[name, fmi_version]

    return get


@pytest.mark.parametrize("fmi_version", [2, 3])
@pytest.mark.parametrize("interface", ["ModelExchange", "CoSimulation"])
@pytest.mark.parametrize("name", MODELS)
def test_compiled_and_python_kernels_give_the_same_bits(name, interface, fmi_version, monkeypatch, unpacked):
    fmu = unpacked(name, fmi_version)
    md = read_model_description(fmu)
    outputs = [v.name for v in md.modelVariables if v.causality == "output" and v.type != "String"]
    results = {}
    for native in ("1", "0"):
        monkeypatch.setenv("DELTAFMI_NATIVE", native)
        results[native] = simulate_fmu(fmu, fmi_type=interface, output=outputs)
    compiled, python = results["1"], results["0"]
    assert len(compiled) == len(python) > 1
    for column in ("time", *outputs):
        assert np.array_equal(compiled[column], python[column], equal_nan=True), column
