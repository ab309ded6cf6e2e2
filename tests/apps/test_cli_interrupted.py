"""A signal whose KeyboardInterrupt Python swallows (raised in a ``__del__``, a callback from C:
"Exception ignored") still ends the command as interrupted, with 128 + the signal, not 0, and
without Python's "Exception ignored ... Traceback" on stderr."""
from __future__ import annotations

import os
import signal
import threading
import time

import click
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import _Commands


class _Group(_Commands):
    """deltafmi's group (its invoke: the signal handling) over these tests' own commands."""
    get_command = click.Group.get_command
    list_commands = click.Group.list_commands


class _Finalized:
    def __del__(self):  # the signal arrives here: Python prints "Exception ignored" and goes on
        os.kill(os.getpid(), self.signum)
        time.sleep(0.5)  # the handler runs in the sleep and raises KeyboardInterrupt, swallowed

    def __init__(self, signum: int) -> None:
        self.signum = signum


def _group(signum: int) -> click.Group:
    @click.group(cls=_Group)
    def group() -> None:
        pass

    @group.command()
    def work() -> None:
        _Finalized(signum)  # dropped at once: __del__ runs here
        click.echo("finished anyway")

    return group


@pytest.mark.skipif(threading.current_thread() is not threading.main_thread(), reason="signal handlers: main thread")
@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_swallowed_interrupt_still_ends_the_command_as_interrupted(signum):
    result = CliRunner().invoke(_group(signum), ["work"])
    assert result.exit_code == 128 + signum, result.output
    assert result.output.splitlines()[-1] == f"interrupted ({signal.Signals(signum).name})"
    assert "Traceback" not in result.output and "Exception ignored" not in result.output  # one line, no noise


def test_a_command_without_a_signal_exits_0():
    @click.group(cls=_Group)
    def group() -> None:
        pass

    @group.command()
    def work() -> None:
        click.echo("done")

    result = CliRunner().invoke(group, ["work"])
    assert result.exit_code == 0 and result.output == "done\n"
