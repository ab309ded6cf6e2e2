"""Native builds: the compiler's own messages on failure, one clear line without a compiler, the
prebuilt layer found before anything is compiled, and the first-build progress line.

Real compiles with the system C compiler (gcc); "no compiler" is ``CC`` naming a program that
does not exist, which is what deltafmi runs.
"""
from __future__ import annotations

import ctypes
import logging
import sys
from pathlib import Path

import pytest

from deltafmi import toolchain
from deltafmi.builder import packager
from deltafmi.shipped import MODELS_DIR
from deltafmi.toolchain import BuildError, NoCompilerError, plain_c_library

MODELS = MODELS_DIR


@pytest.fixture
def fresh_cache(tmp_path, monkeypatch):
    cache = tmp_path / "cache"
    monkeypatch.setenv("DELTAFMI_CACHE", str(cache))
    monkeypatch.setattr(toolchain, "PREBUILT_DIR", tmp_path / "no-prebuilt")
    return cache


def test_a_failing_compile_shows_the_compilers_own_error_first(tmp_path, fresh_cache):
    source = tmp_path / "broken.c"
    source.write_text("int answer(void) { return undeclared_thing; }\n")
    with pytest.raises(BuildError) as caught:
        plain_c_library(source)
    lines = str(caught.value).splitlines()
    assert lines[0].startswith(f"{source}: compiling failed (cc exited with 1)")
    # gcc's diagnostic, file:line:column: error: ..., before the command line
    error = next(i for i, line in enumerate(lines) if "error:" in line and "undeclared_thing" in line)
    assert lines[error].startswith(f"{source}:1:")
    command = next(i for i, line in enumerate(lines) if line.startswith("$ cc "))
    assert error < command == len(lines) - 1
    assert not list(fresh_cache.rglob("*.so"))


def test_a_long_compiler_output_is_trimmed_to_its_first_lines(tmp_path, fresh_cache):
    source = tmp_path / "many_errors.c"
    source.write_text("".join(f"int f{i}(void) {{ return missing_{i}; }}\n" for i in range(60)))
    with pytest.raises(BuildError) as caught:
        plain_c_library(source)
    text = str(caught.value)
    assert "missing_0" in text and "missing_59" not in text
    assert len(text.splitlines()) <= toolchain._MAX_OUTPUT_LINES + 3
    assert "more lines)" in text


def test_without_a_compiler_one_line_says_a_compiler_is_needed(tmp_path, fresh_cache, monkeypatch):
    monkeypatch.setenv("CC", str(tmp_path / "bin" / "cc"))
    source = tmp_path / "fine.c"
    source.write_text("int answer(void) { return 42; }\n")
    with pytest.raises(NoCompilerError) as caught:
        plain_c_library(source)
    message = str(caught.value)
    assert message == (f"{source}: building needs a C compiler ({tmp_path / 'bin' / 'cc'} not found; install gcc "
                       "or set CC); the packaged models need none when deltafmi is installed from its wheel, "
                       "which carries them prebuilt")


def test_an_fmu_build_without_compiler_names_the_component_and_warns_nothing(fresh_cache, monkeypatch, recwarn):
    monkeypatch.setenv("CC", "deltafmi-no-such-compiler")
    source = MODELS / "bouncing_ball.py"
    with pytest.raises(NoCompilerError) as caught:
        packager.build_cached(source)
    assert str(caught.value).startswith(f"{source}: building needs a C compiler (deltafmi-no-such-compiler not "
                                        "found; install gcc or set CC)")
    assert "\n" not in str(caught.value)
    assert not recwarn.list  # no "ships plain Python kernels" noise before the error
    assert not fresh_cache.exists() or not list(fresh_cache.rglob("*.fmu"))


def test_the_prebuilt_layer_serves_without_compiler_and_the_user_cache_comes_first(tmp_path, monkeypatch):
    source = tmp_path / "answer.c"
    source.write_text('__attribute__((visibility("default"))) int answer(void) { return 42; }\n')
    monkeypatch.setattr(toolchain, "PREBUILT_DIR", tmp_path / "prebuilt")
    monkeypatch.setenv("DELTAFMI_CACHE", str(tmp_path / "prebuilt"))  # "the wheel build" compiles into it
    built = plain_c_library(source)
    relative = built.relative_to(tmp_path / "prebuilt")

    monkeypatch.setenv("DELTAFMI_CACHE", str(tmp_path / "user"))
    monkeypatch.setenv("CC", str(tmp_path / "nothing"))
    found = plain_c_library(source)
    assert found == tmp_path / "prebuilt" / relative
    assert ctypes.CDLL(str(found)).answer() == 42
    assert not (tmp_path / "user").exists()  # nothing copied or compiled

    (tmp_path / "user" / relative).parent.mkdir(parents=True)
    (tmp_path / "user" / relative).write_bytes(found.read_bytes())
    assert plain_c_library(source) == tmp_path / "user" / relative


def test_the_compiled_kernels_key_ignores_the_python_build(monkeypatch):
    """A model's compiled kernels are plain C (no Python headers): built for one CPython build,
    they serve another; their key is the generated source."""
    from deltafmi.builder.codegen.component_kernels import component_library
    from deltafmi.models import DeltaRobot

    built = component_library(DeltaRobot)
    monkeypatch.setattr(sys, "version", "3.x.y (other build, other compiler)")
    again = component_library(DeltaRobot)
    assert again.library == built.library and again.source == built.source


def test_a_first_build_says_so_in_one_line_and_a_cached_one_is_silent(tmp_path, monkeypatch, capfd, caplog):
    """`deltafmi run` shows one line per FMU it builds, none for a cached one, none with -q; the
    API logs them (INFO, logger deltafmi.build) and prints nothing."""
    from click.testing import CliRunner

    import deltafmi
    from deltafmi.apps.cli import main

    # the shared cache's compiled pieces serve as the prebuilt layer; FMUs go to a fresh cache
    monkeypatch.setattr(toolchain, "PREBUILT_DIR", toolchain.cache_dir())
    monkeypatch.setenv("DELTAFMI_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("HOME", str(tmp_path))
    monkeypatch.chdir(tmp_path)
    first = CliRunner().invoke(main, ["run", "bouncing_ball", "--stop", "0.01"])
    assert first.exit_code == 0, first.output
    assert [line for line in first.output.splitlines() if line.startswith("building")] == [
        f"building {model} FMU (cached afterwards in ~/cache/fmus) ..." for model in ("BouncingBall", "BouncingBallRestitution")]
    again = CliRunner().invoke(main, ["run", "bouncing_ball", "--stop", "0.01"])
    assert again.exit_code == 0 and "building" not in again.output

    monkeypatch.setenv("DELTAFMI_CACHE", str(tmp_path / "quiet"))
    quiet = CliRunner().invoke(main, ["run", "bouncing_ball", "--stop", "0.01", "-q"])
    assert quiet.exit_code == 0 and quiet.output == ""

    # a Python process that never ran a command: the messages go to logging only
    monkeypatch.setattr(packager.BUILD_LOG, "handlers", [])
    monkeypatch.setattr(packager.BUILD_LOG, "propagate", True)
    monkeypatch.setenv("DELTAFMI_CACHE", str(tmp_path / "api"))
    capfd.readouterr()
    caplog.clear()
    with caplog.at_level(logging.INFO, logger="deltafmi.build"):
        deltafmi.simulate("bouncing_ball", stop=0.01)
    assert capfd.readouterr() == ("", "")
    assert [r.getMessage() for r in caplog.records if r.name == "deltafmi.build"] == [
        f"building {model} FMU (cached afterwards in ~/api/fmus) ..." for model in ("BouncingBall", "BouncingBallRestitution")]


def test_the_fmu_cache_key_is_the_environments_not_the_interpreters_name():
    """A venv's bin/python and bin/python3 (the console scripts' shebang) are one environment: the
    API and the CLI share the cached FMUs."""
    import subprocess

    code = ("from pathlib import Path; from deltafmi.builder.packager import content_key; "
            f"print(content_key(Path({str(MODELS / 'oscillator.py')!r})))")
    keys = set()
    for name in ("python", "python3"):
        interpreter = Path(sys.prefix) / "bin" / name
        if interpreter.exists():
            keys.add(subprocess.run([str(interpreter), "-c", code], capture_output=True, text=True, check=True).stdout)
    assert len(keys) == 1
