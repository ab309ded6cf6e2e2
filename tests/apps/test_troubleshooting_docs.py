"""The messages quoted in docs/troubleshooting.md are the ones the commands print.

Each case makes the situation an entry describes (with the worked example's components from
docs/components.md), runs the real CLI and finds the docs' line in what it printed: ``...`` and
``<...>`` in a quoted line stand for parts that vary (GUIDs, folders).
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from test_component_docs import doc_files

DOC = Path(__file__).resolve().parents[2] / "docs" / "troubleshooting.md"
CLI = [sys.executable, "-c", "from deltafmi.apps.cli import main; main()"]

NAN_SOURCE = '''\
import math

from deltafmi.component import Component, Output, State


class Nanny(Component):
    """Its output becomes NaN after 0.05 s."""

    x = State(1.0, unit="m", description="Decaying state")
    y = Output(unit="m", description="The state, then NaN")

    def derivatives(self, t):
        return [-self.x]

    def outputs(self, t):
        self.y = math.nan if t > 0.05 else self.x
'''

INIT_SOURCE = '''\
from deltafmi.component import Component, Input, Output


class Plant(Component):
    """Sets an attribute in __init__."""

    u = Input(0.0, description="Input")
    v = Input(0.0, description="Input")
    y = Output(description="Output")

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.gain = 2.0

    def outputs(self, t):
        self.y = self.gain * self.u
'''

FEEDTHROUGH_SOURCE = INIT_SOURCE.replace('''    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.gain = 2.0
''', '''    def setup(self):
        self.gain = 2.0

    direct_feedthrough = {"y": ["uu"]}
''')

PAIR_SOURCE = '''\
from deltafmi.component import Component


class A(Component):
    """One."""


class B(Component):
    """Two."""
'''

LOOP = '''\
experiment: {start: 0.0, stop: 0.1, step: 1.0e-3}
components:
  motor: {source: dc_motor.py, interface: ME}
  controller: {source: speed_controller.py}
connections:
  - {from: controller.voltage, to: motor.voltage}
  - {from: motor.speed, to: controller.speed}
'''

UNITS = '''\
experiment: {start: 0.0, stop: 0.1, step: 1.0e-3}
components:
  motor: {source: dc_motor.py}
  n: {source: nanny.py}
connections:
  - {from: n.y, to: motor.voltage}
'''

NAN = '''\
experiment: {start: 0.0, stop: 0.1, step: 1.0e-3}
components:
  n: {source: nanny.py}
'''


def quoted(prefix: str) -> str:
    """The one line of the docs that starts with ``prefix``, as a regular expression."""
    lines = [line for line in DOC.read_text().splitlines() if line.startswith(prefix)]
    assert len(lines) == 1, f"{prefix!r}: {len(lines)} lines of {DOC.name} start so"
    return ".*?".join(re.escape(part) for part in re.split(r"<[^>]*>|\.\.\.", lines[0]))


@pytest.fixture(scope="module")
def folder(tmp_path_factory: pytest.TempPathFactory) -> Path:
    folder = tmp_path_factory.mktemp("troubles")
    example = doc_files()
    for name in ("dc_motor.py", "speed_controller.py"):
        (folder / name).write_text(example[name])
    (folder / "nanny.py").write_text(NAN_SOURCE)
    (folder / "loop.yaml").write_text(LOOP)
    (folder / "scenario.yaml").write_text(UNITS)
    (folder / "nan.yaml").write_text(NAN)
    (folder / "afile").write_text("a file, not a folder\n")
    (folder / "x.fmu").write_bytes(bytes(range(256)))
    os.mkfifo(folder / "pipe.csv")
    return folder


def cli(folder: Path, *args: str, env: dict | None = None) -> tuple[int, str]:
    result = subprocess.run(CLI + list(args), capture_output=True, text=True, cwd=folder, timeout=300,
                            env=env)
    assert "Traceback" not in result.stderr, result.stderr
    return result.returncode, result.stdout + result.stderr


@pytest.mark.parametrize("prefix, args", [
    ("Error: 'DeltaRobt'", ["build", "DeltaRobt"]),
    ("Error: no example called", ["run", "delta_trakcing"]),
    ("Error: stop time inf", ["run", "loop.yaml", "--stop", "inf"]),
    ("Error: communication step 0", ["run", "loop.yaml", "--step", "0"]),
    ("Error: tolerance 0", ["run", "loop.yaml", "--tolerance", "0"]),
    ("Error: result file 'r.txt'", ["run", "loop.yaml", "-o", "r.txt"]),
    ("--set controller.kk", ["run", "loop.yaml", "--set", "controller.kk=1"]),
    ("scenario.yaml:6: error: unit mismatch", ["validate", "scenario.yaml"]),
    ("Error: n.y is NaN", ["run", "nan.yaml", "-o", "nan.csv"]),
    ("Error: result file 'afile/r.csv'", ["run", "loop.yaml", "-o", "afile/r.csv"]),
    ("Error: result file 'pipe.csv'", ["run", "loop.yaml", "-o", "pipe.csv"]),
    ("Error: 3.5e+12 communication steps", ["run", "delta_tracking", "--step", "1e-12"]),
    ("Error: x.fmu: cannot read it as an FMU", ["info", "x.fmu"]),
    ("Error: cannot reach the Dask scheduler", ["sweep", "gain_payload", "--fresh", "--scheduler",
                                                "tcp://127.0.0.1:9"]),
])
def test_a_quoted_error(folder: Path, prefix: str, args: list) -> None:
    code, output = cli(folder, *args)
    assert code != 0
    assert re.search(quoted(prefix), output), output


def test_the_line_of_a_folder_made(folder: Path) -> None:
    code, output = cli(folder, "run", "loop.yaml", "--stop", "0.01", "-q", "-o", "results/today/r.csv")
    assert code == 0 and re.search(quoted("made the folder"), output), output
    assert (folder / "results" / "today" / "r.csv").is_file()


@pytest.mark.parametrize("prefix, name, source", [
    ("Error: plant.py:11: Plant defines __init__", "plant.py", INIT_SOURCE),
    ("Error: plant.py:14: direct_feedthrough", "plant.py", FEEDTHROUGH_SOURCE),
    ("Error: my_plant.py: expected exactly one", "my_plant.py", PAIR_SOURCE),
])
def test_a_quoted_build_error(tmp_path: Path, prefix: str, name: str, source: str) -> None:
    (tmp_path / name).write_text(source)
    code, output = cli(tmp_path, "build", name, "--no-validate")
    assert code == 2
    assert re.search(quoted(prefix), output), output


def test_the_unconnected_input_warning(folder: Path) -> None:
    scenario = folder / "scenario_loose.yaml"
    scenario.write_text(LOOP)
    code, output = cli(folder, "validate", scenario.name)
    assert code == 0
    assert re.search(quoted("scenario.yaml: warning: input(s) not connected").replace(
        "scenario\\.yaml", "scenario_loose\\.yaml"), output), output


def test_the_live_run_messages(folder: Path) -> None:
    """A run paced far beyond what it can do falls behind; a UDP source nobody sends to goes
    silent; a second run on the same port cannot listen."""
    import socket

    code, output = cli(folder, "run", "loop.yaml", "--stop", "0.05", "--speed", "100000", "-o", "fast.csv")
    assert code == 0 and re.search(quoted("warning: fell behind real time"), output), output
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", 0))
        port = taken.getsockname()[1]
        (folder / "live.yaml").write_text(LOOP.replace("connections:", f"""\
live:
  cmd:
    udp: {{port: {port}}}
    timeout: 0.05
    signals: {{v: {{unit: V}}}}
connections:"""))
        code, output = cli(folder, "run", "live.yaml", "-o", "live.csv")
        assert code == 2 and re.search(quoted("Error: live input '"), output), output
    code, output = cli(folder, "run", "live.yaml", "--stop", "0.3", "--realtime", "-o", "live.csv")
    assert code == 0 and re.search(quoted("warning: live input '"), output), output


def test_no_compiler(tmp_path: Path) -> None:
    (tmp_path / "my_plant.py").write_text(doc_files()["dc_motor.py"])
    env = {k: v for k, v in os.environ.items() if k != "CC"}
    env.update(PATH=str(Path(sys.executable).parent), DELTAFMI_CACHE=str(tmp_path / "cache"))
    code, output = cli(tmp_path, "build", "my_plant.py", "--no-validate", env=env)
    assert code != 0
    assert re.search(quoted("Error: my_plant.py: building needs a C compiler"), output), output


def test_fmus_that_do_not_start(folder: Path) -> None:
    cli(folder, "build", "dc_motor.py", "-o", "DCMotor.fmu")
    with zipfile.ZipFile(folder / "DCMotor.fmu") as fmu:
        entries = {info.filename: fmu.read(info) for info in fmu.infolist()}
    description = entries["modelDescription.xml"].decode()
    guid = re.search(r'guid="\{(.)', description)
    other = "0" if guid.group(1) != "0" else "1"
    changed = description.replace(f'guid="{{{guid.group(1)}', f'guid="{{{other}', 1)
    for name, replaced in (("Guid.fmu", {"modelDescription.xml": changed.encode()}),
                           ("NoBin.fmu", {n: None for n in entries if n.startswith("binaries/")})):
        with zipfile.ZipFile(folder / name, "w") as fmu:
            for entry, data in {**entries, **replaced}.items():
                if data is not None:
                    fmu.writestr(entry, data)
    (folder / "junk.fmu").write_text("hello\n")

    code, output = cli(folder, "run", "Guid.fmu", "--stop", "0.01")
    assert code != 0 and re.search(quoted("Error: simulation failed at t = 0 s: DCMotor (Guid.fmu)"), output), output
    code, output = cli(folder, "validate", "Guid.fmu")
    assert code != 0 and re.search(quoted("Error: Guid.fmu: the GUID"), output), output
    code, output = cli(folder, "validate", "NoBin.fmu")
    assert code != 0 and re.search(quoted("Error: NoBin.fmu: no binary"), output), output
    code, output = cli(folder, "run", "junk.fmu")
    assert code != 0 and re.search(quoted("junk.fmu: error:"), output), output


BUG_SOURCE = '''\
from deltafmi.component import Component, Output


class Trajectory(Component):
    """Raises in outputs() after 0.05 s."""

    r = Output(description="Reference")

    def outputs(self, t):
        if t > 0.05:
            raise RuntimeError("my bug")
        self.r = t
'''


def test_an_exception_in_a_component_and_a_too_long_controller_step(tmp_path: Path) -> None:
    (tmp_path / "trajectory.py").write_text(BUG_SOURCE)
    (tmp_path / "bug.yaml").write_text("experiment: {stop: 0.1, step: 0.01}\n"
                                       "components:\n  trajectory: {source: trajectory.py}\n")
    code, output = cli(tmp_path, "run", "bug.yaml", "-o", "r.csv")
    assert code == 1 and re.search(quoted("Error: simulation failed at t = <t> s: <component>: fmi2DoStep"),
                                   output), output
    code, output = cli(tmp_path, "run", "delta_tracking", "--stop", "0.01", "--step", "0.002", "-o", "r.csv")
    assert code == 0 and re.search(quoted("warning: controller: communication step"), output), output
    # the same failure again, now that r.csv holds a good result: it stays, the rows go beside it
    code, output = cli(tmp_path, "run", "bug.yaml", "-o", "r.csv")
    assert code == 1 and re.search(quoted("Error: simulation failed at t = <t> s: <reason> (results up to the "
                                          "failure in r.failed.csv; r.csv left as it was)"), output), output
