"""Issue 26: a component's kernels compiled to C and called by its FMU's C layer with no Python.

The compiled and the Python paths of the same FMU (``DELTAFMI_NATIVE=0`` switches the compiled
one off at instantiation) must give the same numbers bit for bit: the generated C performs the
kernels' float operations in Python's order (deltafmi/builder/codegen). That the C path really
runs is shown by the test component's ``python_calls`` output, which only its Python derivatives
method advances. Physics: the test oscillator against its closed-form response.
"""
from __future__ import annotations

import ctypes
import json
import math
import subprocess
import sys
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Model, defaultCallbacks, fmi2CallbackFunctions, fmi2CallbackLoggerTYPE

from deltafmi.builder import build_fmu

ROOT = Path(__file__).resolve().parents[2]
COMPILED = ROOT / "tests" / "components" / "compiled" / "model.py"
OUTPUTS = ("y", "yd", "sign", "positive")


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    folder = tmp_path_factory.mktemp("native")
    return {version: build_fmu(COMPILED, folder / f"CompiledOscillator{version}.fmu", fmi_version=version)
            for version in (2, 3)}


def _simulate(fmu, native: bool, monkeypatch, **kwargs):
    monkeypatch.setenv("DELTAFMI_NATIVE", "1" if native else "0")
    return simulate_fmu(str(fmu), fmi_type="ModelExchange", output_interval=0.01, output=[*OUTPUTS, "python_calls"],
                        **kwargs)


@pytest.mark.parametrize("version", [2, 3])
def test_compiled_kernels_run_and_equal_the_python_bit_for_bit(fmus, version, monkeypatch):
    compiled = _simulate(fmus[version], True, monkeypatch, start_values={"u": 0.3})
    python = _simulate(fmus[version], False, monkeypatch, start_values={"u": 0.3})
    for name in OUTPUTS:
        assert np.array_equal(compiled[name], python[name]), name
    # the Python derivatives ran only in initialization with the compiled kernels on
    assert compiled["python_calls"][-1] <= 5
    assert python["python_calls"][-1] > 100


def test_compiled_oscillator_follows_the_closed_form(fmus, monkeypatch):
    omega, zeta, u, gain, offset = 3.0, 0.1, 0.3, 2.0, 0.5
    result = _simulate(fmus[2], True, monkeypatch, start_values={"u": u}, relative_tolerance=1e-10)
    t = result["time"]
    wd = omega * math.sqrt(1.0 - zeta ** 2)
    x_ss = u / omega ** 2  # x(0) = 1, x'(0) = 0 about the static deflection
    a = 1.0 - x_ss
    x = x_ss + a * np.exp(-zeta * omega * t) * (np.cos(wd * t) + zeta * omega / wd * np.sin(wd * t))
    assert np.max(np.abs(result["y"] - (gain * x + offset))) < 1e-6
    assert np.array_equal(result["sign"], np.where(x > 0, 1, np.where(x < 0, -1, 0)))


class _Instance:
    """One FMI 2.0 Model Exchange instance through fmpy, messages collected."""

    def __init__(self, fmu: Path, name: str, parameters: dict) -> None:
        md = read_model_description(str(fmu))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.messages: list[str] = []
        self.model = FMU2Model(guid=md.guid, unzipDirectory=extract(str(fmu)),
                               modelIdentifier=md.modelExchange.modelIdentifier, instanceName=name)
        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(lambda env, inst, status, cat, msg: self.messages.append(msg.decode()))
        callbacks.allocateMemory = defaultCallbacks.allocateMemory
        callbacks.freeMemory = defaultCallbacks.freeMemory
        self._callbacks = callbacks
        self.model.instantiate(callbacks=callbacks, loggingOn=True)
        self.model.setupExperiment(startTime=0.0)
        self.model.enterInitializationMode()
        for name_, value in parameters.items():
            self.model.setReal([self.vr[name_]], [value])
        self.model.exitInitializationMode()
        self.model.newDiscreteStates()
        self.model.enterContinuousTimeMode()

    def derivatives(self) -> list[float]:
        dx = (ctypes.c_double * 2)()
        self.model.getDerivatives(dx, 2)
        return list(dx)

    def real(self, name: str) -> float:
        return self.model.getReal([self.vr[name]])[0]

    def integer(self, name: str) -> int:
        return self.model.getInteger([self.vr[name]])[0]


def test_a_raising_kernel_hands_the_call_to_python_which_explains(fmus, monkeypatch):
    monkeypatch.setenv("DELTAFMI_NATIVE", "1")
    inst = _Instance(fmus[2], "raising", {})
    inst.model.setReal([inst.vr["u"]], [2.0])
    assert inst.derivatives()[1] == 2.0 - 9.0  # x = (1, 0): u - omega^2 x
    assert inst.integer("python_calls") <= 5
    inst.model.setReal([inst.vr["u"]], [30.0])  # beyond the limit: the kernel raises
    with pytest.raises(Exception):
        inst.derivatives()
    assert any("input 30.0 is beyond the limit 10.0" in m for m in inst.messages), inst.messages


def test_instances_keep_their_own_attributes(fmus, monkeypatch):
    """Two instances of one FMU in one process, each with its attributes' struct."""
    monkeypatch.setenv("DELTAFMI_NATIVE", "1")
    slow, fast = _Instance(fmus[2], "slow", {"omega": 2.0}), _Instance(fmus[2], "fast", {"omega": 5.0})
    for _ in range(3):
        assert slow.derivatives() == [0.0, -4.0] and fast.derivatives() == [0.0, -25.0]
        slow.model.setTime(0.1)
        fast.model.setTime(0.1)
    assert slow.integer("python_calls") <= 5 and fast.integer("python_calls") <= 5


def test_flagship_with_the_compiled_plant_equals_the_python_plant(tmp_path, monkeypatch):
    """The flagship (delta_tracking): the DeltaRobot's derivatives and outputs in C, all columns
    of the result (time, 14 variables) the same bits as with its Python kernels."""
    import deltafmi

    results = {}
    for native in ("1", "0"):
        monkeypatch.setenv("DELTAFMI_NATIVE", native)
        results[native] = deltafmi.simulate("delta_tracking", stop=1.0)
    compiled, python = results["1"], results["0"]
    assert list(compiled) == list(python) and len(list(compiled)) == 15  # time and 14 variables
    for name in compiled:
        assert np.array_equal(compiled[name], python[name]), name


def test_the_fmu_carries_the_generated_c(fmus):
    with zipfile.ZipFile(fmus[2]) as archive:
        names = archive.namelist()
        description = json.loads(archive.read("resources/native_kernels.json"))
        source = archive.read("sources/CompiledOscillator_kernels.c").decode()
    assert description["library"] in names and description["kernels"] == ["derivatives", "outputs"]
    # each C line of the kernel names the Python line it comes from
    assert "raise ValueError" in source and "dfmi_kernel_derivatives" in source


BAD_KERNEL = '''
from deltafmi.component import Component, Kernel, NativeKernels, Output, Parameter, State


def rate(x, k):
    table = {{"a": k}}
    return [-table["a"] * x[0]]


class Decay(Component):
    k = Parameter(1.0)
    x = State([1.0])
    native = NativeKernels(derivatives=Kernel(rate, "states", "k"), mode="{mode}")

    def derivatives(self, t):
        return rate(self.x, self.k)
'''


def _build(tmp_path: Path, text: str) -> subprocess.CompletedProcess:
    source = tmp_path / "decay.py"
    source.write_text(text)
    return subprocess.run([sys.executable, "-c", "from deltafmi.apps.cli import main; main()", "build", str(source), "-o",
                           str(tmp_path / "Decay.fmu")],
                          capture_output=True, text=True, cwd=tmp_path)


def test_an_untranslatable_kernel_fails_the_build_naming_its_line(tmp_path):
    done = _build(tmp_path, BAD_KERNEL.format(mode="required").replace(', mode="required"', ""))  # the default
    assert done.returncode != 0
    assert "decay.py:6" in done.stderr and "Traceback" not in done.stderr, done.stderr
    assert not (tmp_path / "Decay.fmu").exists()


def test_fallback_mode_warns_naming_the_line_and_ships_python(tmp_path, monkeypatch):
    done = _build(tmp_path, BAD_KERNEL.format(mode="fallback"))
    assert done.returncode == 0, done.stderr
    assert "decay.py:6" in done.stderr and "stay Python" in done.stderr, done.stderr
    with zipfile.ZipFile(tmp_path / "Decay.fmu") as archive:
        assert "resources/native_kernels.json" not in archive.namelist()
    result = simulate_fmu(str(tmp_path / "Decay.fmu"), fmi_type="ModelExchange", stop_time=1.0,
                          relative_tolerance=1e-10, output=["x[1]"])
    assert abs(result["x[1]"][-1] - math.exp(-1.0)) < 1e-7


def test_an_unknown_argument_is_named(tmp_path):
    text = BAD_KERNEL.format(mode="required").replace('Kernel(rate, "states", "k")', 'Kernel(rate, "states", "kk")')
    done = _build(tmp_path, text)
    assert done.returncode != 0
    assert "Decay.native: derivatives argument 'kk'" in done.stderr and "Traceback" not in done.stderr, done.stderr


TALLY = ROOT / "tests" / "components" / "compiled_step" / "model.py"


@pytest.fixture(scope="module")
def tally_fmu(tmp_path_factory):
    return build_fmu(TALLY, tmp_path_factory.mktemp("tally") / "CompiledTally.fmu")


def _tally_run(fmu, native: bool, monkeypatch, u_of_step, steps: int = 100, state_at: int = -1):
    """(total, count, python_steps) after each step of an FMU2Slave, and the messages; with
    ``state_at`` >= 0 the FMU state is saved after that step and restored at the end, and the
    steps after it are taken again (their rows appended)."""
    from fmpy.fmi2 import FMU2Slave

    monkeypatch.setenv("DELTAFMI_NATIVE", "1" if native else "0")
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    messages: list[str] = []
    callbacks = fmi2CallbackFunctions()
    callbacks.logger = fmi2CallbackLoggerTYPE(lambda env, inst, status, cat, msg: messages.append(msg.decode()))
    callbacks.allocateMemory, callbacks.freeMemory = defaultCallbacks.allocateMemory, defaultCallbacks.freeMemory
    slave = FMU2Slave(guid=md.guid, unzipDirectory=extract(str(fmu)),
                      modelIdentifier=md.coSimulation.modelIdentifier, instanceName="tally")
    slave.instantiate(callbacks=callbacks, loggingOn=True)
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    rows, saved = [], None

    def take(k: int) -> None:
        slave.setReal([vr["u"]], [u_of_step(k)])
        slave.doStep(k * 0.01, 0.01)
        rows.append((slave.getReal([vr["total"]])[0], *slave.getInteger([vr["count"], vr["python_steps"]])))

    for k in range(steps):
        take(k)
        if k == state_at:
            saved = slave.getFMUstate()
    if saved is not None:
        slave.setFMUstate(saved)
        for k in range(state_at + 1, steps):
            take(k)
    slave.terminate()
    slave.freeInstance()
    return np.array(rows), messages


def _u(k: int) -> float:
    return 1.0 + 0.25 * k if k < 60 else -0.5


def test_a_compiled_step_equals_the_python_step_and_defers_its_warning(tally_fmu, monkeypatch):
    compiled, compiled_log = _tally_run(tally_fmu, True, monkeypatch, _u)
    python, python_log = _tally_run(tally_fmu, False, monkeypatch, _u)
    assert np.array_equal(compiled[:, :2], python[:, :2])
    # the first sample is the initial event update's, before any input is set (u = 0)
    expected = np.cumsum([0.0] + [2.0 * _u(k) for k in range(1, 100)])
    assert np.array_equal(compiled[:, 0], expected) and list(compiled[:, 1]) == list(range(1, 101))
    # C took every step but the one whose sample Python had to warn about
    assert compiled[-1, 2] == 1 and python[-1, 2] == 100
    warnings = [m for m in compiled_log if "negative sample" in m]
    assert warnings == [m for m in python_log if "negative sample" in m] and len(warnings) == 1


def test_the_fmu_state_holds_what_compiled_steps_changed(tally_fmu, monkeypatch):
    """fmi2GetFMUstate after compiled steps saves their attributes (copied back from C first), and
    fmi2SetFMUstate gives them to C again: the steps after the restore repeat exactly."""
    rows, _ = _tally_run(tally_fmu, True, monkeypatch, _u, state_at=39)
    first, again = rows[40:100], rows[100:]
    assert np.array_equal(first[:, :2], again[:, :2])
    assert again[-1, 1] == 100 and again[0, 0] == np.sum([2.0 * _u(k) for k in range(1, 41)])


def test_the_guides_example_builds_runs_compiled_and_follows_its_closed_form(tmp_path, monkeypatch):
    """docs/components.md, "Compiled kernels": its spring.py as written."""
    text = (ROOT / "docs" / "components.md").read_text()
    section = text[text.index("## Compiled kernels"):]
    source = section[section.index("```python\n") + 10:section.index("\n```", section.index("```python\n"))]
    (tmp_path / "spring.py").write_text(source)
    fmu = build_fmu(tmp_path / "spring.py", tmp_path / "Spring.fmu")
    with zipfile.ZipFile(fmu) as archive:
        assert json.loads(archive.read("resources/native_kernels.json"))["kernels"] == ["derivatives", "outputs"]
    results = {}
    for native in ("1", "0"):
        monkeypatch.setenv("DELTAFMI_NATIVE", native)
        results[native] = simulate_fmu(str(fmu), fmi_type="ModelExchange", stop_time=2.0, output_interval=0.01,
                                       relative_tolerance=1e-10, output=["y"])
    assert np.array_equal(results["1"]["y"], results["0"]["y"])
    t, omega, zeta = results["1"]["time"], 3.0, 0.1
    wd = omega * math.sqrt(1.0 - zeta ** 2)
    x = np.exp(-zeta * omega * t) * (np.cos(wd * t) + zeta * omega / wd * np.sin(wd * t))
    assert np.max(np.abs(results["1"]["y"] - x)) < 1e-6


def test_a_subclass_overriding_a_kernels_method_must_declare_its_own(tmp_path):
    """Inheriting the parent's kernels while overriding what they stand for would run two models
    (C and Python): the build refuses it, and ``native = None`` runs the subclass in Python."""
    source = tmp_path / "louder.py"
    head = (f"import sys\nsys.path.insert(0, {str(COMPILED.parent)!r})\nfrom model import CompiledOscillator\n\n\n"
            "class Louder(CompiledOscillator):\n")
    source.write_text(head + "    def outputs(self, t):\n        super().outputs(t)\n        self.y = 2.0 * self.y\n")
    done = _build(tmp_path, source.read_text())
    assert done.returncode != 0 and "Traceback" not in done.stderr
    assert ("Louder overrides outputs() but inherits CompiledOscillator's compiled kernels" in done.stderr
            and "native = None" in done.stderr), done.stderr
    source.write_text(source.read_text() + "\n    native = None\n")
    fmu = build_fmu(source, tmp_path / "Louder.fmu")
    result = simulate_fmu(str(fmu), fmi_type="ModelExchange", stop_time=0.1, output=["y"])
    assert result["y"][0] == 2.0 * (2.0 * 1.0 + 0.5)


def test_a_step_kernel_must_return_what_outputs_computes(tmp_path):
    """A compiled step is the whole fmi2DoStep: an output that outputs() computes after a step and
    the step kernel does not return would go stale in C; the build says which."""
    text = '''
from deltafmi.component import Component, Kernel, NativeKernels, Output, Parameter


def level(t: float, h: float, rate: float) -> float:
    return rate * (t + h)


class Ramp(Component):
    rate = Parameter(3.0)
    y = Output(0.0)
    z = Output(0.0)
    native = NativeKernels(step=Kernel(level, "t", "h", "rate", returns=("y",)))

    def do_step(self, t, h):
        self.y = level(t, h, self.rate)

    def outputs(self, t):
        self.z = 2.0 * self.y
'''
    done = _build(tmp_path, text)
    assert done.returncode != 0 and "Traceback" not in done.stderr
    assert "Ramp.native: its outputs() computes z after a step, which the step kernel does not return" in done.stderr


@pytest.mark.parametrize("name", sorted(set(__import__("deltafmi.models", fromlist=["MODELS"]).MODELS)
                                         - set(__import__("deltafmi.models", fromlist=["MODELS"]).PYTHON_ONLY)))
def test_the_fast_attribute_writer_lays_out_what_ctypes_does(name):
    """The runtime writes attributes with one struct.pack_into (FieldWriter); the bytes must be
    those of the ctypes struct built field by field (pack), for every shipped model's attributes
    after initialization, and for an Optional left None."""
    import deltafmi.models
    from deltafmi.runtime.instance import FmuInstance
    from deltafmi.runtime.native_kernels import FieldWriter, c_type, pack, record_classes, unpack
    from deltafmi.builder.codegen.component_kernels import generate_component

    cls = getattr(deltafmi.models, name)
    description = generate_component(cls).description
    instance = FmuInstance(cls)
    instance.enter_initialization(0.0, math.nan, math.nan)
    instance.evaluate(0.0)
    for attribute, desc in description["attributes"]:
        value = instance.component
        for part in attribute.split("."):
            value = getattr(value, part)
        target, writer = c_type(desc)(), FieldWriter(desc, 0)
        writer.write(target, value)
        reference = pack(desc, value)
        if isinstance(desc, str):
            assert target.value == reference, attribute
            continue
        classes: dict = {}
        record_classes(desc, value, classes)
        if '"object"' not in json.dumps(desc):  # dataclasses are never read back
            # repr: NaN (a state's cond before the first sample) is equal to itself there
            assert repr(unpack(desc, target, classes)) == repr(unpack(desc, reference, classes)), attribute
        if '"str"' not in json.dumps(desc):  # a string field holds a pointer: its bytes differ
            assert bytes(target) == bytes(reference), attribute
        if "optional" in desc:
            writer.write(target, None)
            assert bytes(target) == bytes(pack(desc, None)), attribute


def test_a_compiled_event_update_equals_the_python_update(tally_fmu, monkeypatch, capfd):
    """Model Exchange: the samples at the time events run in C (the update kernel), but the one
    Python must log; the same totals at every event as the Python update."""
    signal = np.array([(0.0, 1.0), (0.5, -1.0)], dtype=[("time", float), ("u", float)])
    results, logs = {}, {}
    for native in ("1", "0"):  # (fmpy's logger= keeps a callback process-wide that later calls reach: capfd)
        monkeypatch.setenv("DELTAFMI_NATIVE", native)
        results[native] = simulate_fmu(str(tally_fmu), fmi_type="ModelExchange", input=signal,
                                       output=["total", "count", "python_updates"])
        logs[native] = [line for line in "".join(capfd.readouterr()).splitlines() if "negative sample" in line]
    compiled, python = results["1"], results["0"]
    assert np.array_equal(compiled["total"], python["total"]) and compiled["count"][-1] == 101  # 0 .. 1 s
    assert compiled["python_updates"][-1] == 1 and python["python_updates"][-1] >= 101
    assert logs["1"] == logs["0"] and len(logs["1"]) == 1
