"""SSP 1.0 archives: ``deltafmi export-ssp`` writes one, ``deltafmi run`` runs one.

* A YAML scenario and the SSP exported from it give the same samples in our master (every
  column, bit for bit; asserted to 1e-12): FMUs built from sources, ME solver options, every
  FMI type as parameter and connection, factor/offset, multi-rate, adaptive step, Jacobi and
  Gauss-Seidel, recorded patterns, result settings; and the flagship delta robot loop.
* The SSD is valid against the SSP 1.0 XSDs (fmpy's ``read_ssd`` validates it; the inline
  parameter sets against SystemStructureParameterValues.xsd) and says what it should.
* Two third-party masters load the archive as it is: OSP libcosim (libcosimpy) and Ecos (ecospy)
  give our Jacobi samples, to the last bit, on a grid both hold exactly (h = 1/128 s).
* Broken archives fail with ``<archive>/SystemStructure.ssd:<line>: error: ...`` and exit 2.
"""
from __future__ import annotations

import re
import zipfile
from pathlib import Path
from typing import Callable, Dict

import numpy as np
import pytest
from click.testing import CliRunner
from lxml import etree

from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns
from deltafmi.master.ssp.format import NAMESPACES, SSD_NAME, schema_problems
from third_party.build import build_fmu as build_c_fmu

ROOT = Path(__file__).resolve().parents[2]
OSCILLATOR = ROOT / "fmu_src" / "oscillator.py"
H = 0.0078125  # 1/128 s: its multiples are exact in binary and in libcosim's nanoseconds


@pytest.fixture(scope="module")
def all_types(tmp_path_factory) -> Path:
    """The plain-C FMU with an input, output and parameter of every FMI type."""
    return build_c_fmu("AllTypes", tmp_path_factory.mktemp("c_fmus"))


def optional(name: str):
    """Import a third-party master, or skip saying why (ecospy needs Debian's libtbb12)."""
    try:
        return __import__(name)
    except (ImportError, OSError) as exc:
        pytest.skip(f"{name} is not usable here: {exc}")


def cli(*args: str, code: int = 0) -> str:
    result = CliRunner().invoke(main, [str(a) for a in args])
    assert result.exit_code == code, result.output
    return result.output


def export(scenario: Path, ssp: Path) -> Path:
    result = CliRunner().invoke(main, ["export-ssp", str(scenario), "-o", str(ssp)])
    assert result.exit_code == 0, result.output
    assert result.stdout.splitlines()[-1].startswith(f"wrote {ssp} (")  # (stderr may say it made the folder)
    return ssp


def deviation(a: Dict[str, np.ndarray], b: Dict[str, np.ndarray]) -> float:
    """Largest difference between two results with the same columns (strings must be equal)."""
    assert list(a) == list(b) and len(a["time"]) == len(b["time"])
    worst = 0.0
    for name in a:
        if a[name].dtype == object:
            assert list(a[name]) == list(b[name]), name
        else:
            worst = max(worst, float(np.max(np.abs(a[name] - b[name]))))
    return worst


def ssd_of(ssp: Path) -> etree._Element:
    with zipfile.ZipFile(ssp) as archive:
        return etree.fromstring(archive.read(SSD_NAME))


def rewrite(ssp: Path, out: Path, edit: Callable[[str], str]) -> Path:
    """A copy of ``ssp`` whose SSD text went through ``edit``."""
    with zipfile.ZipFile(ssp) as source, zipfile.ZipFile(out, "w") as target:
        for item in source.infolist():
            data = source.read(item)
            target.writestr(item, edit(data.decode()) if item.filename == SSD_NAME else data)
    return out


# --- YAML -> SSP -> our master ------------------------------------------------------------------

MIXED = """description: every FMI type through an SSP
experiment: {{start: 0.0, stop: 1.0, step: 0.01}}
master: {{algorithm: {algorithm}}}
components:
  osc:
    source: {oscillator}
    interface: ME
    parameters: {{k: 20.0, e: 0.5, t_step: 0.4}}
    solver: {{rtol: 1.0e-9, atol: 1.0e-11, method: bdf, max_step: 0.05}}
  mt:
    fmu: {all_types}
    interface: CS
    parameters: {{gain: 3, offset: 10, invert: true, prefix: 'seen "now", ', tint: green}}
  mt2:
    fmu: {all_types}
    interface: ME
    step_multiple: 2
    parameters: {{tint: 3, prefix: ''}}
connections:
  - {{from: osc.energy, to: mt.u, factor: 0.5, offset: -1.0}}
  - {{from: osc.impacts, to: mt.u_int}}
  - {{from: osc.force_on, to: mt.u_bool}}
  - {{from: mt.y_str, to: mt2.u_str}}
  - {{from: mt.y_color, to: mt2.u_color}}
  - {{from: mt.y, to: mt2.u}}
outputs: ['osc.*', 'mt.y*', 'mt2.y*', mt2.x]
result: {{every: 2}}
"""

ADAPTIVE = """experiment: {{stop: 2.0, step: 0.01}}
master:
  algorithm: jacobi
  adaptive: {{enabled: true, tolerance: 1.0e-5, abs_tolerance: 1.0e-7, max_step: 0.1}}
components:
  a: {{source: {oscillator}, parameters: {{k: 30.0}}}}
  b: {{source: {oscillator}, parameters: {{c: 1.0}}}}
connections:
  - {{from: a.energy, to: b.F, factor: 0.2, offset: 0.5}}
outputs: ['*.x', '*.energy']
result: {{file: out/r.csv}}
"""


@pytest.mark.parametrize("name, algorithm", [("mixed", "gauss-seidel"), ("mixed", "jacobi"), ("adaptive", None)])
def test_yaml_and_its_ssp_give_the_same_samples(all_types, tmp_path, name, algorithm):
    text = {"mixed": MIXED, "adaptive": ADAPTIVE}[name]
    scenario = tmp_path / f"{name}.yaml"
    scenario.write_text(text.format(oscillator=OSCILLATOR, all_types=all_types, algorithm=algorithm))
    cli("run", scenario, "-o", tmp_path / "yaml.csv", "-q")
    ssp = export(scenario, tmp_path / "system" / f"{name}.ssp")
    if name == "adaptive":  # the result file travels, relative to the archive
        cli("run", ssp, "-q")
        ours = tmp_path / "system" / "out" / "r.csv"
    else:
        cli("run", ssp, "-o", tmp_path / "ssp.csv", "-q")
        ours = tmp_path / "ssp.csv"
    yaml_result, ssp_result = columns(tmp_path / "yaml.csv"), columns(ours)
    assert deviation(yaml_result, ssp_result) <= 1e-12  # measured: 0.0
    if name == "mixed":  # the recorded patterns, every second row, the string parameter travelled
        assert {"osc.x", "osc.energy", "mt.y_str", "mt2.y_color", "mt2.x"} <= set(ssp_result)
        assert "mt.u" not in ssp_result
        assert len(ssp_result["time"]) > 51 and ssp_result["time"][1] == 0.02
        assert ssp_result["mt.y_str"][0] == 'seen "now", '
    else:
        assert len(ssp_result["time"]) < 150  # the adaptive step grew
        again = export(ssp, tmp_path / "system" / "again.ssp")  # SSP -> SSP says the same
        stamp = lambda root: root.attrib.pop("generationDateAndTime") and etree.tostring(root)  # noqa: E731
        assert stamp(ssd_of(again)).replace(b'"again"', b'"adaptive"') == stamp(ssd_of(ssp))


def test_delta_robot_loop_through_an_ssp(tmp_path):
    """The flagship loop (three FMUs built from sources, ME plant, 18 scalar connections)."""
    scenario = ROOT / "scenarios" / "delta_tracking.yaml"
    cli("run", scenario, "-o", tmp_path / "yaml.csv", "--stop", "0.02", "-q")
    ssp = export(scenario, tmp_path / "delta.ssp")
    cli("run", ssp, "-o", tmp_path / "ssp.csv", "--stop", "0.02", "-q")
    assert deviation(columns(tmp_path / "yaml.csv"), columns(tmp_path / "ssp.csv")) <= 1e-12


# --- what the archive holds ---------------------------------------------------------------------

def test_exported_ssd_is_valid_ssp_1_0_and_complete(all_types, tmp_path):
    from fmpy.ssp.ssd import read_ssd

    scenario = tmp_path / "mixed.yaml"
    scenario.write_text(MIXED.format(oscillator=OSCILLATOR, all_types=all_types, algorithm="jacobi"))
    ssp = export(scenario, tmp_path / "mixed.ssp")
    with zipfile.ZipFile(ssp) as archive:
        names = sorted(archive.namelist())
    assert names == ["SystemStructure.ssd", "resources/AllTypes.fmu", "resources/Oscillator.fmu"]

    ssd = read_ssd(str(ssp))  # validates against fmpy's SSP 1.0 XSDs
    components = {c.name: c for c in ssd.system.elements}
    assert {n: c.source for n, c in components.items()} == {
        "osc": "resources/Oscillator.fmu", "mt": "resources/AllTypes.fmu", "mt2": "resources/AllTypes.fmu"}
    assert len(ssd.system.connections) == 6
    mt_set = components["mt"].parameterBindings[0].parameterValues[0]
    assert {p.name: (p.type, p.value) for p in mt_set.parameters} == {
        "gain": ("Real", "3.0"), "offset": ("Integer", "10"), "invert": ("Boolean", "true"),
        "prefix": ("String", 'seen "now", '), "tint": ("Enumeration", "green")}

    root = ssd_of(ssp)
    for parameter_set in root.iter(f"{{{NAMESPACES['ssv']}}}ParameterSet"):
        assert schema_problems(parameter_set, "ssv") == []
    x = lambda path: root.xpath(path, namespaces=NAMESPACES)  # noqa: E731
    assert x("ssd:DefaultExperiment/@startTime") == ["0.0"] and x("ssd:DefaultExperiment/@stopTime") == ["1.0"]
    assert x("//ssd:Component[@name='osc']/@implementation") == ["ModelExchange"]
    assert x("//ssd:Component[@name='mt']/@implementation") == ["CoSimulation"]
    transform = x("//ssd:Connection[@startConnector='energy']/ssc:LinearTransformation")[0]
    assert (transform.get("factor"), transform.get("offset")) == ("0.5", "-1.0")
    assert x("//ssd:Connection[@endConnector='u_int']/ssc:LinearTransformation") == []
    assert x("//ssd:Connector[@name='u_color']/ssc:Enumeration/@name") == ["Color"]
    assert x("ssd:Enumerations/ssc:Enumeration[@name='Color']/ssc:Item/@name") == ["red", "green", "blue"]
    # what SSP 1.0 cannot say, in annotations: ours, and libcosim's step
    assert x("//ssc:Annotation[@type='com.deltafmi']/dfmi:Master/@step") == ["0.01"]
    assert x("//osp:FixedStepAlgorithm/@baseStepSize") == ["0.01"]
    assert x("//ssd:Component[@name='osc']//dfmi:Solver/@rtol") == ["1e-09"]
    assert x("//ssd:Component[@name='mt2']//dfmi:Component/@step_multiple") == ["2"]
    assert x("//dfmi:Results/dfmi:Record/@pattern") == ["osc.*", "mt.y*", "mt2.y*", "mt2.x"]


# --- third-party masters ------------------------------------------------------------------------

PAIR = """experiment: {stop: 1.0, step: 0.0078125}
master: {algorithm: jacobi}
components:
  a: {fmu: FMU, interface: CS, parameters: {k: 20.0, c: 0.5}}
  b: {fmu: FMU, interface: CS, step_multiple: MULTIPLE, parameters: {e: 0.5, F_step: 2.0, t_step: 0.3}}
connections:
  - {from: a.energy, to: b.F, factor: 0.05, offset: 0.1}
outputs: [a.x, a.energy, b.x, b.v, b.F]
"""
PAIR_COLUMNS = ["a.x", "a.energy", "b.x", "b.v", "b.F"]


def pair(build_fmu_from_src, tmp_path: Path, multiple: int = 1):
    """Two Co-Simulation oscillators, a's energy driving b's force through factor/offset:
    (the exported SSP, our Jacobi result without its t = 0 row)."""
    scenario = tmp_path / "pair.yaml"
    scenario.write_text(PAIR.replace("FMU", str(build_fmu_from_src("oscillator.py")))
                        .replace("MULTIPLE", str(multiple)))
    cli("run", scenario, "-o", tmp_path / "ours.csv", "-q")
    ours = columns(tmp_path / "ours.csv")
    return export(scenario, tmp_path / "pair.ssp"), np.column_stack([ours[n][1:] for n in PAIR_COLUMNS])


@pytest.mark.parametrize("multiple", [1, 2])
def test_libcosim_runs_the_exported_ssp_like_our_jacobi(build_fmu_from_src, tmp_path, multiple):
    """libcosim reads the step (osp:FixedStepAlgorithm), the parameter set, the linear
    transformation and, for multi-rate, osp:StepSizeHint; it agrees on every sample where
    both masters have stepped every component (all rows, or every second row for b)."""
    optional("libcosimpy")
    from libcosimpy.CosimExecution import CosimExecution
    from libcosimpy.CosimLogging import CosimLogLevel, log_output_level
    from libcosimpy.CosimObserver import CosimObserver

    ssp, ours = pair(build_fmu_from_src, tmp_path, multiple)
    log_output_level(CosimLogLevel.WARNING)
    execution = CosimExecution.from_ssp_file(str(ssp))
    observer = CosimObserver.create_last_value()
    execution.add_observer(observer)
    slaves = {info.name.decode(): info.index for info in execution.slave_infos()}
    refs = []
    for column in PAIR_COLUMNS:
        name, variable = column.split(".")
        vr = next(v.reference for v in execution.slave_variables(slaves[name]) if v.name.decode() == variable)
        refs.append((slaves[name], vr))
    theirs = []
    for _ in range(len(ours)):
        assert execution.step()
        theirs.append([observer.last_real_values(slave, [vr])[0] for slave, vr in refs])
    theirs = np.array(theirs)
    rows = slice(multiple - 1, None, multiple)
    assert np.max(np.abs(theirs[rows] - ours[rows])) <= 1e-12  # measured: 0.0
    assert np.max(np.abs(theirs[:, :2] - ours[:, :2])) <= 1e-12  # a steps every step in both
    assert abs(theirs[-1, 3]) > 0.1  # b moved


def test_ecos_runs_the_exported_ssp_like_our_jacobi(build_fmu_from_src, tmp_path):
    """Ecos applies the parameter set by name and the linear transformation; outputs and
    states agree to the last bit. Its b.F after a step is the value the connection gives at
    that time (applied in the next step); our row shows the value the step used: one row later."""
    ecospy = optional("ecospy")
    ssp, ours = pair(build_fmu_from_src, tmp_path)
    theirs = []
    with ecospy.EcosSimulation(step_size=H, ssp_path=str(ssp)) as simulation:
        simulation.init(parameter_set="start values")
        for _ in range(len(ours)):
            simulation.step()
            theirs.append([simulation.get_real(c.replace(".", "::")) for c in PAIR_COLUMNS])
        assert simulation.get_time() == 1.0
        simulation.terminate()
    theirs = np.array(theirs)
    assert np.max(np.abs(theirs[:, :4] - ours[:, :4])) <= 1e-12  # measured: 0.0
    assert np.max(np.abs(theirs[:-1, 4] - ours[1:, 4])) <= 1e-12


# --- reading archives that are not ours, and broken ones ----------------------------------------

def test_bare_ssd_without_our_annotations_runs(build_fmu_from_src, tmp_path):
    """Unpacked, our annotations removed (as another tool would write it): the step comes from
    libcosim's annotation, the recorded variables default to every output, and without a stop
    time --stop must say it."""
    ssp, ours = pair(build_fmu_from_src, tmp_path)
    folder = tmp_path / "unpacked"
    with zipfile.ZipFile(ssp) as archive:
        archive.extractall(folder)
    ssd = folder / SSD_NAME
    root = etree.parse(str(ssd)).getroot()
    for annotation in root.xpath("//ssc:Annotation[@type='com.deltafmi']", namespaces=NAMESPACES):
        parent = annotation.getparent()
        parent.remove(annotation)
        if len(parent) == 0:
            parent.getparent().remove(parent)
    del root.find("ssd:DefaultExperiment", NAMESPACES).attrib["stopTime"]
    ssd.write_bytes(etree.tostring(root))
    message = cli("run", ssd, code=2).strip().splitlines()[-1]
    assert re.fullmatch(rf"{re.escape(str(ssd))}:\d+: error: no DefaultExperiment stopTime: .*--stop", message)
    cli("run", ssd, "-o", tmp_path / "bare.csv", "--stop", "1.0", "-q")
    bare = columns(tmp_path / "bare.csv")
    assert "a.impacts" in bare and "a.x" not in bare  # every output, no states
    assert np.max(np.abs(bare["a.energy"][1:] - ours[:, 1])) <= 1e-12


def test_parameters_from_an_ssv_file_bound_at_system_level(build_fmu_from_src, tmp_path):
    """a's parameters moved out of the SSD into resources/a.ssv, bound to the system with
    prefix "a." (SSP 1.0's way to aim a component's parameter set at one element)."""
    ssp, ours = pair(build_fmu_from_src, tmp_path)
    root = ssd_of(ssp)
    bindings = root.xpath("//ssd:Component[@name='a']/ssd:ParameterBindings", namespaces=NAMESPACES)[0]
    parameter_set = bindings.xpath(".//ssv:ParameterSet", namespaces=NAMESPACES)[0]
    bindings.getparent().remove(bindings)
    system = root.find("ssd:System", NAMESPACES)
    system.insert(0, etree.fromstring(
        f'<ssd:ParameterBindings xmlns:ssd="{NAMESPACES["ssd"]}">'
        '<ssd:ParameterBinding source="resources/a.ssv" prefix="a."/></ssd:ParameterBindings>'))
    moved = tmp_path / "moved.ssp"
    with zipfile.ZipFile(ssp) as source, zipfile.ZipFile(moved, "w") as target:
        for item in source.infolist():
            target.writestr(item, etree.tostring(root) if item.filename == SSD_NAME else source.read(item))
        target.writestr("resources/a.ssv", etree.tostring(parameter_set))
    cli("run", moved, "-o", tmp_path / "moved.csv", "-q")
    moved_result = columns(tmp_path / "moved.csv")
    assert np.max(np.abs(np.column_stack([moved_result[n][1:] for n in PAIR_COLUMNS]) - ours)) <= 1e-12


def test_validate_accepts_an_ssp(build_fmu_from_src, tmp_path):
    ssp, _ = pair(build_fmu_from_src, tmp_path)
    output = cli("validate", ssp)
    assert "2 components, 1 scalar connections, 5 recorded variables" in output
    assert output.strip().endswith(f"{ssp}: OK")


BROKEN = {
    # (what to replace, with what, expected message after "<file>:<line>: error: "); the line is
    # the one with the replacement (for a parameter: the ssv:Parameter element, one above)
    "schema": ('factor="0.05"', 'factor="fast"',
               "not valid SSP 1.0: Element 'ssc:LinearTransformation', attribute 'factor': 'fast' is not a "
               "valid value of the atomic type 'xs:double'."),
    "variable": ('endConnector="F"', 'endConnector="FF"',
                 "'FF' is not a connector of component 'b' (declare it in its ssd:Connectors) (did you mean 'F'?)"),
    "parameter": ('<ssv:Real value="20.0"/>', '<ssv:String value="stiff"/>',
                  "component 'a': parameter 'k': type mismatch: 'k' is Real but the value 'stiff' is str"),
    "fmu": ('source="resources/oscillator.fmu"', 'source="resources/oscilator.fmu"',
            "component 'a': no 'resources/oscilator.fmu' in the archive (did you mean 'resources/oscillator.fmu'?)"),
    "nested": ("</ssd:Elements>", '<ssd:System name="inner"/></ssd:Elements>',
               "'inner': nested systems are not supported (a flat system of FMU components is)"),
}


@pytest.mark.parametrize("case", list(BROKEN))
def test_broken_archive_names_the_ssd_line(build_fmu_from_src, tmp_path, case):
    old, new, message = BROKEN[case]
    ssp, _ = pair(build_fmu_from_src, tmp_path)
    broken = rewrite(ssp, tmp_path / "broken.ssp", lambda text: text.replace(old, new, 1))
    with zipfile.ZipFile(broken) as archive:
        text = archive.read(SSD_NAME).decode()
    line = next(i for i, l in enumerate(text.splitlines(), 1) if new in l) - (case == "parameter")
    output = cli("run", broken, code=2)
    assert output.strip().splitlines()[-1] == f"{broken}/{SSD_NAME}:{line}: error: {message}"
