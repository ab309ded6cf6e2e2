"""Issue 26 items 1-2: C generated from the delta robot's Python kernels (deltafmi/builder/codegen)
computes what the Python computes, bit for bit.

The generator translates every Python float operation into the same C double operation in the
same order, and the unit is compiled with -ffp-contract=off -fno-builtin-pow, so the tolerance is
zero: the plant derivative and outputs, the controller's law (Newton and closed-form forward
kinematics, constraint Jacobian, gravity and inverse dynamics, PID with feed-forward and
anti-windup, impedance mode, saturation, the singular paths), the zero-order-hold lead and warm
start, and the minimum-jerk path are compared with the Python functions they come from, on random
inputs and on the flagship's; the generated closed loop (a hand-written C driver of the generated
kernels) is compared with the flagship itself (deltafmi.simulate) over its first 0.5 s.
"""
from __future__ import annotations

import importlib.util
import math
import struct
import sys
from pathlib import Path

import numpy as np
import pytest

import deltafmi
from deltafmi.toolchain import NoCompilerError
from deltafmi.physics.delta import control, control_law, dynamics, kinematics
from deltafmi.physics.delta.params import DeltaParams

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))

from deltafmi.builder.codegen import CodegenError, Entry, generate  # noqa: E402
from deltafmi.builder.codegen.build import compile_unit  # noqa: E402
from deltafmi.builder.codegen.translate import D, I  # noqa: E402
from kernel_codegen.flagship import IDENTITIES, GeneratedFlagship, entries  # noqa: E402


@pytest.fixture(scope="module")
def native():
    """benchmarks/native.py: the flagship's data and the hand C transcription."""
    return importlib.import_module("native")


@pytest.fixture(scope="module")
def system(native):
    return native.load_flagship()


@pytest.fixture(scope="module")
def generated(native, system, tmp_path_factory):
    try:
        return GeneratedFlagship(native.flagship_models(system), tmp_path_factory.mktemp("codegen"))
    except NoCompilerError as exc:
        pytest.skip(f"no C compiler for the generated kernels: {exc}")


def bits(value) -> list[int]:
    """Every number of a (nested) result as its IEEE-754 bits (ints and bools as themselves)."""
    if isinstance(value, (tuple, list, np.ndarray)):
        return [b for v in value for b in bits(v)]
    if isinstance(value, float):
        return [struct.unpack("<q", struct.pack("<d", value))[0]]
    return [int(value)]


def call(generated, name, *args):
    return generated.library.call(name, *args)


def test_plant_derivative_and_outputs_bit_for_bit(native, system, generated):
    models = native.flagship_models(system)
    p, f, pole = models.plant, models.f, models.pole
    rng = np.random.default_rng(26)
    for _ in range(40):
        z0 = [rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-1.15, -0.8)]
        x = np.concatenate([_assembled(p, z0) + rng.normal(0.0, 1e-3, 9), rng.normal(0.0, 2.0, 9)]).tolist()
        u = rng.normal(0.0, 50.0, 3).tolist()
        assert bits(call(generated, "dfk_state_derivative", p, x, u, f, pole)) == \
            bits(dynamics.state_derivative(p, x, u, f, pole))
        assert bits(call(generated, "dfk_evaluate_plant", p, x[:9], x[9:], u, f, pole)) == \
            bits(tuple(dynamics.evaluate_plant(p, x[:9], x[9:], u, f, pole)))


def _assembled(p, z):
    return np.asarray(kinematics.inverse_kinematics(p, z), dtype=float)


def _laws(p):
    return {
        "flagship-like": control_law.make_law(p),
        "impedance": control_law.make_law(p, impedance=True, stiffness=(400.0, 300.0, 900.0),
                                          task_damping=(20.0, 30.0, 40.0)),
        "no coriolis, closed form": control_law.make_law(p, coriolis=False, fk="closed", feedforward=False),
        "saturating, ill-conditioned": control_law.make_law(p, torque_limit=2.0, cond_limit=1.5,
                                                            integral_limit=1e-4),
    }


@pytest.mark.parametrize("law_name", ["flagship-like", "impedance", "no coriolis, closed form",
                                      "saturating, ill-conditioned"])
def test_controller_law_bit_for_bit_on_random_inputs(native, system, generated, law_name):
    p = native.flagship_models(system).controller.params
    law = _laws(p)[law_name]
    rng = np.random.default_rng(sum(map(ord, law_name)))
    seen = set()
    for trial in range(60):
        z = [rng.uniform(-0.3, 0.3), rng.uniform(-0.3, 0.3), rng.uniform(-1.15, -0.8)]
        y, x = (a.tolist() for a in control.inverse_kinematics_servo(p, z))
        yd = rng.normal(0.0, 1.0, 3).tolist()
        r = (np.array(z) + rng.normal(0.0, 0.01, 3)).tolist()
        rd, rdd, force = (rng.normal(0.0, 1.0, 3).tolist() for _ in range(3))
        integral = rng.normal(0.0, 1e-3, 3).tolist()
        guess = [None, (np.array(x) + rng.normal(0.0, 1e-4, 6)).tolist(), (np.array(x) + 2.0).tolist()][trial % 3]
        if trial == 5:
            y = [math.nan, 0.0, 0.0]  # no forward kinematics: the singular result
        want = control_law.evaluate(law, y, yd, r, rd, rdd, integral, 1e-3, guess, force)
        got = call(generated, "dfk_evaluate", law, y, yd, r, rd, rdd, integral, 1e-3, guess, force)
        assert bits(got) == bits(tuple(want)), f"trial {trial}"
        seen.add((want.status, want.iterations >= 0))
    assert len(seen) >= 2  # the inputs reach more than one path through the law


def test_hold_and_warm_start_bit_for_bit(generated):
    rng = np.random.default_rng(7)
    for _ in range(50):
        u, prev = rng.normal(0.0, 200.0, 3).tolist(), rng.normal(0.0, 200.0, 3).tolist()
        for previous in (None, prev):
            assert call(generated, "dfk_hold", u, previous, 250.0) == control_law.hold(u, previous, 250.0)
        x, xd, xd0 = (rng.normal(0.0, 1.0, 6).tolist() for _ in range(3))
        for previous in (None, xd0):
            assert bits(call(generated, "dfk_warm_start", x, xd, previous, 1e-3)) == \
                bits(control_law.warm_start(x, xd, previous, 1e-3))


def test_flagship_inputs_bit_for_bit(native, system, generated, tmp_path):
    """On the flagship's first 0.5 s (its states and samples, from the hand C transcription that
    tests/builder/test_native_baseline.py holds to the flagship): the plant derivative, and the
    controller (the generated sample, its state between samples included) against the Python
    DeltaController stepped through the same samples."""
    baseline = native.Baseline(native.compile_baseline(tmp_path))
    spec = native.flagship_spec(system)
    models = native.flagship_models(system)
    rows, states, _ = baseline.run(spec, 501)
    for k in range(0, 501, 25):
        x, u = states[k].tolist(), rows[k + 1, 10:13].tolist()
        assert bits(call(generated, "dfk_state_derivative", models.plant, x, u, models.f, models.pole)) == \
            bits(dynamics.state_derivative(models.plant, x, u, models.f, models.pole)), f"step {k}"
    inputs = native.controller_inputs(baseline, spec, rows, states)
    want, _ = native.python_controller(models.controller, inputs)
    got, _ = generated.replay_controller(inputs)
    assert bits(got.ravel().tolist()) == bits(want.ravel().tolist())
    assert np.ptp(got[:, 0]) > 1.0


def test_path_bit_for_bit(generated):
    path = generated.path
    times = np.concatenate([np.linspace(path.t0 - 0.2, path.t0 + path.duration + 0.3, 1500),
                            path._starts, np.random.default_rng(3).uniform(0.0, path.duration, 200)])
    for t in times.tolist():
        assert bits(call(generated, "dfk_path", path, t)) == bits(path.evaluate_flat(t)), f"t = {t}"


def test_generated_closed_loop_equals_the_flagship(native, system, generated):
    """The first 0.5 s of the flagship (its FMUs stepped by the master) against the generated loop."""
    result = deltafmi.simulate("delta_tracking", stop=0.5)
    spec = native.flagship_spec(system)
    steps = len(result.time) - 1
    assert steps == 500
    rows = generated.run(spec.start, spec.h, steps)
    np.testing.assert_array_equal(rows[:, 0], result.time)
    for j, name in enumerate(native.COLUMNS[1:], start=1):
        assert bits(rows[:, j].tolist()) == bits(np.asarray(result[name], dtype=float).tolist()), name
    assert np.ptp(rows[:, 1]) > 0.01 and np.ptp(rows[:, 10]) > 1.0  # it moves


@pytest.mark.parametrize("body, line, message", [
    ("    s = 0.0\n    try:\n        s = 1.0 / x\n    except ZeroDivisionError:\n        pass\n    return s\n", 6,
     "statement 'Try' is not supported"),
    ("    s = 0.0\n    for t in (x, x):\n        if t > 1.0:\n            break\n        s += t\n    return s\n", 8,
     "'break' only in a while loop or a range() loop with bounds known at run time"),
    ("    if x > 0.0:\n        y = 1.0\n    else:\n        y = (1.0, 2.0)\n    return y\n", 9,
     "'y' has different types on the branches that reach here"),
    ("    return tuple(t * t for t in (x, x))[0]\n", 5, "(GeneratorExp) is not supported"),
])
def test_unsupported_construct_is_a_one_line_error_naming_the_line(tmp_path, body, line, message):
    source = tmp_path / "user_kernel.py"
    source.write_text("import math\n\n\ndef kernel(x: float) -> float:\n" + body)
    spec = importlib.util.spec_from_file_location("user_kernel", source)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with pytest.raises(CodegenError) as info:
        generate([Entry("k", module.kernel, [D])])
    text = str(info.value)
    assert "\n" not in text
    assert text.startswith(f"{source}:{line}: in kernel: ") and message in text


USER_KERNELS = """\
import math


def newton_sqrt(a: float, tol: float) -> float:
    x = a if a > 1.0 else 1.0
    it = 0
    while abs(x * x - a) > tol * a:
        x = 0.5 * (x + a / x)
        it += 1
        if it >= 50:
            break
    return x


def partial_sum(x: float, n: int) -> float:
    s = 0.0
    for k in range(n):
        if k * x > 3.0:
            continue
        s += math.sin(k * x)
    return s


def cancelling_sum(a: float, b: float) -> float:
    return sum(t for t in (a, b, -a, 1e-3 * b, -b))
"""


def user_kernels(folder: Path, name: str, text: str, **entries: list):
    """(module, compiled library) of a user's kernels module ``text``: each entry's argument types."""
    source = folder / f"{name}.py"
    source.write_text(text)
    spec = importlib.util.spec_from_file_location(name, source)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    try:
        return module, compile_unit([Entry(f, getattr(module, f), args) for f, args in entries.items()], folder)
    except NoCompilerError as exc:
        pytest.skip(f"no C compiler: {exc}")


def test_user_kernel_with_loops_known_at_run_time(tmp_path):
    """A user's kernel: a while loop with break, a range() loop with continue (C loops), sum()."""
    module, lib = user_kernels(tmp_path, "user_loops", USER_KERNELS, newton_sqrt=[D, D], partial_sum=[D, I],
                               cancelling_sum=[D, D])
    rng = np.random.default_rng(11)
    for a in rng.uniform(0.0, 1e4, 50).tolist() + [2.0, 0.25]:
        assert bits(lib.call("newton_sqrt", a, 1e-15)) == bits(module.newton_sqrt(a, 1e-15))
        assert abs(lib.call("newton_sqrt", a, 1e-12) - math.sqrt(a)) <= 1e-6 * math.sqrt(a)
    for x, n in zip(rng.uniform(0.0, 1.0, 30).tolist(), range(30)):
        assert bits(lib.call("partial_sum", x, n)) == bits(module.partial_sum(x, n))
    # sum() is Python's: left to right before 3.12, compensated from 3.12 on
    for a, b in [(1e16, 1.0), (-0.0, -0.0), (1e308, 1e308), (3.5, -2.25)] + rng.normal(0.0, 1e8, (20, 2)).tolist():
        assert bits(lib.call("cancelling_sum", a, b)) == bits(module.cancelling_sum(a, b)), (a, b)


def test_the_entries_cover_the_flagship(generated):
    """What the generated loop runs comes from these Python functions (no hand C kernels)."""
    names = {e.func.__qualname__ for e in entries(generated.path)}
    assert names == {"state_derivative", "evaluate_plant", "sample", "evaluate", "hold", "warm_start",
                     "MinimumJerkPath.evaluate_flat"}
    assert IDENTITIES == {"_as_list", "_f3"}
    assert DeltaParams in {t.cls for e in entries(generated.path) for t in e.args if hasattr(t, "cls")}


RAISING_KERNELS = """\
import math


def ratio(a: float, b: float) -> float:
    return a / b


def root(x: float) -> float:
    return math.sqrt(x) + math.log(x)


def grow(x: float, y: float) -> float:
    return math.exp(x) + x ** y


def branch(x: float) -> float:
    return 1.0 / x if x != 0.0 else math.sin(x)


def turn(x: float, y: float) -> float:
    return math.sin(x) * y + math.cos(x)
"""


def test_where_python_raises_the_kernel_returns_the_line(tmp_path):
    """Division by zero, math outside its domain or overflowing: Python raises where C would give
    inf or nan; the generated C records the line as a raise's (the FMU then runs the Python,
    which raises with its message), and computes the same bits everywhere else."""
    module, lib = user_kernels(tmp_path, "user_raising", RAISING_KERNELS, ratio=[D, D], root=[D], grow=[D, D],
                               branch=[D], turn=[D, D])
    cases = [("ratio", (1.0, 0.0), 5), ("ratio", (0.0, 0.0), 5), ("root", (-1.0,), 9), ("root", (0.0,), 9),
             ("grow", (710.0, 1.0), 13), ("grow", (-2.0, 0.5), 13), ("grow", (0.0, -1.0), 13),
             ("grow", (10.0, 400.0), 13), ("turn", (math.inf, 1.0), 21), ("turn", (-math.inf, 0.0), 21)]
    for name, args, line in cases:
        with pytest.raises(ArithmeticError, match=f"at line {line}$"):
            lib.call(name, *args)
        with pytest.raises((ArithmeticError, ValueError, TypeError)):
            value = getattr(module, name)(*args)
            if isinstance(value, complex):  # (-2.0) ** 0.5: Python's value is complex, no float
                raise TypeError(value)
    for name, args in [("ratio", (1.0, 3.0)), ("ratio", (1.0, math.inf)), ("root", (math.inf,)), ("root", (2.0,)),
                       ("grow", (1.0, 2.5)), ("grow", (math.inf, 1.0)), ("branch", (0.0,)), ("branch", (4.0,)),
                       ("turn", (math.nan, 1.0)), ("turn", (1e300, 2.0)), ("turn", (-0.0, 1.0)), ("turn", (0.7, math.inf))]:
        assert bits(lib.call(name, *args)) == bits(getattr(module, name)(*args)), (name, args)


def test_a_large_kernel_called_from_several_places_is_left_to_the_compiler():
    """Forced inlining copies a kernel into every caller: one of thousands of lines called twice is
    KERNEL_SHARED (the compiler decides); a small one, or a large one called once, stays KERNEL."""
    from deltafmi.builder.codegen.translate import _INLINE_LINES, _share_large_kernels

    def kernel(name, lines, calls=()):
        body = "".join(f"    x = {callee}(err, x);\n" for callee in calls) + "    x += 1.0;\n" * lines
        return f"KERNEL double {name}(int *err, double x)", f"/* {name} */\nKERNEL double {name}(int *err, double x)\n{{\n{body}    return x;\n}}\n"

    big = _INLINE_LINES + 10
    pieces = [kernel("k_small_1", 5), kernel("k_big_2", big, ["k_small_1"]), kernel("k_once_3", big),
              kernel("k_user_4", 3, ["k_big_2", "k_big_2", "k_once_3"])]
    wrappers = ["int entry(double *x) { int err = 0; *x = k_user_4(&err, *x); return err; }"]
    prototypes, defs = _share_large_kernels([p + ";" for p, _ in pieces], [d for _, d in pieces], wrappers)
    shared = [p.split("(")[0].split()[-1] for p in prototypes if p.startswith("KERNEL_SHARED ")]
    assert shared == ["k_big_2"]
    assert sum(d.count("KERNEL_SHARED ") for d in defs) == 1
