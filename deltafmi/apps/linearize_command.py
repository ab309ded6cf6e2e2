"""``deltafmi linearize``: A, B, C, D of an FMU, or Phi, Gamma, C, D of a scenario's closed loop."""
from __future__ import annotations

from pathlib import Path
from typing import Any, Dict, Optional, Sequence

import click

from deltafmi.errors import BadInput
from deltafmi.apps.console import output_folders

__all__ = ["linearize"]


def _value(text: str) -> Any:
    lowered = text.strip().lower()
    if lowered in ("true", "false"):
        return lowered == "true"
    try:
        return float(text)
    except ValueError:
        return text.strip()


def _assignments(items: Sequence[str], option: str) -> Dict[str, Any]:
    """``NAME=VALUE`` or ``NAME=V1,V2,V3`` (an array) -> {name: value or list}."""
    out: Dict[str, Any] = {}
    for item in items:
        name, sep, text = item.partition("=")
        if not sep or not name.strip() or not text.strip():
            raise BadInput(f"{option} {item!r}: expected NAME=VALUE (an array: NAME=1.0,2.0,3.0)")
        values = [_value(t) for t in text.split(",")]
        out[name.strip()] = values if len(values) > 1 else values[0]
    return out


@click.command()
@click.argument("target")
@click.option("-o", "--save", "save", type=click.Path(dir_okay=False), callback=output_folders,
              help="Base name of the .npz and .mat files written (default: <target>_linear next to it).")
@click.option("--at", "at", type=float,
              help="Time of the operating point [s]. FMU: 0 by default; scenario: a communication point "
                   "(default: the start), which the master runs to first.")
@click.option("-u", "--input", "inputs", multiple=True, metavar="NAME",
              help="Inputs of the linear model (repeatable; arrays by name). FMU: its Real inputs (default: "
                   "all continuous ones). Scenario: comp.input, a perturbation added to that input.")
@click.option("-y", "--output", "outputs", multiple=True, metavar="NAME",
              help="Outputs of the linear model (repeatable). FMU: its Real outputs (default: all continuous "
                   "ones). Scenario: comp.output.")
@click.option("--set", "sets", multiple=True, metavar="NAME=VALUE",
              help="FMU: a parameter or start value, set before initialization (arrays: NAME=1,2,3).")
@click.option("--state", "states", multiple=True, metavar="NAME=VALUE",
              help="FMU: a continuous state, set after initialization.")
@click.option("--rest", is_flag=True,
              help="FMU: move to an equilibrium first (every derivative zero), solving for the --free inputs.")
@click.option("--free", multiple=True, metavar="NAME",
              help="FMU: an input the equilibrium solves for (default: every continuous Real input).")
@click.option("--hold", multiple=True, metavar="NAME=VALUE",
              help="FMU: an output the equilibrium holds at VALUE; the states are solved for too (implies --rest).")
@click.option("-q", "--quiet", is_flag=True, help="Print no pole table.")
def linearize(target: str, save: Optional[str], at: Optional[float], inputs: Sequence[str],
              outputs: Sequence[str], sets: Sequence[str], states: Sequence[str], rest: bool, free: Sequence[str],
              hold: Sequence[str], quiet: bool) -> None:
    """Linearize TARGET: an FMU (.fmu, or a component source .py) or a scenario (.yaml, .ssp).

    \b
    An FMU (FMI 2.0 or 3.0) gives the continuous A, B, C, D at an operating point (its Model
    Exchange equations, differentiated by its directional derivatives). A scenario gives its
    closed loop at a communication point as the discrete map over one step: Phi, Gamma, C, D
    with Ts the step.
    Writes both as .npz and .mat with the state, input and output names, and prints the poles
    with their damping.

    \b
    Examples:
      deltafmi linearize DeltaRobot --set z0=0.1,-0.1,-0.9 --rest --free u -u u -y z
      deltafmi linearize delta_tracking --at 0.05 -u 'controller.r' -y 'plant.z'
    """
    from deltafmi.master.linearize.closed_loop import expand_references, linearize_scenario
    from deltafmi.master.linearize.fmu import linearize_fmu
    from deltafmi.master.scenario.fmu_scenario import is_fmu

    path, packaged = _target_path(target)
    if path.suffix in (".yaml", ".yml", ".ssp", ".ssd"):
        fmu_only = [name for name, given in (("--set", sets), ("--state", states), ("--rest", rest),
                                             ("--free", free), ("--hold", hold)) if given]
        if fmu_only:
            raise BadInput(f"{', '.join(fmu_only)}: only for an FMU; a scenario takes its values from its file")
        from deltafmi.apps.run_commands import load_system
        system = load_system(str(path))
        components = {c.name: c for c in system.components}
        model = linearize_scenario(path, at=at, inputs=expand_references(components, inputs),
                                   outputs=expand_references(components, outputs), system=system)
    else:
        fmu = path
        if path.suffix == ".py":
            from deltafmi.builder import build_cached
            fmu = build_cached(path, class_name=packaged)
        elif not is_fmu(path):
            raise BadInput(f"'{target}': expected an .fmu, a component .py or a scenario .yaml/.ssp")
        model = linearize_fmu(fmu, start_values=_assignments(sets, "--set"),
                              states=_assignments(states, "--state"), time=at or 0.0, rest=rest, free=free,
                              hold=_assignments(hold, "--hold"), inputs=inputs, outputs=outputs, label=target)
    kind = f"discrete, Ts = {model.sample_time:g} s" if model.discrete else "continuous"
    click.echo(f"{target} at t = {model.time:g} s: {len(model.states)} states, {len(model.inputs)} inputs, "
               f"{len(model.outputs)} outputs ({kind})")
    for note in model.notes:
        click.echo(f"  {note}")
    if not quiet:
        for line in model.pole_table():
            click.echo(line)
    from deltafmi.shipped import is_shipped
    # shipped examples and models live in the installed package: their results go here
    base = Path(save) if save else (Path() if is_shipped(path) else path.parent) / f"{path.stem}_linear"
    written = model.save(base)
    click.echo(f"wrote {', '.join(str(p) for p in written)}")


def _target_path(target: str) -> tuple[Path, Optional[str]]:
    """The file to linearize: ``target`` itself, a packaged model's source (with its class name)
    or a shipped example scenario."""
    path = Path(target)
    if path.is_file():
        return path, None
    from deltafmi.builder.sources import find_component, is_module_reference, packaged_model_names
    if target in packaged_model_names() or is_module_reference(target):
        source = find_component(target)
        return source.path, source.class_name
    if path.suffix or len(path.parts) > 1:
        raise BadInput(f"'{target}' not found")
    from deltafmi.errors import did_you_mean
    from deltafmi.shipped import examples, find_input
    if not any(e.name == target for e in examples()):  # a typo: the closest models and scenarios
        models = packaged_model_names()
        hint = did_you_mean(target, models + [e.name for e in examples() if e.kind == "scenario"]) or \
            f" (packaged models: {', '.join(models)}; `deltafmi examples` lists the scenarios)"
        raise BadInput(f"'{target}' is neither a file, a packaged model nor an example scenario{hint}")
    return find_input(target, "scenario"), None

