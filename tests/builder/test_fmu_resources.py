"""Files in an FMU's resources/: ``deltafmi build --resource``, a scenario component's ``resources:``
(content-keyed in the build cache, checked at load), ``deltafmi examples copy``, and the shipped
mpc_press example, whose controller FMU carries its linear model and so runs from any folder."""
from __future__ import annotations

import importlib.util
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner
from fmpy import simulate_fmu

from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.shipped import SCENARIOS_DIR

ROOT = Path(__file__).resolve().parents[2]
SHIPPED_MODEL = SCENARIOS_DIR / "mpc_press_model.npz"

#: a component that reads a number from a file of its FMU's resources at initialization
TABLE_GAIN = textwrap.dedent('''\
    import os

    from deltafmi.component import Component, Experiment, Output, Parameter


    class TableGain(Component):
        """Outputs the number written in the file `table` of its FMU's resources."""

        default_experiment = Experiment(start=0.0, stop=0.01, step=1e-3)
        table = Parameter("gain.txt", type=str, description="A file in the FMU's resources")
        gain = Output(0.0, description="The number in the file")

        def initialize(self, t):
            with open(os.path.join(self.resources_dir, self.table), encoding="utf-8") as f:
                self._gain = float(f.read())

        def outputs(self, t):
            self.gain = self._gain
    ''')

SCENARIO = textwrap.dedent('''\
    experiment: {start: 0.0, stop: 0.01, step: 1.0e-3}
    components:
      table:
        source: table_gain.py
        resources: [gain.txt]
    outputs: [table.gain]
    ''')


def _invoke(*args: str):
    return CliRunner().invoke(main, list(args))


@pytest.fixture
def component(tmp_path: Path) -> Path:
    """table_gain.py and its gain.txt (2.5) in ``tmp_path``."""
    (tmp_path / "table_gain.py").write_text(TABLE_GAIN)
    (tmp_path / "gain.txt").write_text("2.5\n")
    return tmp_path / "table_gain.py"


def test_a_resource_reaches_the_fmu_and_its_component_reads_it(tmp_path, component, monkeypatch):
    """`build --resource`: the file is resources/gain.txt, byte for byte, and the component reads it
    at initialization, in fmpy (both interfaces), from a folder that has no such file. 2.5 is a
    binary fraction: float("2.5") is exact, so the output equals it exactly."""
    fmu = tmp_path / "TableGain.fmu"
    result = _invoke("build", str(component), "--resource", str(tmp_path / "gain.txt"), "-o", str(fmu))
    assert result.exit_code == 0, result.output
    with zipfile.ZipFile(fmu) as archive:
        assert "resources/gain.txt" in archive.namelist()
        assert archive.read("resources/gain.txt") == b"2.5\n"
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    monkeypatch.chdir(elsewhere)
    for fmi_type in ("CoSimulation", "ModelExchange"):
        run = simulate_fmu(str(fmu), fmi_type=fmi_type, output=["gain"])
        assert np.all(run["gain"] == 2.5), fmi_type


def test_build_refuses_a_resource_that_takes_a_name_of_the_fmus_own(tmp_path, component):
    (tmp_path / "deltafmi.json").write_text("{}")
    result = _invoke("build", str(component), "--resource", str(tmp_path / "deltafmi.json"),
                     "-o", str(tmp_path / "x.fmu"))
    assert result.exit_code == 2
    assert "resource " in result.output and "resources/deltafmi.json has that name" in result.output
    assert not (tmp_path / "x.fmu").exists()


def _run(scenario: Path) -> tuple[Path, float]:
    """The FMU the scenario's component gets from the build cache, and the gain it outputs."""
    system = resolve_system(load_scenario(scenario))
    out = scenario.with_suffix(".csv")
    Master(system, result=out).run()
    return system.components[0].fmu, float(columns(out)["table.gain"][-1])


def test_a_scenarios_resources_are_part_of_its_fmus_cache_key(tmp_path, component):
    """New content -> another FMU (built, carrying it); the old content again -> the first FMU
    (keyed by content, not by the file's time)."""
    scenario = tmp_path / "table.yaml"
    scenario.write_text(SCENARIO)
    first, gain = _run(scenario)
    assert gain == 2.5
    (tmp_path / "gain.txt").write_text("4.0\n")
    second, gain = _run(scenario)
    assert gain == 4.0 and second != first
    with zipfile.ZipFile(second) as archive:
        assert archive.read("resources/gain.txt") == b"4.0\n"
    (tmp_path / "gain.txt").write_text("2.5\n")
    assert _run(scenario) == (first, 2.5)


def test_a_missing_resource_is_an_error_at_its_line(tmp_path, component):
    """file:line: error: naming the component and the file, exit 2; `resources` with `fmu` too."""
    scenario = tmp_path / "table.yaml"
    scenario.write_text(SCENARIO.replace("[gain.txt]", "\n      - gain.txt\n      - missing.npz"))
    result = _invoke("run", str(scenario))
    assert result.exit_code == 2
    assert f"{scenario}:7: error: component 'table': resource 'missing.npz' not found" in result.output
    scenario.write_text(SCENARIO.replace("source: table_gain.py", "fmu: TableGain.fmu"))
    result = _invoke("run", str(scenario))
    assert result.exit_code == 2
    assert f"{scenario}:5: error: component 'table': resources go into an FMU built from 'source'" in result.output


def test_the_shipped_linear_model_is_what_the_tool_makes_now(tmp_path):
    """tools/make_mpc_model.py run again gives the shipped mpc_press_model.npz: a stale file (the
    robot's model changed) fails here. Here the two are identical to the bit (deterministic code).
    Another machine's rounding: the equilibrium solve stops ~1e-14 relative from the root, and the
    FMU's central differences (steps ~1e-6 relative) turn eps = 2.2e-16 into ~1e-10 relative of
    each matrix's largest entry; 1e-9 of it bounds both, while a changed parameter moves A by its
    own relative change (1e-3 of a mass: 1e-3)."""
    spec = importlib.util.spec_from_file_location("make_mpc_model", ROOT / "tools" / "make_mpc_model.py")
    tool = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(tool)
    fresh, shipped = np.load(tool.make_model(tmp_path / "fresh.npz")), np.load(SHIPPED_MODEL)
    assert sorted(fresh.files) == sorted(shipped.files)
    for name in ("inputs", "outputs", "states"):
        assert list(fresh[name]) == list(shipped[name])
    for name in ("A", "B", "C", "D", "x0", "u0", "y0"):
        scale = max(float(np.abs(shipped[name]).max()), 1.0)
        np.testing.assert_allclose(fresh[name], shipped[name], rtol=0.0, atol=1e-9 * scale, err_msg=name)
    assert SHIPPED_MODEL.stat().st_size < 20_000  # commit-size small


def test_the_controller_fmu_carries_no_co_simulation_code():
    """MpcController reads its model with numpy: its FMU carries none of deltafmi.master (which
    imports fmpy, a host's package, not an FMU's)."""
    from deltafmi.builder.packager import runtime_modules
    carried = runtime_modules(ROOT / "fmu_src" / "mpc_controller.py")
    assert "deltafmi.physics.control.contact_mpc" in carried
    assert not [name for name in carried if name.startswith("deltafmi.master")]


def test_mpc_press_runs_from_any_folder_and_from_its_copy(tmp_path, monkeypatch):
    """From an empty folder (no linear model there: the controller's FMU carries it) and from a
    copy made by `examples copy`, which copies the model beside the scenario; 0.1 s, before
    contact (the press itself and its limits: tests/models/test_mpc_controller.py)."""
    monkeypatch.chdir(tmp_path)
    result = _invoke("run", "mpc_press", "--stop", "0.1", "-q", "-o", "shipped.csv")
    assert result.exit_code == 0, result.output
    assert not list(tmp_path.glob("*.npz"))
    result = _invoke("examples", "copy", "mpc_press", "mine")
    assert result.exit_code == 0, result.output
    assert (tmp_path / "mine" / "mpc_press_model.npz").read_bytes() == SHIPPED_MODEL.read_bytes()
    result = _invoke("run", "mine/mpc_press.yaml", "--stop", "0.1", "-q", "-o", "copy.csv")
    assert result.exit_code == 0, result.output
    shipped, copy = columns(tmp_path / "shipped.csv"), columns(tmp_path / "copy.csv")
    for c in (shipped, copy):
        assert np.all(c["mpc.status"] == 0)
    # the same model and components (the copies' sources are the packaged ones): the same run
    np.testing.assert_array_equal(shipped["mpc_plant.z[3]"], copy["mpc_plant.z[3]"])
