"""Published compatibility information (``deltafmi compat``): the tree of our FMUs follows the FMI
Cross-Check layout (fmpy's own Cross-Check validator finds no problem in it), fmpy reproduces
every ``X_ref.csv`` from the FMU, ``X_ref.opt`` and ``X_in.csv`` alone (Co-Simulation to 1e-7 of
each signal's range: same FMU, same communication points; Model Exchange within a band of 1e-3 of
the range: two CVODEs at RelTol), and ``compat import`` runs third-party FMUs (FMI 2.0 and 3.0;
Real, Integer, Boolean, Enumeration and array inputs) laid out the same way through our master,
writing ``passed`` next to them, and ``failed`` for a reference that is off by 3 % of one signal's
range (the import band: 1 %).
"""
from __future__ import annotations

import inspect
import re
import shutil
from pathlib import Path

import fmpy
import numpy as np
import pytest
from click.testing import CliRunner
from fmpy.cross_check.validate_vendor_repo import validate_repo
from fmpy.util import read_csv, read_ref_opt_file

from deltafmi.apps.cli import main
from deltafmi.apps.compat.compare import mismatches
from deltafmi.apps.compat.files import RefOptions, Table, read_table, write_options, write_table
from third_party.build import build_fmu

MODELS = ("Oscillator", "BouncingBall", "DeltaRobot")  # an input and events, events alone, arrays
VERSION = __import__("deltafmi").__version__
FMI_TYPES = {"cs": "CoSimulation", "me": "ModelExchange"}
# fmpy's Cross-Check validator imports from scipy.ndimage.filters
pytestmark = pytest.mark.filterwarnings("ignore:Please import:DeprecationWarning")


def invoke(*args: str):
    result = CliRunner().invoke(main, list(args))
    return result


@pytest.fixture(scope="module")
def tree(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("xc")
    result = invoke("compat", str(root), "--fmi-version", "2", "--models", ",".join(MODELS))
    assert result.exit_code == 0, result.output
    return root


def fmpy_run(folder: Path, model: str, interface: str, names):
    """fmpy alone, from the files of the model folder."""
    opts = read_ref_opt_file(str(folder / f"{model}_ref.opt"))
    in_csv = folder / f"{model}_in.csv"
    return fmpy.simulate_fmu(str(folder / f"{model}.fmu"), fmi_type=FMI_TYPES[interface],
                             start_time=opts["StartTime"], stop_time=opts["StopTime"],
                             output_interval=opts["StepSize"], relative_tolerance=opts["RelTol"],
                             input=read_csv(str(in_csv)) if in_csv.exists() else None, output=list(names))


def as_table(result) -> Table:
    return Table(result["time"], {name: result[name] for name in result.dtype.names[1:]})


def test_tree_follows_the_layout(tree):
    for model in MODELS:
        for interface in ("cs", "me"):
            folder = tree / "fmus" / "2.0" / interface / "linux64" / "deltafmi" / VERSION / model
            files = sorted(p.name for p in folder.iterdir())
            expected = [f"{model}.fmu", f"{model}_ref.csv", f"{model}_ref.opt", "ReadMe.md"]
            if model != "BouncingBall":
                expected.append(f"{model}_in.csv")
            assert files == sorted(expected)
            md = fmpy.read_model_description(str(folder / f"{model}.fmu"))
            header = (folder / f"{model}_ref.csv").read_text().splitlines()[0]
            names = [n.strip('"') for n in header.split(",")]
            assert names[0] == "time" and header == ",".join(f'"{n}"' for n in names)
            assert set(names[1:]) <= {v.name for v in md.modelVariables} and len(names) <= 11
            if (folder / f"{model}_in.csv").exists():
                inputs = read_table(folder / f"{model}_in.csv")
                assert inputs.names == [v.name for v in md.modelVariables if v.causality == "input"]
    # the Cross-Check's validator: model descriptions, .opt files, CSV names, sizes
    fmu_count, result_count, problems = validate_repo(str(tree))
    assert (fmu_count, problems) == (2 * len(MODELS), [])


@pytest.mark.parametrize("interface", ["cs", "me"])
@pytest.mark.parametrize("model", MODELS)
def test_fmpy_reproduces_the_reference(tree, model, interface):
    folder = tree / "fmus" / "2.0" / interface / "linux64" / "deltafmi" / VERSION / model
    reference = read_table(folder / f"{model}_ref.csv")
    result = fmpy_run(folder, model, interface, reference.names)
    opts = read_ref_opt_file(str(folder / f"{model}_ref.opt"))
    assert result["time"][-1] == pytest.approx(opts["StopTime"])
    if interface == "cs":  # same FMU, same communication points, same inputs there
        assert np.allclose(result["time"], reference.time, rtol=0, atol=1e-12)
        for name in reference.names:
            # 1e-7: the two masters add up the communication times differently (an ulp apart),
            # which moves the ball's contact events inside the FMU's own solver a little
            scale = max(np.ptp(reference.columns[name]), 1e-6)
            assert np.max(np.abs(result[name] - reference.columns[name])) <= 1e-7 * scale, name
    else:  # two CVODEs at RelTol, one interpolating the inputs, the other holding them 1/10 step
        assert mismatches(as_table(result), reference, opts["StopTime"], tolerance=1e-3) == []


def test_fmi3_tree(tmp_path):
    from deltafmi.builder.packager import build_cached
    if "fmi_version" not in inspect.signature(build_cached).parameters:
        pytest.skip("FMI 3.0 export is not in this tree yet")
    result = invoke("compat", str(tmp_path), "--fmi-version", "3", "--models", "DeltaRobot")
    assert result.exit_code == 0, result.output
    for interface in ("cs", "me"):
        folder = tmp_path / "fmus" / "3.0" / interface / "x86_64-linux" / "deltafmi" / VERSION / "DeltaRobot"
        reference = read_table(folder / "DeltaRobot_ref.csv")
        assert reference.names == ["y", "z", "zd", "energy"] and reference.columns["z"].shape[1] == 3
        fmpy_result = fmpy_run(folder, "DeltaRobot", interface, reference.names)
        assert mismatches(as_table(fmpy_result), reference, 0.2) == []


# --- importing others' FMUs ----------------------------------------------------------------------

#: third-party model -> (FMI version, stop, step, tolerance, input signals on the grid)
THIRD_PARTY = {
    "BouncingBall": ("2.0", 2.0, 0.01, 1e-8, None),
    "AllTypes": ("2.0", 1.0, 0.01, 1e-8, lambda t: {"u": np.sin(2 * np.pi * t), "u_int": np.floor(5 * t),
                                                    "u_bool": 1.0 * (t > 0.45), "u_color": 1 + 1 * (t > 0.55)}),
    "LookupTable": ("2.0", 1.0, 0.01, 1e-6, lambda t: {"u": 0.5 + 0.4 * np.sin(2 * np.pi * t)}),
    "Ticker": ("2.0", 1.5, 0.01, 1e-6, lambda t: {"u": np.cos(np.pi * t)}),  # it ends itself at 1.75 s
    "BouncingBall3": ("3.0", 2.0, 0.01, 1e-8, None),
    "StateSpace3": ("3.0", 2.0, 0.01, 1e-8, lambda t: {"u": np.column_stack([np.sin(t), np.cos(2 * t)])}),
    "Table3": ("3.0", 1.0, 0.01, 1e-6, lambda t: {"u": 0.5 + 0.4 * np.sin(2 * np.pi * t)}),
}
PLATFORMS = {"2.0": "linux64", "3.0": "x86_64-linux"}
#: Model Exchange references from the model's equations (gain 2, offset 1, no invert, red tint):
#: fmpy's own ME run of AllTypes starts integrating x two output steps late (x = 0 up to 0.02 s)
EXACT = {"AllTypes": lambda t: {"y": 2 * np.sin(2 * np.pi * t), "x": (1 - np.cos(2 * np.pi * t)) / np.pi,
                                "y_int": np.floor(5 * t) + 1, "y_bool": 1.0 * (t > 0.45),
                                "y_color": 1 + 1 * (t > 0.55), "y_discrete": 0 * t}}


def third_party_folder(root: Path, model: str, interface: str, part: str = "fmus") -> Path:
    version = THIRD_PARTY[model][0]
    importer = ("deltafmi", VERSION) if part == "results" else ()
    return root.joinpath(part, version, interface, PLATFORMS[version], *importer, "ThirdParty", "1.0", model)


@pytest.fixture(scope="module")
def others(tmp_path_factory) -> Path:
    """A tree of plain-C FMUs of tests/third_party (FMI 2.0 and 3.0) with references by fmpy
    (or, where given, from the model's equations)."""
    root = tmp_path_factory.mktemp("others")
    build = tmp_path_factory.mktemp("c_fmus")
    for model, (version, stop, step, tolerance, signals) in THIRD_PARTY.items():
        fmu = build_fmu(model, build)
        for interface in ("cs", "me"):
            folder = third_party_folder(root, model, interface)
            folder.mkdir(parents=True)
            shutil.copyfile(fmu, folder / f"{model}.fmu")
            write_options(folder / f"{model}_ref.opt", RefOptions(0.0, stop, step, tolerance))
            t = np.linspace(0.0, stop, int(round(stop / step)) + 1)
            if signals:
                write_table(folder / f"{model}_in.csv", t, signals(t))
            md = fmpy.read_model_description(str(folder / f"{model}.fmu"))
            outputs = [v.name for v in md.modelVariables
                       if v.causality == "output" and v.type not in ("String", "Binary")]
            if interface == "me" and model in EXACT:
                write_table(folder / f"{model}_ref.csv", t, EXACT[model](t))
                continue
            result = fmpy_run(folder, model, interface, outputs)
            write_table(folder / f"{model}_ref.csv", result["time"], {n: result[n] for n in outputs})
    return root


def test_import_of_third_party_fmus_passes(others):
    result = invoke("compat", "import", str(others))
    assert result.exit_code == 0, result.output
    assert f"{2 * len(THIRD_PARTY)} passed, 0 failed, 0 rejected of {2 * len(THIRD_PARTY)} FMUs" in result.output
    for model in THIRD_PARTY:
        for interface in ("cs", "me"):
            folder = third_party_folder(others, model, interface, "results")
            assert sorted(p.name for p in folder.iterdir()) == sorted([f"{model}_out.csv", "ReadMe.md", "passed"])
            out = read_table(folder / f"{model}_out.csv")
            ref = read_table(third_party_folder(others, model, interface) / f"{model}_ref.csv")
            assert out.names == ref.names and out.time[-1] == pytest.approx(ref.time[-1])
            assert all(out.columns[n].shape[1:] == ref.columns[n].shape[1:] for n in ref.names)  # arrays whole
    # fmpy's Cross-Check validator (FMI 1.0 and 2.0) re-checks every 'passed' against its reference
    assert validate_repo(str(others))[2] == []


def test_a_broken_reference_fails(others, tmp_path):
    folder = third_party_folder(tmp_path, "BouncingBall", "cs")
    shutil.copytree(third_party_folder(others, "BouncingBall", "cs"), folder)
    reference = read_table(folder / "BouncingBall_ref.csv")
    h = reference.columns["h"]
    reference.columns["h"] = h + 0.03 * np.ptp(h) * (reference.time > 1.0)  # 3 % of the range, after 1 s
    write_table(folder / "BouncingBall_ref.csv", reference.time, reference.columns)
    result = invoke("compat", "import", str(tmp_path))
    assert result.exit_code == 1 and "0 passed, 1 failed" in result.output
    status = third_party_folder(tmp_path, "BouncingBall", "cs", "results")
    assert (status / "failed").exists() and not (status / "passed").exists()
    readme = (status / "ReadMe.md").read_text()
    found = re.search(r"^h: \S+ at t = (\S+) s is outside the band", readme, re.M)
    assert found and float(found.group(1)) > 1.0, readme  # not before the reference went wrong


def test_bad_trees_are_one_line(tmp_path):
    result = invoke("compat", "import", str(tmp_path))
    assert result.exit_code == 2 and "no fmus/ folder" in result.output and "Traceback" not in result.output
    folder = tmp_path / "fmus" / "2.0" / "cs" / "linux64" / "X" / "1" / "M"
    folder.mkdir(parents=True)
    (folder / "M.fmu").write_bytes(b"not a zip")
    (folder / "M_ref.csv").write_text('"time","y"\n0,1\n1,1\n')
    (folder / "M_ref.opt").write_text("StartTime, 0\nStopTime, 1\n")
    result = invoke("compat", "import", str(tmp_path))
    assert result.exit_code == 0 and "1 rejected of 1" in result.output
    result = invoke("compat", str(tmp_path / "out"), "--models", "NoSuchModel")
    assert result.exit_code == 2 and "NoSuchModel: not a packaged model" in result.output
