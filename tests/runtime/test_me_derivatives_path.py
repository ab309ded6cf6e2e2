"""Model Exchange derivatives and event indicators through a real FMU in fmpy: whatever the
component returns (list, tuple, numpy array, integers), the importer reads the same numbers,
and a wrong result or an exception is an fmi2Error with the reason in the log.

The FMU's C layer copies lists and tuples itself and hands anything else to Python; this checks
both ways against the closed form of the model, y' = a y + b, z = y - c."""
import ctypes
import re
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Model

from deltafmi.builder import build_fmu

SOURCE = '''
import numpy as np
from deltafmi.component import Component, Parameter, State

class Affine(Component):
    """y' = a y + b (two copies), event indicators y - c."""
    n_event_indicators = 2
    a = Parameter(-2.0)
    b = Parameter(3.0)
    c = Parameter(0.5)
    kind = Parameter(0, type=int)
    y = State([1.0, 4.0])

    def derivatives(self, t):
        y0, y1 = self.y.tolist()
        values = [self.a * y0 + self.b, self.a * y1 + self.b]
        kind = self.kind
        if kind == 1:
            return tuple(values)
        if kind == 2:
            return np.array(values)
        if kind == 3:
            return [int(v) for v in values]
        if kind == 4 and t > 0.1:  # after initialization, in continuous-time mode
            return values[:1]
        if kind == 5 and t > 0.1:
            raise RuntimeError("no derivatives today")
        return values

    def event_indicators(self, t):
        z = [v - self.c for v in self.y.tolist()]
        return np.array(z) if self.kind == 2 else z
'''

@pytest.fixture(scope="module")
def fmu(tmp_path_factory) -> Path:
    directory = tmp_path_factory.mktemp("affine")
    (directory / "affine.py").write_text(SOURCE)
    return build_fmu(directory / "affine.py", directory / "Affine.fmu")


def model_in_continuous_time(fmu: Path, kind: int) -> tuple[FMU2Model, dict]:
    md = read_model_description(str(fmu))
    vr = {v.name: v.valueReference for v in md.modelVariables}
    model = FMU2Model(guid=md.guid, unzipDirectory=extract(str(fmu)),
                      modelIdentifier=md.modelExchange.modelIdentifier, instanceName="affine")
    model.instantiate(loggingOn=True)  # fmpy's default logger prints the FMU's messages
    model.setupExperiment(startTime=0.0)
    model.setInteger([vr["kind"]], [kind])
    model.enterInitializationMode()
    model.exitInitializationMode()
    model.newDiscreteStates()
    model.enterContinuousTimeMode()
    return model, vr


def derivatives_and_indicators(model: FMU2Model, x: list[float]) -> tuple[np.ndarray, np.ndarray]:
    states, dx, z = np.array(x), np.zeros(2), np.zeros(2)
    pointer = lambda a: a.ctypes.data_as(ctypes.POINTER(ctypes.c_double))  # noqa: E731
    model.setTime(0.25)
    model.setContinuousStates(pointer(states), 2)
    model.getDerivatives(pointer(dx), 2)
    model.getEventIndicators(pointer(z), 2)
    return dx, z


@pytest.mark.parametrize("kind", [0, 1, 2])
def test_every_sequence_type_gives_the_same_numbers(fmu: Path, kind: int):
    model, _ = model_in_continuous_time(fmu, kind)
    for x in ([1.0, 4.0], [0.3, -7.5], [2.0, 2.0]):
        dx, z = derivatives_and_indicators(model, x)
        assert dx.tolist() == [-2.0 * x[0] + 3.0, -2.0 * x[1] + 3.0]
        assert z.tolist() == [x[0] - 0.5, x[1] - 0.5]
    model.terminate()
    model.freeInstance()


def test_integers_are_converted(fmu: Path):
    model, _ = model_in_continuous_time(fmu, 3)
    dx, _ = derivatives_and_indicators(model, [1.0, 4.0])
    assert dx.tolist() == [1.0, -5.0]
    model.terminate()
    model.freeInstance()


@pytest.mark.parametrize("kind, reason", [(4, r"derivatives\(\) returned 1 values for 2 states"),
                                          (5, "no derivatives today")])
def test_a_wrong_result_or_an_exception_is_an_error(fmu: Path, kind: int, reason: str, capfd):
    model, _ = model_in_continuous_time(fmu, kind)
    dx = np.zeros(2)
    model.setTime(0.25)
    with pytest.raises(Exception, match="fmi2GetDerivatives failed"):
        model.getDerivatives(dx.ctypes.data_as(ctypes.POINTER(ctypes.c_double)), 2)
    model.freeInstance()
    assert re.search(reason, capfd.readouterr().out)
