"""The guides (docs/*.md) where this installation has them, for ``deltafmi guides``.

A wheel carries them in ``deltafmi/docs/`` (setup.py copies them there with their figures); a
clone has them in ``docs/`` beside the package. The README's links name them relative to the
repository: this command tells a wheel user where they are.
"""
from __future__ import annotations

from pathlib import Path
from typing import Dict, Optional

import click

__all__ = ["guides_command"]

_PACKAGE = Path(__file__).parent


def guides_dir() -> Optional[Path]:
    """The folder of the guides: the wheel's copy, else a clone's ``docs/``; None without either."""
    for folder in (_PACKAGE / "docs", _PACKAGE.parent / "docs"):
        if (folder / "api.md").is_file():
            return folder
    return None


def guides() -> Dict[Path, str]:
    """Each guide's file -> its title (the first heading)."""
    folder = guides_dir()
    if folder is None:
        return {}
    return {path: path.read_text(encoding="utf-8").splitlines()[0].lstrip("# ").strip()
            for path in sorted(folder.glob("*.md"))}


@click.command("guides")
def guides_command() -> None:
    """Where the guides are (Markdown files: the Python API, writing a component, scenarios,
    studies, troubleshooting, ...), each with its title."""
    found = guides()
    if not found:
        raise click.ClickException("this installation has no guides (a wheel built without docs/?)")
    width = max(len(path.name) for path in found)
    for path, title in found.items():
        click.echo(f"{path.name:<{width}}  {title}")
    click.echo(f"in {next(iter(found)).parent}")
