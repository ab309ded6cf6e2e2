"""Write the insertion MPC's model: the scenario's impedance loop, linearized.

``python -m deltafmi.apps.insertion_mpc_model SCENARIO -o NAME`` takes a scenario with an
InsertionMpc (``mpc``) driving an AssemblyController (``controller``, program = false) on a
plant (``plant``), keeps the controller and the plant only (the loop the MPC predicts; its
other components are dropped), starts the controller's reference at the MPC's ``start`` and
linearizes it as ``deltafmi linearize LOOP --at 0.02 -u controller.r -u controller.rd -u
controller.rdd -y plant.tip -y plant.tip_velocity -o NAME`` does (writes NAME.npz and NAME.mat). The tip starts at
rest on the reference, in free space: the operating point is an equilibrium, and the
feedback-linearized loop is linear, so the model holds along the whole approach. At 20 ms, not
0: at the start the controller has not sampled yet and the loop is open (the linearization
then has the robot's undamped poles on the unit circle and no controller states).
"""
from __future__ import annotations

import argparse
import tempfile
from pathlib import Path
from typing import Sequence

import yaml

__all__ = ["keep_components", "write_model"]

LOOP = ("controller", "plant")


def keep_components(scenario: dict, names: Sequence[str]) -> dict:
    """A copy of the scenario (as read from YAML) with only the components ``names``, the
    connections between them and the outputs of theirs."""
    spec = dict(scenario)
    missing = [name for name in names if name not in spec.get("components", {})]
    if missing:
        raise ValueError(f"the scenario has no component(s) {', '.join(missing)}")
    spec["components"] = {name: spec["components"][name] for name in names}
    spec["connections"] = [c for c in spec.get("connections", [])
                           if c["from"].split(".")[0] in names and c["to"].split(".")[0] in names]
    spec["outputs"] = [o for o in spec.get("outputs", []) if o.split(".")[0] in names]
    return spec


def loop_scenario(scenario: dict, mpc: str = "mpc") -> dict:
    """The scenario's controller and plant alone, the controller following its reference inputs."""
    if mpc not in scenario.get("components", {}):
        raise ValueError(f"the scenario has no component {mpc}")
    start = scenario["components"][mpc].get("parameters", {}).get("start", [0.0, 0.0, -1.17])
    spec = keep_components(scenario, LOOP)
    controller = dict(spec["components"]["controller"])
    controller["parameters"] = dict(controller.get("parameters", {}), program=False, r=list(start),
                                    rd=[0.0] * 3, rdd=[0.0] * 3)
    spec["components"]["controller"] = controller
    spec["outputs"] = ["plant.tip[*]"]
    spec["experiment"] = dict(spec["experiment"], stop=0.05)
    return spec


#: the loop's inputs and outputs the MPC predicts with
INPUTS = ("controller.r", "controller.rd", "controller.rdd")
OUTPUTS = ("plant.tip", "plant.tip_velocity")


def write_model(scenario: Path, base: Path) -> Path:
    """Linearize ``scenario``'s loop into ``base``.npz (and .mat); returns the .npz."""
    from deltafmi import linearize_scenario, resolve_system
    from deltafmi.master.linearize.closed_loop import expand_references
    from deltafmi.master.scenario.spec import load_scenario

    with tempfile.TemporaryDirectory() as folder:
        loop = Path(folder) / "insertion_loop.yaml"
        loop.write_text(yaml.safe_dump(loop_scenario(yaml.safe_load(scenario.read_text()))))
        system = resolve_system(load_scenario(loop))
        components = {c.name: c for c in system.components}
        model = linearize_scenario(loop, at=0.02, inputs=expand_references(components, INPUTS),
                                   outputs=expand_references(components, OUTPUTS), system=system)
    return next(path for path in model.save(base) if path.suffix == ".npz")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenario", help="scenario .yaml (or a shipped example's name)")
    parser.add_argument("-o", "--output", default="peg_in_hole_mpc_model", help="base name of the files")
    args = parser.parse_args()
    path = Path(args.scenario)
    if not path.is_file():
        from deltafmi.shipped import find_input
        path = find_input(args.scenario, "scenario")
    print(f"wrote {write_model(path, Path(args.output))}")


if __name__ == "__main__":
    main()
