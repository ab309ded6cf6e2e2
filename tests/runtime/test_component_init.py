"""A component that defines ``__init__`` is refused at build time, pointing at the ``def`` and at setup().

An FMU creates its component without calling ``__init__`` (and fmi2Reset makes a fresh one the same
way), so an attribute set there would fail later with AttributeError inside a run.
"""
from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

CLI = [sys.executable, "-c", "from deltafmi.apps.cli import main; main()"]

OWN_INIT = '''\
from deltafmi.component import Component, Output, Parameter


class Counter(Component):
    """Counts steps."""

    gain = Parameter(2.0, description="Gain")
    y = Output(0.0, description="Output")

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.count = 0

    def outputs(self, t):
        self.y = self.gain * self.count
'''

MIXIN_INIT = '''\
from deltafmi.component import Component, Output


class Buffered:
    """A helper base that keeps a history."""

    def __init__(self):
        self.history = []


class Logger(Buffered, Component):
    """Records its input."""

    y = Output(0.0, description="Output")

    def outputs(self, t):
        self.y = len(self.history)
'''


def _build(source: Path, tmp_path: Path) -> subprocess.CompletedProcess:
    return subprocess.run(CLI + ["build", str(source), "-o", str(tmp_path / "out.fmu"), "--no-validate"],
                          capture_output=True, text=True, cwd=tmp_path, timeout=300)


def test_build_refuses_a_component_with_its_own_init(tmp_path: Path) -> None:
    source = tmp_path / "counter.py"
    source.write_text(OWN_INIT)
    result = _build(source, tmp_path)
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    # the line of `def __init__` in the file, and the hook to use instead
    assert lines[0].startswith("Error: counter.py:10: Counter defines __init__, which an FMU never calls")
    assert "setup()" in lines[0]
    assert not (tmp_path / "out.fmu").exists()


def test_build_refuses_a_mixin_init(tmp_path: Path) -> None:
    source = tmp_path / "logger.py"
    source.write_text(MIXIN_INIT)
    result = _build(source, tmp_path)
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    assert "Error: logger.py:7: Buffered (a base of Logger) defines __init__" in result.stderr
    assert "setup()" in result.stderr


def test_a_scenario_naming_such_a_component_fails_before_running(tmp_path: Path) -> None:
    (tmp_path / "counter.py").write_text(OWN_INIT)
    scenario = tmp_path / "counting.yaml"
    scenario.write_text(textwrap.dedent("""\
        experiment: {start: 0.0, stop: 0.01, step: 1.0e-3}
        components:
          counter: {source: counter.py}
        """))
    result = subprocess.run(CLI + ["run", str(scenario), "-o", str(tmp_path / "r.csv")],
                            capture_output=True, text=True, cwd=tmp_path, timeout=300)
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    assert "counter.py:10: Counter defines __init__" in result.stderr
    assert "setup()" in result.stderr
    assert not (tmp_path / "r.csv").exists()


FEEDTHROUGH = '''\
from deltafmi.component import Component, Input, Output, State


class Gain(Component):
    """y = k u + x, with a force output named by its FMI name."""

    x = State(0.0, description="State")
    u = Input(0.0, description="Input")
    v = Input(0.0, description="Unused input")
    y = Output(description="Output")
    lam = Output(name="lambda", description="Also follows u")

    direct_feedthrough = {{"y": ["u"], "lambda": {lam_inputs}}}

    def derivatives(self, t):
        return [-self.x]

    def outputs(self, t):
        self.y = 2.0 * self.u + self.x
        self.lam = self.u
'''


def test_direct_feedthrough_by_fmi_name_declares_the_dependency(tmp_path: Path) -> None:
    from fmpy import read_model_description

    from deltafmi.builder import build_fmu

    source = tmp_path / "gain.py"
    source.write_text(FEEDTHROUGH.format(lam_inputs='["u"]'))
    md = read_model_description(str(build_fmu(source, tmp_path / "gain.fmu")))
    u = next(v for v in md.modelVariables if v.name == "u")
    x = next(v for v in md.modelVariables if v.name == "x")
    dependencies = {o.variable.name: {d.name for d in o.dependencies} for o in md.outputs}
    assert dependencies == {"y": {x.name, u.name}, "lambda": {x.name, u.name}}


def test_a_misspelt_direct_feedthrough_name_is_a_build_error(tmp_path: Path) -> None:
    source = tmp_path / "gain.py"
    source.write_text(FEEDTHROUGH.format(lam_inputs='["uu"]'))
    result = _build(source, tmp_path)
    assert result.returncode == 2, result.stdout + result.stderr
    assert "Traceback" not in result.stderr
    assert ("Error: gain.py:13: direct_feedthrough['lambda'] names 'uu', which is not an input of Gain "
            "(inputs: u, v)") in result.stderr


def test_a_file_with_two_components_says_how_to_pick_one(tmp_path: Path) -> None:
    source = tmp_path / "pair.py"
    source.write_text(MIXIN_INIT.replace("class Buffered:", "class Buffered(Component):")
                      .replace("    def __init__(self):\n        self.history = []\n", "    pass\n")
                      .replace("class Logger(Buffered, Component):", "class Logger(Component):"))
    result = _build(source, tmp_path)
    assert result.returncode == 2, result.stdout + result.stderr
    assert ("expected exactly one Component subclass, found Buffered, Logger "
            "(build one of them as pair.py:Buffered)") in result.stderr
