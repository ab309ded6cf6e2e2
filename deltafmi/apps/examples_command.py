"""CLI command ``deltafmi examples``: list the shipped examples, copy one to edit."""
from __future__ import annotations

from pathlib import Path

import click

from deltafmi.apps.console import folder_output

__all__ = ["examples"]


@click.group(invoke_without_command=True)
@click.pass_context
def examples(context: click.Context) -> None:
    """The example scenarios and studies shipped with deltafmi.

    Without a subcommand, lists them. Run a scenario by name from any folder
    (`deltafmi run delta_tracking`), a study likewise (`deltafmi sweep gain_payload`); copy one
    to edit it (`deltafmi examples copy delta_tracking my_robot/`).
    """
    if context.invoked_subcommand is None:
        context.invoke(list_examples)


@examples.command("list")
def list_examples() -> None:
    """Name and one line of every example, and of every packaged model."""
    from deltafmi.shipped import examples as shipped
    from deltafmi.apps.examples import model_summaries

    found = shipped()
    models = model_summaries()
    width = max(len(name) for name in [e.name for e in found] + list(models))
    for kind, heading, command in (("scenario", "Scenarios", "deltafmi run NAME"),
                                   ("study", "Studies", "deltafmi sweep NAME")):
        click.echo(f"{heading} ({command}):")
        for e in found:
            if e.kind == kind:
                click.echo(f"  {e.name:<{width}}  {e.summary}")
    click.echo("Models (deltafmi build NAME; in a scenario, source: deltafmi.models:NAME):")
    for name, summary in models.items():
        click.echo(f"  {name:<{width}}  {summary}")


@examples.command("copy")
@click.argument("name")
@click.argument("directory", type=click.Path(file_okay=False, path_type=Path), callback=folder_output)
def copy(name: str, directory: Path) -> None:
    """Write example NAME and the component sources it uses into DIRECTORY, ready to edit.

    The copied YAML names the copied sources (models/*.py), so `deltafmi run DIRECTORY/NAME.yaml`
    builds and runs your edited components. The files its components carry in their FMUs
    (resources:, such as a controller's linear model) are copied beside it.
    """
    from deltafmi.shipped import example
    from deltafmi.apps.examples import copy_example

    chosen = example(name)
    written = copy_example(name, directory)
    for path in written:
        click.echo(f"wrote {path}")
    click.echo(f"run it: deltafmi {'sweep' if chosen.kind == 'study' else 'run'} {written[0]}")
