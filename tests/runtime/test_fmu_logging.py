"""The FMU speaks through the FMI logger, and only there (issue 25, part 4).

A test component (tests/components/chatty) logs at every level, warns, and ends the simulation at
t_end through Component.terminate_simulation. Checked in the plain-C host (stdout and stderr of
the process captured: the logger's lines and the result rows, nothing else), in an fmpy host with
two instances stepped from two threads, and through ``deltafmi run`` with and without -v/-q.
"""
from __future__ import annotations

import json
import logging
import math
import re
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import pytest
from click.testing import CliRunner

from conftest import clean_env, unzip
from deltafmi.apps.cli import main
from deltafmi.runtime.fmu_logging import CATEGORIES, message
from deltafmi.master.results.csv_file import columns
from deltafmi.builder import build_fmu

# in-process runs (fmpy, deltafmi run): pytest's own warning capture replaces the FMU's hook
pytestmark = pytest.mark.filterwarnings("ignore:a warnings.warn from initialize")

COMPONENT = Path(__file__).parents[1] / "components" / "chatty" / "model.py"
LINE = re.compile(r"^\[(?P<instance>[^|]*)\|(?P<status>\d)\|(?P<category>\w+)\] (?P<text>.*)$")
T_END = 0.55  # the component's default t_end
# what the component says, by category (texts as logged)
COMPONENT_SAYS = {"setup: the model is loaded", "debug record from initialize", "info record: T = 1 s",
                  "info through Component.log"}
WARNS = {"warning record from initialize", "some.library: a library's warning",
         "resources/model/model.py:30: UserWarning: a warnings.warn from initialize"}
ERROR = "error record from initialize (the run goes on)"
REASON = "ending the simulation: t_end = 0.55 s reached"


@pytest.fixture(scope="module")
def chatty(tmp_path_factory) -> Path:
    return build_fmu(COMPONENT, tmp_path_factory.mktemp("chatty") / "Chatty.fmu")


@pytest.fixture(scope="module")
def unzipped(chatty, tmp_path_factory) -> tuple[Path, str]:
    directory = unzip(chatty, tmp_path_factory.mktemp("chatty_unzipped"))
    guid = ET.parse(directory / "modelDescription.xml").getroot().get("guid")
    return directory, guid


def host_run(c_host: Path, unzipped: tuple[Path, str], mode: str = "cs", step: float = 0.1,
             **env: str) -> tuple[list[str], list[tuple[int, str, str]]]:
    """Run the C host on the Chatty FMU (output y, vr 4): its stdout lines and its logger's
    messages (status, category, text), checking that stderr holds nothing else."""
    directory, guid = unzipped
    run = subprocess.run([str(c_host), str(directory), "Chatty", guid, mode, "1.0", str(step), "4"],
                         capture_output=True, text=True, env=clean_env(HOST_NX="1", **env), timeout=600)
    assert run.returncode == 0, run.stderr
    messages = []
    for line in run.stderr.splitlines():
        match = LINE.match(line)
        assert match, f"stderr line not from the host's logger: {line!r}"
        assert match["instance"] == "host"
        messages.append((int(match["status"]), match["category"], match["text"]))
    return run.stdout.splitlines(), messages


def rows_and_end(lines: list[str]) -> tuple[list[tuple[float, float]], float]:
    """The CSV rows (t, y) of the host's stdout and the time of its 'terminated,<t>' line."""
    rows, end = [], math.nan
    for line in lines:
        if line.startswith("terminated,"):
            end = float(line.split(",")[1])
        elif not line.startswith("setDebugLogging="):
            t, y = line.split(",")
            rows.append((float(t), float(y)))
    return rows, end


def by_category(messages) -> dict[str, set[str]]:
    found: dict[str, set[str]] = {}
    for _, category, text in messages:
        found.setdefault(category, set()).add(text)
    return found


def test_log_categories_declared_are_the_ones_the_binary_accepts(unzipped, c_host):
    directory, _ = unzipped
    declared = [c.get("name") for c in ET.parse(directory / "modelDescription.xml").iter("Category")]
    assert declared == [name for name, _ in CATEGORIES] + ["logAll"]
    assert {"logEvents", "logStatusWarning", "logStatusDiscard", "logStatusError"} <= set(declared)  # FMI names
    lines, _ = host_run(c_host, unzipped, HOST_DEBUG_LOGGING="1:" + ",".join(declared))
    assert "setDebugLogging=0" in lines
    lines, messages = host_run(c_host, unzipped, HOST_DEBUG_LOGGING="1:logEvents,logBogus")
    assert "setDebugLogging=3" in lines
    errors = [text for status, category, text in messages if status == 3 and category == "logStatusError"]
    assert errors[0].startswith("fmi2SetDebugLogging: unknown log category 'logBogus' (this FMU's categories: "
                                "logEvents, logComponent, logSolver,")


def test_c_host_default_sends_warnings_errors_and_the_reason_only(unzipped, c_host):
    lines, messages = host_run(c_host, unzipped)
    assert by_category(messages) == {"logStatusWarning": WARNS, "logStatusError": {ERROR},
                                     "logStatusDiscard": {REASON}}
    assert {(s, c) for s, c, _ in messages} == {(1, "logStatusWarning"), (3, "logStatusError"), (2, "logStatusDiscard")}
    rows, end = rows_and_end(lines)  # stdout: the rows and the end, nothing else
    assert end == T_END and rows[-1][0] == T_END and [t for t, _ in rows[:-1]] == pytest.approx(
        [0.1 * k for k in range(6)], abs=1e-12)
    # CVODE at rtol 1e-8 against the exact decay x = exp(-t / T)
    assert max(abs(y - math.exp(-t)) for t, y in rows) < 1e-6


def test_c_host_logging_on_sends_every_category(unzipped, c_host):
    _, messages = host_run(c_host, unzipped, HOST_LOGGING_ON="1")
    found = by_category(messages)
    assert found["logComponent"] == COMPONENT_SAYS
    assert found["logStatusWarning"] == WARNS and found["logStatusDiscard"] == {REASON}
    assert any(text.startswith("event at t = 0.55") and text.endswith("terminate True") for text in found["logEvents"])
    assert [text.startswith("CVODE (bdf) from t = 0.0: 1 states") for text in found["logSolver"]] == [True]
    assert all(status == 0 for status, category, _ in messages if category in ("logComponent", "logEvents", "logSolver"))


@pytest.mark.parametrize("setting, expected", [
    ("1:logEvents,logSolver", {"logEvents", "logSolver", "logStatusError"}),  # exactly those, and errors
    ("0:", {"logStatusError"}),  # everything off: errors still go (FMI 2.0: an fmi2Error explains itself)
    ("0:logStatusWarning", {"logStatusDiscard", "logStatusError"}),  # one category off
    ("1:", {"logEvents", "logComponent", "logSolver", "logStatusWarning", "logStatusDiscard", "logStatusError"}),
])
def test_set_debug_logging_filters_categories(unzipped, c_host, setting, expected):
    lines, messages = host_run(c_host, unzipped, HOST_DEBUG_LOGGING=setting)
    assert "setDebugLogging=0" in lines
    found = by_category(messages)
    assert set(found) == expected
    assert found["logStatusError"] == {ERROR}


def test_c_host_model_exchange_terminate_simulation(unzipped, c_host):
    lines, messages = host_run(c_host, unzipped, mode="me", step=0.01)
    rows, end = rows_and_end(lines)
    assert end == T_END and rows[-1][0] == T_END
    # the host's explicit Euler: x_k = (1 - h / T)^k up to the time event at t_end
    assert rows[-1][1] == pytest.approx((1 - 0.01) ** 55, rel=1e-12)
    assert by_category(messages)["logStatusDiscard"] == {REASON}


FMPY_HOST = textwrap.dedent('''
    """Two instances of the Chatty FMU in one fmpy host, instantiated and stepped from two threads."""
    import json, logging, sys, threading, warnings
    from fmpy import calloc, free, read_model_description
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import (FMU2Slave, fmi2CallbackAllocateMemoryTYPE, fmi2CallbackFreeMemoryTYPE,
                           fmi2CallbackFunctions, fmi2CallbackLoggerTYPE, fmi2LastSuccessfulTime, fmi2Terminated)

    directory = sys.argv[1]
    host_records, host_warnings = [], []

    class Keep(logging.Handler):
        def emit(self, record):
            host_records.append(record.getMessage())

    logging.getLogger().addHandler(Keep())  # the host's own logging configuration ...
    warnings.showwarning = lambda message, *args, **kwargs: host_warnings.append(str(message))  # ... and warnings
    md = read_model_description(directory)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    barrier = threading.Barrier(2)
    results = {}

    def run(name, T, t_end):
        messages = []

        def logger(env, instance, status, category, message):
            messages.append([instance.decode(), status, category.decode(), message.decode()])

        callbacks = fmi2CallbackFunctions()
        callbacks.logger = fmi2CallbackLoggerTYPE(logger)
        callbacks.allocateMemory = fmi2CallbackAllocateMemoryTYPE(calloc)
        callbacks.freeMemory = fmi2CallbackFreeMemoryTYPE(free)
        fmu = FMU2Slave(guid=md.guid, unzipDirectory=directory, modelIdentifier="Chatty", instanceName=name)
        barrier.wait()
        fmu.instantiate(callbacks=callbacks, loggingOn=True)
        fmu.setupExperiment(startTime=0.0)
        fmu.setReal([vr["T"], vr["t_end"]], [T, t_end])
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        t = 0.0
        for k in range(1, 101):
            try:
                fmu.doStep(t, 0.01)
            except FMICallException as exc:
                results[name] = {"status": exc.status, "terminated": fmu.getBooleanStatus(fmi2Terminated),
                                 "reached": fmu.getRealStatus(fmi2LastSuccessfulTime),
                                 "y": fmu.getReal([vr["y"]])[0], "messages": messages}
                break
            t = k * 0.01
        fmu.terminate()
        fmu.freeInstance()

    threads = [threading.Thread(target=run, args=args) for args in (("a", 1.0, 0.33), ("b", 2.0, 0.77))]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    logging.getLogger("host").warning("host record")
    warnings.warn("host warning")
    print(json.dumps({"results": results, "host_records": host_records, "host_warnings": host_warnings}))
''')


def test_fmpy_host_two_threads_each_instance_gets_its_own_messages(unzipped, tmp_path):
    directory, _ = unzipped
    script = tmp_path / "fmpy_host.py"
    script.write_text(FMPY_HOST)
    run = subprocess.run([sys.executable, str(script), str(directory)], capture_output=True, text=True, timeout=600)
    assert run.returncode == 0, run.stderr
    assert run.stderr == ""  # the FMUs printed nothing
    out = json.loads(run.stdout)  # and stdout is the script's one line
    # the host's logging and warnings saw only the host's own, and still work
    assert out["host_records"] == ["host record"] and out["host_warnings"] == ["host warning"]
    for name, T, t_end, other in (("a", 1, 0.33, "T = 2 s"), ("b", 2, 0.77, "T = 1 s")):
        result = out["results"][name]
        assert result["status"] == 2 and result["terminated"] is True  # fmi2Discard + fmi2Terminated
        assert result["reached"] == t_end  # fmi2LastSuccessfulTime: the time event, exactly
        assert result["y"] == pytest.approx(math.exp(-t_end / T), rel=1e-6)
        texts = [text for instance, _, _, text in result["messages"]]
        assert {instance for instance, _, _, _ in result["messages"]} == {name}
        assert f"info record: T = {T} s" in texts and not any(other in text for text in texts)
        assert texts.count(f"ending the simulation: t_end = {t_end:g} s reached") == 1
        assert texts.count("warning record from initialize") == 1 and ERROR in texts


@pytest.fixture(scope="module")
def scenario(chatty, tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("chatty_cli")
    path = folder / "chatty.yaml"
    path.write_text(f"experiment: {{stop: 2.0, step: 0.1}}\n"
                    f"components:\n  cs: {{fmu: {chatty}, interface: CS}}\n"
                    f"  me: {{fmu: {chatty}, interface: ME, parameters: {{t_end: 0.35}}}}\n"
                    "outputs: [cs.y, me.y]\nresult: {file: out/chatty.csv}\n")
    return path


def test_run_shows_warnings_and_errors_and_why_the_run_ended(scenario):
    result = CliRunner().invoke(main, ["run", str(scenario)])
    assert result.exit_code == 0, result.output
    errors = result.stderr.splitlines()
    assert "warning: cs: warning record from initialize" in errors
    assert "error: me: error record from initialize (the run goes on)" in errors
    assert "discard: me: ending the simulation: t_end = 0.35 s reached" in errors
    assert not any("[log" in line or "info:" in line for line in errors)
    assert result.stdout.strip().endswith(
        "ended early: me terminated the simulation at t = 0.35 s (ending the simulation: t_end = 0.35 s reached)")
    written = columns(scenario.parent / "out" / "chatty.csv")
    assert written["time"][-1] == pytest.approx(0.35, abs=1e-12)
    assert written["me.y"][-1] == pytest.approx(math.exp(-0.35), rel=1e-4)  # fmpy's CVODE in the master


def test_run_verbose_shows_every_category_and_quiet_none(scenario):
    verbose = CliRunner().invoke(main, ["run", str(scenario), "-v"])
    assert verbose.exit_code == 0, verbose.output
    errors = verbose.stderr.splitlines()
    assert "info: cs: [logComponent] debug record from initialize" in errors
    assert "info: me: [logComponent] info record: T = 1 s" in errors
    assert any(line.startswith("info: cs: [logSolver] CVODE (bdf) from t = 0.0:") for line in errors)
    assert any(line.startswith("info: me: [logEvents] event at t = 0.35") for line in errors)
    quiet = CliRunner().invoke(main, ["run", str(scenario), "-q"])
    assert quiet.exit_code == 0 and quiet.output == ""
    both = CliRunner().invoke(main, ["run", str(scenario), "-q", "-v"])
    assert both.exit_code == 2 and "-q and -v contradict each other" in both.output


def test_restoring_a_state_from_before_the_end_lets_co_simulation_go_on(unzipped):
    from fmpy.fmi1 import FMICallException
    from fmpy.fmi2 import FMU2Slave, fmi2LastSuccessfulTime, fmi2Terminated

    from deltafmi.master.stepping.unit_base import logger_callbacks

    directory, guid = unzipped
    said: list = []
    callbacks = logger_callbacks(lambda status, category, text: said.append((status, category, text)))
    fmu = FMU2Slave(guid=guid, unzipDirectory=str(directory), modelIdentifier="Chatty", instanceName="rollback")
    fmu.instantiate(callbacks=callbacks)
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        fmu.doStep(0.0, 0.5)
        saved = fmu.getFMUstate()
        with pytest.raises(FMICallException) as failed:
            fmu.doStep(0.5, 0.1)
        assert failed.value.status == 2 and fmu.getBooleanStatus(fmi2Terminated)
        assert fmu.getRealStatus(fmi2LastSuccessfulTime) == T_END
        fmu.setFMUstate(saved)  # back to t = 0.5, before the end: a shorter step goes through
        assert not fmu.getBooleanStatus(fmi2Terminated)
        fmu.doStep(0.5, 0.04)
        assert fmu.getRealStatus(fmi2LastSuccessfulTime) == pytest.approx(0.54, abs=1e-15)
        assert fmu.getReal([4])[0] == pytest.approx(math.exp(-0.54), rel=1e-6)
        fmu.freeFMUstate(saved)
    finally:
        fmu.terminate()
        fmu.freeInstance()
    assert [text for status, _, text in said if status == 2] == [REASON]


@pytest.mark.parametrize("name, level, expected", [
    ("deltafmi.solver", logging.INFO, (0, "logSolver", "deltafmi.solver: CVODE says")),
    ("deltafmi.solver", logging.WARNING, (1, "logStatusWarning", "deltafmi.solver: CVODE says")),
    ("_deltafmi_fmu_Plant_0123456789ab", logging.DEBUG, (0, "logComponent", "CVODE says")),
    ("root", logging.CRITICAL, (3, "logStatusError", "CVODE says")),
])
def test_records_map_to_status_and_category(name, level, expected):
    record = logging.LogRecord(name, level, __file__, 1, "CVODE %s", ("says",), None)
    assert message(record) == expected


def test_a_component_that_steps_itself_ends_at_the_end_of_its_step(c_host, tmp_path):
    fmu = build_fmu(COMPONENT.parents[1] / "stopper" / "model.py", tmp_path / "Stopper.fmu")
    directory = unzip(fmu, tmp_path / "stopper")
    guid = ET.parse(directory / "modelDescription.xml").getroot().get("guid")
    run = subprocess.run([str(c_host), str(directory), "Stopper", guid, "cs", "1.0", "0.1"], capture_output=True,
                         text=True, env=clean_env(), timeout=600)
    assert run.returncode == 0, run.stderr
    lines = run.stdout.splitlines()  # rows of t only (no variables asked), then the end
    assert [float(t) for t in lines[:-1]] == pytest.approx([0.0, 0.1, 0.2, 0.3], abs=1e-15)
    assert lines[-1].startswith("terminated,") and float(lines[-1].split(",")[1]) == pytest.approx(0.3, abs=1e-15)
    assert run.stderr.splitlines() == ["[host|2|logStatusDiscard] ending the simulation: 3 steps taken"]
