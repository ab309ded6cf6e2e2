"""One set of checks: a study's cases pass the checks a scenario's values and --set pass (type,
finite, declared min and max) before any case runs, with the same words."""
from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

from deltafmi.apps.cli import main

SCENARIO = """\
experiment: {stop: 0.2, step: 0.01}
components:
  osc: {source: 'deltafmi.models:Oscillator', interface: ME}
outputs: [osc.x]
"""


def _study(tmp_path: Path, vary: str) -> Path:
    (tmp_path / "osc.yaml").write_text(SCENARIO)
    path = tmp_path / "study.yaml"
    path.write_text(f"scenario: osc.yaml\nvary:\n{vary}metrics:\n  peak: {{signal: osc.x, statistic: max}}\n")
    return path


def test_a_case_outside_the_declared_range_is_refused_before_any_case_runs(tmp_path):
    study = _study(tmp_path, "  grid:\n    osc.m: [1, 0, -1, -2]\n")
    done = CliRunner().invoke(main, ["sweep", str(study)])
    assert done.exit_code == 2, done.output
    assert done.output.strip().splitlines()[-1] == \
        f"{study}:4: error: 'osc.m' = -1 in case 2 is outside its declared range [0, inf] (and 1 more case)"
    assert not (tmp_path / "study.journal.jsonl").exists()  # nothing ran
    # the scenario's own check says the same of the same value
    scenario = CliRunner().invoke(main, ["run", str(tmp_path / "osc.yaml"), "--set", "osc.m=-1"])
    assert scenario.exit_code == 2 and "is outside its declared range [0, inf]" in scenario.output


def test_monte_carlo_samples_and_zipped_values_pass_the_same_checks(tmp_path):
    study = _study(tmp_path, "  monte_carlo:\n    samples: 50\n    seed: 1\n    parameters:\n"
                             "      osc.m: {distribution: normal, mean: 0.1, std: 1.0}\n")
    done = CliRunner().invoke(main, ["sweep", str(study), "--dry-run"])
    assert done.exit_code == 2, done.output
    assert "'osc.m' = " in done.output and "is outside its declared range [0, inf]" in done.output
    study = _study(tmp_path, "  zip:\n    osc.m: [1.0, .nan]\n    osc.k: [10.0, 20.0]\n")
    done = CliRunner().invoke(main, ["sweep", str(study), "--dry-run"])
    assert done.exit_code == 2, done.output
    assert "'osc.m' = nan in case 1 is not a finite number" in done.output


def test_values_inside_the_range_plan_as_before(tmp_path):
    study = _study(tmp_path, "  grid:\n    osc.m: [0.5, 1.0, 2.0]\n")
    done = CliRunner().invoke(main, ["sweep", str(study), "--dry-run"])
    assert done.exit_code == 0, done.output
    assert "3 cases varying osc.m" in done.output
