"""Study files: schema and name errors at file:line with suggestions, and the cases they make
(grid product, zipped lists, reproducible Monte Carlo samples)."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.errors import ScenarioError
from deltafmi.apps.studies.cases import generate_cases
from deltafmi.apps.studies.plan import plan_study
from deltafmi.apps.studies.spec import load_study, parse_study

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = f"""\
experiment: {{stop: 1.0, step: 1.0e-3}}
components:
  osc:
    source: {ROOT / 'fmu_src' / 'oscillator.py'}
    interface: ME
outputs: [osc.x]
"""
GOOD = """\
scenario: osc.yaml
vary:
  grid:
    osc.k: {from: 30, to: 50, step: 10}
    osc.c: [0.5, 1.0]
metrics:
  peak: {signal: osc.x, statistic: max}
"""


def write(folder: Path, study: str, scenario: str = SCENARIO) -> Path:
    (folder / "osc.yaml").write_text(scenario)
    path = folder / "study.yaml"
    path.write_text(textwrap.dedent(study))
    return path


def errors(path: Path, plan: bool = False) -> list:
    with pytest.raises(ScenarioError) as info:
        study = load_study(path)
        if plan:
            plan_study(study)
    return [str(d) for d in info.value.diagnostics]


@pytest.mark.parametrize("text, line, message", [
    (GOOD.replace("metrics:", "metrix:"), 6, "unknown key 'metrix' in the study (did you mean 'metrics'?)"),
    (GOOD.replace("statistic: max", "statistic: maximum"), 7, "'maximum' is not allowed (did you mean 'max'?)"),
    (GOOD.replace("statistic: max}", "statistic: max, level: 0.5}"), 7,
     "metric 'peak': 'level' applies to first_crossing, not to 'max'"),
    (GOOD.replace("statistic: max}", "statistic: settling_time}"), 7, "metric 'peak': 'settling_time' needs 'band'"),
    (GOOD.replace("signal: osc.x,", "signal: osc.x-osc.v,"), 7,
     "write a difference with spaces around the minus"),
    (GOOD.replace("step: 10}", "num: 3, step: 10}"), 4, "grid 'osc.k': give either 'step' or 'num'"),
    (GOOD.replace("    osc.c: [0.5, 1.0]", "    experiment.stopp: [1.0]"), 5,
     "'experiment.stopp': a study varies only experiment.stop and experiment.step of the experiment "
     "(did you mean 'experiment.stop' or 'experiment.step'?)"),
    (GOOD.replace("  grid:\n    osc.k: {from: 30, to: 50, step: 10}\n    osc.c: [0.5, 1.0]",
                  "  zip:\n    osc.k: [30, 40]\n    osc.c: [0.5, 1.0, 2.0]"), 3,
     "zipped lists must have the same length (osc.k: 2, osc.c: 3)"),
    (GOOD.replace("  grid:\n    osc.k: {from: 30, to: 50, step: 10}\n    osc.c: [0.5, 1.0]",
                  "  monte_carlo:\n    samples: 4\n    seed: 1\n    parameters:\n"
                  "      osc.k: {distribution: uniform, low: 30, mean: 50}"), 7,
     "'osc.k': 'mean' is not a parameter of the uniform distribution (it takes low and high)"),
])
def test_schema_and_semantic_errors_name_file_line(tmp_path, text, line, message):
    found = errors(write(tmp_path, text))
    assert any(f"study.yaml:{line}: error: " in e and message in e for e in found), found


@pytest.mark.parametrize("replace, by, line, message", [
    ("osc.k: {from", "osk.k: {from", 4, "'osk.k': the scenario has no component 'osk' (did you mean 'osc'?)"),
    ("osc.k: {from", "osc.kk: {from", 4, "component 'osc' has no variable 'kk' (did you mean 'k'?)"),
    ("osc.c: [0.5, 1.0]", "osc.c: [0.5, abc]", 5, "type mismatch: 'c' is Real but the value 'abc' is str"),
    ("osc.c: [0.5, 1.0]", "osc.impacts: [1, 2]", 5, "'impacts' is an output (calculated) and cannot be set"),
    ("signal: osc.x,", "signal: osc.energi,", 7,
     "metric 'peak': component 'osc' has no variable 'energi' (did you mean 'energy'?)"),
    ("signal: osc.x,", "signal: osc.x - osc.v,", 7, "metric 'peak': 'osc.x' is in 'm' but 'osc.v' in 'm/s'"),
])
def test_names_are_checked_against_the_scenario_and_fmus(tmp_path, replace, by, line, message):
    found = errors(write(tmp_path, GOOD.replace(replace, by)), plan=True)
    assert any(f"study.yaml:{line}: error: " in e and message in e for e in found), found


def test_monte_carlo_of_an_integer_is_an_error(tmp_path):
    text = GOOD.replace("  grid:\n    osc.k: {from: 30, to: 50, step: 10}\n    osc.c: [0.5, 1.0]",
                        "  monte_carlo:\n    samples: 4\n    seed: 1\n    parameters:\n"
                        "      osc.impacts: {distribution: normal, mean: 1, std: 0.1}")
    found = errors(write(tmp_path, text), plan=True)
    assert any("study.yaml:7: error: 'osc.impacts' is Integer: Monte Carlo samples are real numbers" in e
               for e in found), found


def test_cli_reports_bad_study_with_exit_code_2_and_no_traceback(tmp_path):
    path = write(tmp_path, GOOD.replace("osc.k: {from", "osc.kk: {from"))
    result = CliRunner().invoke(main, ["sweep", str(path), "--dry-run"])
    assert result.exit_code == 2
    assert "study.yaml:4: error:" in result.output and "Traceback" not in result.output
    ok = CliRunner().invoke(main, ["sweep", str(write(tmp_path, GOOD)), "--dry-run"])
    assert ok.exit_code == 0, ok.output
    assert "6 cases varying osc.k, osc.c" in ok.output


def test_grid_is_the_cartesian_product_first_axis_slowest(tmp_path):
    study = parse_study(GOOD, tmp_path / "s.yaml")
    cases = generate_cases(study.vary)
    assert [c.values for c in cases] == [{"osc.k": k, "osc.c": c} for k in (30, 40, 50) for c in (0.5, 1.0)]
    assert [c.id for c in cases] == list(range(6))
    spaced = parse_study(GOOD.replace("{from: 30, to: 50, step: 10}", "{from: 0, to: 1, num: 11}"), tmp_path / "s.yaml")
    assert spaced.vary.grid[0][1][3] == 0.3 and len(spaced.vary.grid[0][1]) == 11


def test_zip_then_monte_carlo_product_and_reproducible_samples(tmp_path):
    text = """\
    scenario: osc.yaml
    vary:
      zip: {osc.k: [30, 40], osc.c: [0.5, 1.0]}
      monte_carlo:
        samples: 3
        seed: 7
        parameters:
          osc.m: {distribution: uniform, low: 0.9, high: 1.1, relative: true}
          osc.x: {distribution: normal, mean: 1.0, std: 0.1}
    metrics:
      peak: {signal: osc.x, statistic: max}
    """
    study = parse_study(textwrap.dedent(text), tmp_path / "s.yaml")
    cases = generate_cases(study.vary, {"osc.m": 2.0})
    assert len(cases) == 6
    assert [(c.values["osc.k"], c.values["osc.c"]) for c in cases] == [(30, 0.5)] * 3 + [(40, 1.0)] * 3
    masses = [c.values["osc.m"] for c in cases]
    assert masses[:3] == masses[3:]  # common random numbers across the zipped rows
    assert all(1.8 <= m <= 2.2 for m in masses)  # relative: nominal 2 x uniform(0.9, 1.1)
    again = generate_cases(study.vary, {"osc.m": 2.0})
    assert [c.values for c in again] == [c.values for c in cases]
    more = parse_study(textwrap.dedent(text).replace("samples: 3", "samples: 5"), tmp_path / "s.yaml")
    longer = generate_cases(more.vary, {"osc.m": 2.0})
    assert [longer[i].values for i in range(3)] == [cases[i].values for i in range(3)]  # more samples keep the first


@pytest.mark.parametrize("spec, mean, std", [
    ("{distribution: uniform, low: 2.0, high: 4.0}", 3.0, 2.0 / np.sqrt(12)),
    ("{distribution: normal, mean: -1.0, std: 0.5}", -1.0, 0.5),
    ("{distribution: lognormal, mu: 0.1, sigma: 0.2}", np.exp(0.1 + 0.02), np.sqrt((np.exp(0.04) - 1) * np.exp(0.24))),
])
def test_samples_follow_their_distribution(tmp_path, spec, mean, std):
    text = f"""\
    scenario: osc.yaml
    vary:
      monte_carlo:
        samples: 20000
        seed: 3
        parameters: {{osc.k: {spec}}}
    metrics:
      peak: {{signal: osc.x, statistic: max}}
    """
    values = np.array([c.values["osc.k"] for c in generate_cases(parse_study(textwrap.dedent(text), tmp_path / "s.yaml").vary)])
    # sample mean within 5 standard errors, sample standard deviation within 3 %
    assert abs(values.mean() - mean) < 5 * std / np.sqrt(len(values))
    assert values.std(ddof=1) == pytest.approx(std, rel=0.03)
