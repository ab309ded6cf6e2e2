"""CLI commands of the co-simulation master (being written)."""
import click


@click.command()
def run() -> None:
    """Run a scenario (not yet implemented)."""
    raise click.ClickException("not implemented yet")


validate = click.command(name="validate")(lambda: None)
plot = click.command(name="plot")(lambda: None)
