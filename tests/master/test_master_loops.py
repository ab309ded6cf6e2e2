"""Algebraic loops solved by the master, at initialization and at every communication step.

FMUs: ``Gain`` (tests/components/gain: y = (a + a_rate t) u + b + w, direct feedthrough from u
and w) and ``Lag`` (tests/components/lag: T x' = u - x, y = x + d u). Closed forms:

* two gains in a loop, y1 = a u1 + b + w, u2 = y1, y2 = c u2, u1 = y2: y1 = (b + w) / (1 - a c);
  no solution when a c = 1 (and b + w != 0);
* a lag in a loop with a gain k, u = k y: u = k x / (1 - k d), so x' = lambda x with
  lambda = (k / (1 - k d) - 1) / T. Solved at every step with the input held over the step (the
  master redoes the step until the held input agrees with the outputs at its end), the lag
  follows the implicit recurrence tau = k E x_n / (1 - k (1 - E) - k d), x_n+1 = tau + (x_n - tau) E,
  E = exp(-h / T), exactly; it converges to exp(lambda t) to first order in h.
"""
from __future__ import annotations

import ast
import shutil
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

import deltafmi.master.stepping
from deltafmi.apps.cli import main
from deltafmi.master.results.csv_file import columns
from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping.master import Master
from deltafmi.builder import build_fmu

COMPONENTS = Path(__file__).parents[1] / "components"


@pytest.fixture(scope="module")
def fmus(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("loops")
    build_fmu(COMPONENTS / "gain" / "model.py", folder / "Gain.fmu")
    build_fmu(COMPONENTS / "lag" / "model.py", folder / "Lag.fmu")
    return folder


def write(folder: Path, name: str, text: str) -> Path:
    path = folder / f"{name}.yaml"
    path.write_text(textwrap.dedent(text))
    return path


def simulate(path: Path, **options):
    summary = Master(resolve_system(load_scenario(path)), result=path.with_suffix(".csv"), **options).run()
    return summary, columns(path.with_suffix(".csv"))


# --------------------------------------------------------------------- two gains: closed form
A0, A_RATE, C, B, T_SOURCE = 2.0, 0.5, 0.8, 1.0, 0.5  # a c runs from 1.6 to 2.0: fixed-point iterations diverge


@pytest.mark.parametrize("interface", ["CS", "ME"])
@pytest.mark.parametrize("algorithm", ["gauss-seidel", "jacobi"])
def test_two_gains_follow_the_closed_form(fmus, tmp_path, algorithm, interface):
    """A source feeds the loop, an observer reads it: y1 = (b + w) / (1 - a(t) c) at every row,
    the first one solved at initialization. Gauss-Seidel steps the loop after the source and
    before the observer (both see the same instant); Jacobi hands every value over one step late."""
    path = write(fmus, f"gains_{algorithm}_{interface}", f"""\
        experiment: {{stop: 1.0, step: 0.1}}
        master: {{algorithm: {algorithm}}}
        components:
          obs: {{fmu: Gain.fmu}}
          g2: {{fmu: Gain.fmu, interface: {interface}, parameters: {{a: {C}}}}}
          g1: {{fmu: Gain.fmu, interface: {interface}, parameters: {{a: {A0}, a_rate: {A_RATE}, b: {B}}}}}
          src: {{fmu: Lag.fmu, parameters: {{T: {T_SOURCE}, d: 0.0}}}}
        connections:
          - {{from: g1.y, to: g2.u}}
          - {{from: g2.y, to: g1.u}}
          - {{from: src.y, to: g1.w}}
          - {{from: g1.y, to: obs.u}}
        outputs: [g1.y, g2.y, src.y, obs.y]
        """)
    system = resolve_system(load_scenario(path))
    if algorithm == "gauss-seidel":  # the loop in its evaluation order: tearing g1.y keeps the scenario's
        assert system.order == ["src", "g2", "g1", "obs"]
    summary, c = simulate(path)
    t = c["time"]
    w = np.exp(-t / T_SOURCE)  # the source's output
    seen = w if algorithm == "gauss-seidel" else np.r_[w[0], w[:-1]]
    y1 = (B + seen) / (1.0 - (A0 + A_RATE * t) * C)
    assert np.max(np.abs(c["g1.y"] - y1)) < 1e-8
    assert np.max(np.abs(c["g2.y"] - C * c["g1.y"])) < 1e-8
    observed = y1 if algorithm == "gauss-seidel" else np.r_[y1[0], y1[:-1]]
    assert np.max(np.abs(c["obs.y"] - observed)) < 1e-8
    # fixed-point iterations diverge here (a c > 1): Newton, with the last Jacobian reused
    loops = summary.loops
    assert loops.solves == 11 and loops.evaluations <= 3 * loops.solves


def test_a_component_fed_back_onto_itself(fmus):
    """y = a u + b with u = y: y = b / (1 - a) (a = 3: fixed-point iterations diverge)."""
    path = write(fmus, "self_loop", """\
        experiment: {stop: 0.3, step: 0.1}
        components:
          g: {fmu: Gain.fmu, parameters: {a: 3.0, b: 2.0}}
        connections:
          - {from: g.y, to: g.u}
        """)
    _, c = simulate(path)
    np.testing.assert_allclose(c["g.y"], -1.0, rtol=1e-9)


# ---------------------------------------------------------------------------- no solution
SINGULAR = """\
    experiment: {{stop: 1.0, step: 0.1}}
    components:
      g1: {{fmu: Gain.fmu, parameters: {{a: {a}, a_rate: {rate}, b: 1.0}}}}
      g2: {{fmu: Gain.fmu, parameters: {{a: {c}}}}}
    connections:
      - {{from: g1.y, to: g2.u}}
      - {{from: g2.y, to: g1.u}}
    """


def test_a_loop_without_solution_at_initialization_fails_cleanly(fmus):
    """a c = 1: y1 = a c y1 + b has no solution; exit 1, the loop and its residual named."""
    path = write(fmus, "singular", SINGULAR.format(a=2.0, rate=0.0, c=0.5))
    result = CliRunner().invoke(main, ["run", str(path), "-o", str(path.with_suffix(".csv"))])
    assert result.exit_code == 1, result.output
    message = result.output.strip().splitlines()[-1]
    assert message.startswith("Error: simulation failed at t = 0 s: algebraic loop g1.y -> g2.u, g2.y -> g1.u")
    assert "at initialization not solved: residual 0.5 at g2.y" in message  # b c = 0.5 whatever y1
    assert "Traceback" not in result.output
    assert not path.with_suffix(".csv").exists()  # no row computed: no result file made


def test_a_loop_that_loses_its_solution_keeps_the_results_so_far(fmus):
    """a(t) = 0.5 + t, c = 1: y1 = 1 / (0.5 - t) until a c reaches 1 at t = 0.5."""
    path = write(fmus, "ramp", SINGULAR.format(a=0.5, rate=1.0, c=1.0))
    result = CliRunner().invoke(main, ["run", str(path), "-o", str(path.with_suffix(".csv"))])
    assert result.exit_code == 1, result.output
    assert "Error: simulation failed at t = 0.4 s: algebraic loop g1.y -> g2.u, g2.y -> g1.u" in result.output
    kept = path.with_suffix(".failed.csv")  # a failed run's rows, under a name that says so
    assert "not solved: residual" in result.output and f"(results up to the failure in {kept})" \
        in result.output.replace("\n", "")
    c = columns(kept)
    np.testing.assert_allclose(c["time"], [0.0, 0.1, 0.2, 0.3, 0.4], atol=1e-12)
    np.testing.assert_allclose(c["g1.y"], 1.0 / (0.5 - c["time"]), rtol=1e-9)


# ------------------------------------------------------------------- a state inside the loop
T, D, K, X0 = 0.5, 0.5, -1.0, 1.0
LAMBDA = (K / (1 - K * D) - 1) / T


def lag_loop(fmus: Path, name: str, step: float, interface: str = "CS", loops: str = "{}", stop: float = 0.5):
    path = write(fmus, name, f"""\
        experiment: {{stop: {stop}, step: {step}}}
        master: {{loops: {loops}}}
        components:
          lag: {{fmu: Lag.fmu, interface: {interface}, parameters: {{T: {T}, d: {D}, x: {X0}}}}}
          k: {{fmu: Gain.fmu, parameters: {{a: {K}}}}}
        connections:
          - {{from: lag.y, to: k.u}}
          - {{from: k.y, to: lag.u}}
        outputs: [lag.x, lag.u, lag.y]
        """)
    return simulate(path)


def held_input_recurrence(step: float, n: int) -> np.ndarray:
    E = np.exp(-step / T)
    x = [X0]
    for _ in range(n):
        tau = K * E * x[-1] / (1 - K * (1 - E) - K * D)
        x.append(tau + (x[-1] - tau) * E)
    return np.array(x)


@pytest.mark.parametrize("interface", ["CS", "ME"])
def test_a_lag_in_the_loop_redoes_its_step_until_consistent(fmus, interface):
    """Every row satisfies the loop (u = k (x + d u)), the first one from initialization; the
    states follow the held-input recurrence to the integrator's accuracy, and the DAE's closed
    form to first order in the step."""
    errors = []
    for step in (0.02, 0.01):
        summary, c = lag_loop(fmus, f"lag_{interface}_{step}", step, interface)
        assert np.max(np.abs(c["lag.u"] - K * (c["lag.x"] + D * c["lag.u"]))) < 1e-9
        assert c["lag.u"][0] == pytest.approx(K * X0 / (1 - K * D), rel=1e-10)
        assert np.max(np.abs(c["lag.x"] - held_input_recurrence(step, len(c["time"]) - 1))) < 1e-7
        errors.append(np.max(np.abs(c["lag.x"] - X0 * np.exp(LAMBDA * c["time"]))))
    assert 1.8 < errors[0] / errors[1] < 2.2  # first order
    assert errors[1] < 3e-3


@pytest.mark.parametrize("loops, most_per_solve", [
    ("{}", 2.5),                                     # fixed point once, then Newton, finite differences
    ("{fixed_point_iterations: 0}", 2.5),            # Newton at once
    ("{jacobian: directional-derivative}", 3.5),     # the instantaneous partials miss dx(t+h)/du
    ("{method: fixed-point, max_iterations: 100}", 40),  # contraction 0.52 per iteration
])
def test_every_solver_setting_reaches_the_same_steps(fmus, loops, most_per_solve):
    summary, c = lag_loop(fmus, "lag_settings", 0.01, loops=loops, stop=0.2)
    np.testing.assert_allclose(c["lag.x"], held_input_recurrence(0.01, 20), atol=1e-8)
    assert summary.loops.evaluations <= most_per_solve * summary.loops.solves


def test_loops_under_the_adaptive_step(fmus):
    """Every trial step (coarse, and two halves) solves the loop; the accepted rows satisfy it."""
    path = write(fmus, "adaptive", f"""\
        experiment: {{stop: 0.3, step: 0.01}}
        master: {{adaptive: {{enabled: true, tolerance: 1.0e-5}}}}
        components:
          lag: {{fmu: Lag.fmu, parameters: {{T: {T}, d: {D}, x: {X0}}}}}
          k: {{fmu: Gain.fmu, parameters: {{a: {K}}}}}
        connections:
          - {{from: lag.y, to: k.u}}
          - {{from: k.y, to: lag.u}}
        outputs: [lag.x, lag.u]
        """)
    summary, c = simulate(path)
    assert np.max(np.abs(c["lag.u"] - K * (c["lag.x"] + D * c["lag.u"]))) < 1e-9
    # a seventh of the error of the fixed 0.01 s step (2.4e-3 at t = 0.3 s)
    assert np.max(np.abs(c["lag.x"] - X0 * np.exp(LAMBDA * c["time"]))) < 5e-4
    assert summary.loops.solves >= 3 * summary.steps


def test_events_inside_a_loop_are_recorded_once(fmus, build_fmu_from_src):
    """Two oscillators (ME; no direct_feedthrough declared, so energy depends on F) drive each
    other's force from their energy: a loop. a bounces on its wall; each redo of a step finds the
    impact again, but only the accepted evaluation's event rows (before, after) are written."""
    shutil.copy(build_fmu_from_src("oscillator.py"), fmus / "Osc.fmu")
    system = """\
        experiment: {{stop: 1.2, step: 0.01}}
        components:
          a: {{fmu: Osc.fmu, interface: ME, parameters: {{t_step: 100.0}}}}
          b: {{fmu: Osc.fmu, interface: ME, parameters: {{t_step: 100.0, wall: -5.0}}}}
        connections:
          - {{from: a.energy, to: b.F, factor: 0.01}}
        {feedback}
        outputs: [a.energy, a.impacts, b.energy, a.F, b.F]
        """
    # without the feedback (no loop): how many events the master sees per impact of this FMU
    one_way, c = simulate(write(fmus, "one_way", system.format(feedback="")))
    per_impact = one_way.events / c["a.impacts"][-1]
    summary, c = simulate(write(fmus, "oscillators", system.format(
        feedback="  - {from: b.energy, to: a.F, factor: 0.01}")))
    t = c["time"]
    on_grid = np.abs(t / 0.01 - np.round(t / 0.01)) < 1e-9
    assert c["a.impacts"][-1] == 2 and summary.events == per_impact * 2
    assert np.count_nonzero(~on_grid) == 2 * summary.events and np.all(np.diff(t) >= 0)
    # at every communication point both connections hold (event rows show the others' latest values)
    assert np.max(np.abs(c["b.F"] - 0.01 * c["a.energy"])[on_grid]) < 1e-9
    assert np.max(np.abs(c["a.F"] - 0.01 * c["b.energy"])[on_grid]) < 1e-9


# ---------------------------------------------------------------------------- validation
def _with_attribute(fmu: Path, target: Path, old: str, new: str) -> Path:
    """A copy of ``fmu`` whose modelDescription.xml has ``old`` replaced by ``new``."""
    with zipfile.ZipFile(fmu) as source, zipfile.ZipFile(target, "w") as copy:
        for item in source.infolist():
            data = source.read(item)
            if item.filename == "modelDescription.xml":
                text = data.decode()
                assert old in text
                data = text.replace(old, new).encode()
            copy.writestr(item, data)
    return target


LOOP = """\
experiment: {{stop: 1.0, step: 0.1}}
master: {{loops: {loops}}}
components:
  g1: {{fmu: {g1}, parameters: {{a: 0.5}}}}
  g2: {{fmu: Gain.fmu, step_multiple: {multiple}}}
connections:
  - {{from: g1.y, to: g2.u}}
  - {{from: g2.y, to: g1.u}}
"""


def validate(fmus: Path, g1: str = "Gain.fmu", loops: str = "{}", multiple: int = 1):
    path = fmus / "check.yaml"
    path.write_text(LOOP.format(g1=g1, loops=loops, multiple=multiple))
    return str(path), CliRunner().invoke(main, ["validate", str(path)])


def test_validate_describes_how_a_loop_is_solved(fmus):
    path, result = validate(fmus)
    assert result.exit_code == 0, result.output
    assert ("algebraic loop g1.y -> g2.u, g2.y -> g1.u (g1, g2; line 7): solved at initialization and at every step, "
            "iterating on g2.y") in result.output
    assert result.output.count("algebraic loop") == 1


def test_a_loop_needs_components_that_restore_their_state(fmus):
    _with_attribute(fmus / "Gain.fmu", fmus / "Stateless.fmu", 'canGetAndSetFMUstate="true"',
                    'canGetAndSetFMUstate="false"')
    path, result = validate(fmus, g1="Stateless.fmu")
    assert result.exit_code == 2, result.output
    assert (f"{path}:7: error: algebraic loop g1.y -> g2.u, g2.y -> g1.u (g1, g2; line 7): component 'g1' (CS) "
            "cannot save and restore its state") in result.output


def test_a_loop_steps_together(fmus):
    path, result = validate(fmus, multiple=2)
    assert result.exit_code == 2, result.output
    assert f"{path}:7: error: algebraic loop" in result.output
    assert "need the same step_multiple (they have g1: 1, g2: 2)" in result.output


def test_directional_derivatives_on_request_need_every_fmu_to_give_them(fmus):
    _with_attribute(fmus / "Gain.fmu", fmus / "NoDerivatives.fmu", 'providesDirectionalDerivative="true"',
                    'providesDirectionalDerivative="false"')
    path, result = validate(fmus, g1="NoDerivatives.fmu", loops="{jacobian: directional-derivative}")
    assert result.exit_code == 2, result.output
    assert "component 'g1' (CS) does not provide fmi2GetDirectionalDerivative" in result.output
    path, result = validate(fmus, g1="NoDerivatives.fmu")  # auto: finite differences
    assert result.exit_code == 0, result.output


def test_loop_settings_are_checked_with_their_line(fmus):
    path, result = validate(fmus, loops="{tolerance: 0, max_iteration: 5}")
    assert result.exit_code == 2, result.output
    assert f"{path}:2: error: master.loops.tolerance: 0 is less than or equal to the minimum of 0" in result.output
    assert f"{path}:2: error: unknown key 'max_iteration' in master.loops (did you mean 'max_iterations'" \
        in result.output
    path, result = validate(fmus, loops="{method: newtn}")
    assert "master.loops.method: 'newtn' is not allowed (did you mean 'newton'?)" in result.output


def test_adaptive_and_loops_import_nothing_of_the_master():
    """The master imports the adaptive loop and the loop solver; they drive it through small
    protocols and import nothing of it, not even for type checking (no import cycle)."""
    stepping = Path(deltafmi.master.stepping.__file__).parent
    for module in ("adaptive.py", "algebraic_loops.py"):
        tree = ast.parse((stepping / module).read_text())
        imported = {node.module for node in ast.walk(tree) if isinstance(node, ast.ImportFrom)}
        imported |= {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import) for alias in node.names}
        assert not {name for name in imported if name and name.split(".")[-1] == "master"}, module
    code = "import sys, deltafmi.master.stepping.adaptive; assert 'deltafmi.master.stepping.master' not in sys.modules"
    subprocess.run([sys.executable, "-c", code], check=True)
