"""The Component's value access: descriptors and read_reals read and write the FMI buffers."""
import numpy as np
import pytest

from deltafmi.component import Component, Input, Output, Parameter, State


class Sample(Component):
    """A component with reals in several blocks of the buffer and an integer between them."""

    k = Parameter(2.0, description="Gain")
    x = State([1.0, 2.0], description="States")
    a = Input([3.0, 4.0, 5.0], description="Vector input")
    n = Input(7, type=int, description="Integer input")
    b = Input(6.0, description="Scalar input")
    y = Output(shape=2, description="Vector output")
    flag = Output(True, description="Boolean output")


def test_read_reals_equals_the_attributes_concatenated():
    c = Sample()
    c.y = (8.0, 9.0)
    expected = np.concatenate([c.a, [c.b], c.x, c.y, [c.k]]).tolist()
    assert c.read_reals("a", "b", "x", "y", "k") == expected
    assert c.read_reals("a") == [3.0, 4.0, 5.0]
    assert all(type(v) is float for v in c.read_reals("x", "b"))


def test_read_reals_refuses_what_is_not_a_real():
    c = Sample()
    with pytest.raises(ValueError, match="'n' is not a Real variable of Sample"):
        c.read_reals("a", "n")
    with pytest.raises(ValueError, match="'nothing' is not a Real variable"):
        c.read_reals("nothing")


def test_array_assignments_keep_numpy_semantics():
    c = Sample()
    c.a = [1, 2, 3]                       # ints into a Real array
    assert c.a.tolist() == [1.0, 2.0, 3.0]
    c.a = np.float32(0.5)                 # a scalar broadcasts, as numpy does
    assert c.a.tolist() == [0.5, 0.5, 0.5]
    c.y = (np.float64(1.25), 2.5)         # tuples and numpy scalars
    assert c.y.tolist() == [1.25, 2.5]
    with pytest.raises(ValueError):      # a wrong length is still numpy's error
        c.a = [1.0, 2.0]
    c.b = 3                               # an int into a Real scalar
    assert c.b == 3.0 and type(c.b) is float
    c.flag = False
    assert c.flag is False
    c.n = 4
    assert c.n == 4


def test_write_reals_is_the_inverse_of_read_reals():
    c = Sample()
    values = [0.5, 1.5, 2.5, 3.5, 4.5, 5.5]
    c.write_reals(values, "a", "b", "y")       # contiguous: a, b... and y after the integer
    assert c.read_reals("a", "b", "y") == values
    assert c.a.tolist() == values[:3] and c.b == values[3] and c.y.tolist() == values[4:]
    c.write_reals((7, np.float64(8.0)), "x")  # ints and numpy scalars, as for the attributes
    assert c.x.tolist() == [7.0, 8.0]
    with pytest.raises(ValueError, match="3 values for the 2 scalars of x"):
        c.write_reals([1.0, 2.0, 3.0], "x")
    with pytest.raises(ValueError, match="'flag' is not a Real variable"):
        c.write_reals([1.0], "flag")


def test_compiled_and_python_accessors_agree(tmp_path):
    """The compiled value access every FMU carries (runtime/_values.c) against the pure-Python
    accessors, case by case: same values, same types, same errors."""
    import json
    import shutil
    import subprocess
    import sys
    from pathlib import Path

    import deltafmi
    from deltafmi.runtime import native_values
    from deltafmi.toolchain import python_extension
    from deltafmi.builder.packager import VALUE_ACCESS_SOURCE

    import value_access_cases

    assert not native_values.COMPILED  # a source checkout: the Python accessors
    package = tmp_path / "deltafmi"
    shutil.copytree(Path(deltafmi.__file__).parent, package, ignore=shutil.ignore_patterns("__pycache__"))
    extension = python_extension(VALUE_ACCESS_SOURCE)
    shutil.copy(extension, package / "runtime" / extension.name)
    tests = Path(__file__).parents[1]
    out = subprocess.run([sys.executable, str(tests / "value_access_cases.py")], capture_output=True, text=True,
                         check=True, env={"PYTHONPATH": str(tmp_path), "PATH": "/usr/bin:/bin"}).stdout
    compiled = json.loads(out)
    assert compiled["compiled"]
    python = json.loads(json.dumps(value_access_cases.run()))
    assert len(python) == len(compiled["results"]) > 40
    for ours, theirs in zip(python, compiled["results"]):
        assert ours == theirs
