"""Functions a component calls itself, compiled (``NativeKernels(functions=...)``): generated C from
the Python source, in the component's kernel library, called from its Python methods.

The compiled and the Python functions must return the same numbers bit for bit (the generated C
does the float operations in Python's order), in-process (``use_compiled_functions``) and inside
the FMU (``DELTAFMI_NATIVE=0`` switches the compiled ones off); that the C really runs is shown by
the test component's ``compiled`` output. Physics: the oscillator against its closed form.
"""
from __future__ import annotations

import importlib.util
import json
import math
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fmpy import simulate_fmu

from deltafmi.builder import build_fmu
from deltafmi.builder.codegen import CodegenError, use_compiled_functions
from deltafmi.builder.codegen.component_kernels import generate_component
from deltafmi.runtime.native_functions import register_library

ROOT = Path(__file__).resolve().parents[2]
MODEL = ROOT / "tests" / "components" / "functions" / "model.py"


@pytest.fixture(scope="module")
def model():
    spec = importlib.util.spec_from_file_location("functions_model", MODEL)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def compiled(model):
    assert use_compiled_functions(model.FunctionOscillator)
    yield model
    register_library(model.FunctionOscillator, None)


def test_without_a_registered_library_the_functions_are_python(model):
    component = model.FunctionOscillator()
    component.initialize(0.0)
    assert not component.native_functions.compiled
    out = component.native_functions.rate(component._spring, [1.0, 0.5], model.Drive(0.3, 1.0), 3)
    assert isinstance(out, np.ndarray) and out.shape == (2,)
    assert out[1] == pytest.approx(0.3 - 2 * 0.1 * 3 * 0.5 - 9 * 1.0)


def test_compiled_functions_equal_the_python_ones_bit_for_bit(compiled):
    model = compiled
    component = model.FunctionOscillator()
    component.initialize(0.0)
    functions = component.native_functions
    assert functions.compiled
    python = model.FunctionOscillator.native.functions
    rng = np.random.default_rng(3)
    for _ in range(200):
        spring = model.Spring(*rng.uniform(0.1, 10.0, 2))
        x = rng.normal(size=2)
        drive = model.Drive(*rng.normal(size=2))
        steps = int(rng.integers(1, 7))
        expected = np.array(python["rate"].func(spring, x.tolist(), drive, steps))
        assert np.array_equal(functions.rate(spring, x, drive, steps), expected)
        assert np.array_equal(functions.rate(spring, list(x), drive, steps), expected)  # a list is taken too
        parts = python["energy_parts"].func(spring, x.tolist())
        flat = np.array([*parts[0], parts[1], *parts[2]])
        assert np.array_equal(functions.energy_parts(spring, x), flat)  # nested results come flattened
        value = float(rng.uniform(0.0, 5.0))
        assert functions.root(value) == math.sqrt(value) and type(functions.root(value)) is float


def test_a_result_array_is_the_callers_own(compiled):
    component = compiled.FunctionOscillator()
    component.initialize(0.0)
    first = component.native_functions.rate(component._spring, [1.0, 0.0], compiled.Drive(0.0, 1.0), 1)
    component.native_functions.rate(component._spring, [2.0, 0.0], compiled.Drive(0.0, 1.0), 1)
    assert first[1] == -9.0


def test_a_raising_compiled_function_raises_the_python_error(compiled):
    component = compiled.FunctionOscillator()
    with pytest.raises(ValueError, match="root of a negative number -1.0"):
        component.native_functions.root(-1.0)


def test_native_off_in_the_environment_runs_python(compiled, monkeypatch):
    monkeypatch.setenv("DELTAFMI_NATIVE", "0")
    assert not compiled.FunctionOscillator().native_functions.compiled


def test_the_description_says_what_the_runtime_converts(model):
    description = generate_component(model.FunctionOscillator).description
    assert description["kernels"] == []
    assert description["functions"]["rate"] == {
        "args": [{"struct": {"object": ["omega", "zeta"]}}, {"floats": 2},
                 {"struct": {"record": [["force", "double"], ["scale", "double"]]}}, "int"],
        "result": {"floats": 2}}
    assert description["functions"]["energy_parts"]["result"] == {"floats": 5}
    assert description["functions"]["root"] == {"args": ["double"], "result": "double"}


def test_an_argument_type_without_a_c_layout_is_named(model):
    from deltafmi.component import Component, Function, NativeKernels

    class Bad(Component):
        native = NativeKernels(functions={"rate": Function(model.rate, model.Spring, list, model.Drive, int)})

    with pytest.raises(CodegenError, match=r"Bad.native: attribute \"functions\['rate'\] argument 1\""):
        generate_component(Bad)


def test_a_function_name_must_be_an_identifier(model):
    from deltafmi.component import Function, NativeKernels

    with pytest.raises(ValueError, match="'my rate' must be an ASCII identifier"):
        NativeKernels(functions={"my rate": Function(model.root, float)})
    with pytest.raises(ValueError, match="'compiled' is taken"):
        NativeKernels(functions={"compiled": Function(model.root, float)})


@pytest.fixture(scope="module")
def fmu(tmp_path_factory):
    return build_fmu(MODEL, tmp_path_factory.mktemp("functions") / "FunctionOscillator.fmu")


def test_the_fmu_carries_the_functions_in_its_kernel_library(fmu):
    with zipfile.ZipFile(fmu) as archive:
        description = json.loads(archive.read("resources/native_kernels.json"))
        source = archive.read("sources/FunctionOscillator_kernels.c").decode()
    assert set(description["functions"]) == {"rate", "energy_parts", "root"}
    assert "int dfmi_function_rate(" in source


@pytest.mark.parametrize("interface", ["ModelExchange", "CoSimulation"])
def test_in_the_fmu_the_compiled_functions_run_and_equal_python(fmu, interface, monkeypatch):
    results = {}
    for native in ("1", "0"):
        monkeypatch.setenv("DELTAFMI_NATIVE", native)
        results[native] = simulate_fmu(str(fmu), fmi_type=interface, stop_time=3.0, output_interval=0.01,
                                       relative_tolerance=1e-10, start_values={"u": 0.3},
                                       output=["x[1]", "energy", "amplitude", "compiled"])
    compiled, python = results["1"], results["0"]
    assert compiled["compiled"][-1] == 1 and python["compiled"][-1] == 0
    for name in ("x[1]", "energy", "amplitude"):
        assert np.array_equal(compiled[name], python[name]), name
    # the physics: x'' + 2 zeta omega x' + omega^2 x = u from x = 1 at rest
    omega, zeta, u = 3.0, 0.1, 0.3
    t = compiled["time"]
    wd = omega * math.sqrt(1.0 - zeta ** 2)
    x_ss = u / omega ** 2
    x = x_ss + (1.0 - x_ss) * np.exp(-zeta * omega * t) * (np.cos(wd * t) + zeta * omega / wd * np.sin(wd * t))
    assert np.max(np.abs(compiled["x[1]"] - x)) < 1e-6


def test_a_serialized_state_keeps_the_compiled_functions_the_component_holds(fmu):
    """The component keeps its functions in an attribute (as the estimators keep their kernels):
    its FMU state serializes (the compiled functions, calls into the kernel library, could not
    be pickled: fmi2SerializedFMUstateSize failed) and, deserialized, steps on with the instance's
    compiled functions, bit for bit as from the state itself, on the oscillator's closed form."""
    import fmpy
    from fmpy.fmi2 import FMU2Slave

    md = fmpy.read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    slave = FMU2Slave(guid=md.guid, unzipDirectory=fmpy.extract(str(fmu)), modelIdentifier="FunctionOscillator")
    slave.instantiate()
    slave.setupExperiment(startTime=0.0)
    slave.enterInitializationMode()
    slave.exitInitializationMode()
    h, n = 0.01, 100

    def run(t0):
        for k in range(n):
            slave.doStep(t0 + k * h, h)
        return slave.getReal([vr["x[1]"], vr["energy"]]), slave.getInteger([vr["compiled"]])[0]

    run(0.0)
    state = slave.getFMUstate()
    serialized = bytes(slave.serializeFMUstate(state))
    reference = run(n * h)
    slave.setFMUstate(slave.deSerializeFMUstate(serialized))
    assert run(n * h) == reference
    assert reference[1] == 1
    omega, zeta, t = 3.0, 0.1, 2 * n * h
    wd = omega * math.sqrt(1.0 - zeta ** 2)
    x = math.exp(-zeta * omega * t) * (math.cos(wd * t) + zeta * omega / wd * math.sin(wd * t))
    assert abs(reference[0][0] - x) < 1e-6
    slave.freeFMUstate(state)
    slave.terminate()
    slave.freeInstance()


def test_the_master_knows_that_an_fmu_with_functions_only_steps_in_python(fmu, tmp_path):
    """Its kernel library has no role the C layer calls: every step runs Python (it holds the GIL)."""
    from fmpy import extract

    from deltafmi.master.stepping.parallel import runs_python

    assert runs_python(extract(str(fmu), str(tmp_path / "unzipped")))


def test_info_lists_the_compiled_functions(fmu):
    from click.testing import CliRunner

    from deltafmi.apps.cli import main

    result = CliRunner().invoke(main, ["info", str(fmu)])
    assert result.exit_code == 0, result.output
    assert "compiled functions (C its Python calls): rate, energy_parts, root" in result.output
    assert "compiled kernels" not in result.output


def test_functions_beside_kernel_roles_share_the_library(model):
    """A component with a derivatives kernel and a function: one library has both, each works."""
    from deltafmi.component import Component, Function, Kernel, NativeKernels, State

    def decay(x):
        return [-x[0]]

    class Both(Component):
        x = State([1.0])
        native = NativeKernels(derivatives=Kernel(decay, "states"),
                               functions={"root": Function(model.root, float)})

        def derivatives(self, t):
            return decay(self.x)

    description = generate_component(Both).description
    assert description["kernels"] == ["derivatives"] and list(description["functions"]) == ["root"]
    try:
        assert use_compiled_functions(Both)
        functions = Both().native_functions
        assert functions.compiled and functions.root(2.25) == 1.5
    finally:
        register_library(Both, None)
