"""An FMI 3.0 FMU's messages name the FMI 3.0 function the importer called (fmi3UpdateDiscreteStates,
fmi3GetAdjointDerivative, fmi3InstantiateCoSimulation, ...), its token the instantiationToken, and
its rebuild advice the `--fmi-version 3` option; the FMI 2.0 build of the same component keeps its
FMI 2.0 words. Real FMUs in fmpy."""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest
from click.testing import CliRunner
from fmpy import extract, read_model_description
from fmpy.fmi2 import (FMU2Model, calloc, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                       fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, free)
from fmpy.fmi3 import FMU3Model, FMU3Slave

from deltafmi.apps.cli import main
from deltafmi.builder import build_fmu

# update() raises when u > 1, derivatives() when u < -1: each failure is reached by one FMI call
GRUMPY = textwrap.dedent('''
    from deltafmi.component import Component, Experiment, Input, Output, State


    class Grumpy(Component):
        """x' = -x + u; refuses events when u > 1 and derivatives when u < -1."""

        default_experiment = Experiment(stop=1.0, step=0.1)
        x = State(1.0)
        u = Input(0.0)
        y = Output()
        direct_feedthrough = {}

        def derivatives(self, t):
            if self.u < -1.0:
                raise ValueError("no derivatives below u = -1")
            return [-self.x + self.u]

        def outputs(self, t):
            self.y = self.x

        def update(self, t):
            if self.u > 1.0:
                raise ValueError("no events above u = 1")
            return False
''')


class Built:
    """An FMU built, unzipped, with its value references by name."""

    def __init__(self, fmu: Path, directory: Path) -> None:
        self.fmu = fmu
        self.md = read_model_description(str(fmu))
        self.dir = extract(str(fmu), str(directory))
        self.vr = {v.name: v.valueReference for v in self.md.modelVariables}
        self.identifier = (self.md.coSimulation or self.md.modelExchange).modelIdentifier

    def open(self, cls, messages: list, guid: str | None = None):
        """An instance whose messages go to `messages`."""
        fmu = cls(guid=guid or self.md.guid, unzipDirectory=self.dir, modelIdentifier=self.identifier,
                  instanceName="grumpy")
        if self.md.fmiVersion == "3.0":
            fmu.instantiate(logMessage=lambda env, status, category, message: messages.append(message.decode()))
        else:
            callbacks = fmi2CallbackFunctions()
            callbacks.logger = fmi2CallbackLoggerTYPE(
                lambda env, name, status, category, message: messages.append(message.decode()))
            callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
            callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
            fmu.instantiate(callbacks=callbacks)
        return fmu


@pytest.fixture(scope="module")
def grumpy(tmp_path_factory) -> dict[int, Built]:
    out = tmp_path_factory.mktemp("grumpy")
    source = out / "grumpy.py"
    source.write_text(GRUMPY)
    return {version: Built(build_fmu(source, out / f"Grumpy{version}.fmu", fmi_version=version), out / f"x{version}")
            for version in (2, 3)}


def _in_continuous_time(fmu, three: bool, u_vr: int, u: float) -> None:
    """Model Exchange through initialization and the first event into continuous time, u set."""
    if not three:
        fmu.setupExperiment(startTime=0.0)
    fmu.enterInitializationMode()
    fmu.exitInitializationMode()
    fmu.updateDiscreteStates() if three else fmu.newDiscreteStates()
    fmu.enterContinuousTimeMode()
    (fmu.setFloat64 if three else fmu.setReal)([u_vr], [u])


def _failure(call, messages: list) -> list[str]:
    """The messages of one FMI call that fails (fmpy raises on its error status)."""
    del messages[:]
    with pytest.raises(Exception):
        call()
    assert messages, "the failed call said nothing"
    return list(messages)


@pytest.mark.parametrize("version, expected", [(3, "fmi3UpdateDiscreteStates: "), (2, "fmi2NewDiscreteStates: ")])
def test_a_failed_discrete_update_names_the_function_of_its_standard(grumpy, version, expected):
    built, messages = grumpy[version], []
    fmu = built.open(FMU3Model if version == 3 else FMU2Model, messages)
    _in_continuous_time(fmu, version == 3, built.vr["u"], 2.0)
    fmu.enterEventMode()
    errors = _failure(fmu.updateDiscreteStates if version == 3 else fmu.newDiscreteStates, messages)
    assert errors[0].startswith(expected + "Python exception") and "no events above u = 1" in errors[0], errors
    assert not any(f"fmi{5 - version}" in m for m in errors), errors


def test_a_failed_adjoint_derivative_names_fmi3GetAdjointDerivative(grumpy):
    built, messages = grumpy[3], []
    fmu = built.open(FMU3Model, messages)
    _in_continuous_time(fmu, True, built.vr["u"], -2.0)
    der = built.vr["der(x)"]
    errors = _failure(lambda: fmu.getAdjointDerivative([der], [built.vr["x"]], [1.0]), messages)
    assert errors[0].startswith("fmi3GetAdjointDerivative: ") and "no derivatives below u = -1" in errors[0], errors
    assert not any("fmi2" in m for m in errors), errors


def test_a_wrong_instantiation_token_is_named_so_by_fmi3InstantiateCoSimulation(grumpy):
    built, messages = grumpy[3], []
    wrong = "{00000000-0000-0000-0000-000000000000}"
    with pytest.raises(Exception):
        built.open(FMU3Slave, messages, guid=wrong)
    assert messages[0].startswith("fmi3InstantiateCoSimulation: "), messages
    assert (f"fmi3InstantiateCoSimulation: instantiationToken {wrong} does not match this FMU's {built.md.guid}"
            in messages[0]), messages
    assert not any("fmi2" in m or "GUID" in m for m in messages), messages


def test_the_rebuild_advice_of_an_fmi3_fmu_keeps_its_version(grumpy):
    for version, option in ((3, " --fmi-version 3"), (2, "")):
        result = CliRunner().invoke(main, ["info", str(grumpy[version].fmu)])
        assert result.exit_code == 0, result.output
        assert f"`deltafmi build grumpy.py{option} --portable`" in result.output, result.output


def test_a_missing_module_advice_of_an_fmi3_fmu_keeps_its_version(grumpy):
    from deltafmi.runtime.boot import _missing_module

    for version, option in ((3, " --fmi-version 3"), (2, "")):
        resources = str(Path(grumpy[version].dir) / "resources")
        advice = str(_missing_module(ImportError("No module named 'nowhere'", name="nowhere"), resources))
        assert f"`deltafmi build grumpy.py{option} --portable`" in advice, advice
