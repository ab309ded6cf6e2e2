"""The shipped assembly scenarios held 30 s: the sampled impedance loop stays stable on the
contacts it meets (the wedged peg's included) and within the push bound of docs/assembly.md,
section 5: after the first touch the contact force on the peg stays below
push_force + D_ax v + K_lat d (the program's bounded push, the axial damping at the descent
speed v, the lateral spring over the hole's offset d from the nominal one)."""
from __future__ import annotations

import math

import numpy as np
import pytest

import deltafmi
from deltafmi.apps.studies.metrics import alternation
from deltafmi.apps.studies.spec import Window

HOLD = 30.0
WEDGE = {"plant.mu": 0.5, "plant.hole_tilt": [0.0524, 0.0], "controller.rot_stiffness": [500.0] * 3,
         "controller.inertia": [0.05] * 3}
# peg_in_hole.yaml's impedance and program: K_ax 1500 N/m, M_ax 10 kg (zeta 1), 20 N, 20 mm/s; the
# true hole 1.8 mm off the nominal, K_lat 300 N/m
PUSH, K_AX, M_AX, SPEED, K_LAT, OFFSET = 20.0, 1500.0, 10.0, 0.02, 300.0, math.hypot(0.0015, 0.001)
BOUND = PUSH + 2.0 * math.sqrt(K_AX * M_AX) * SPEED + K_LAT * OFFSET  # 25.4 N


def _held(scenario: str, plants: tuple[str, ...], parameters: dict) -> dict:
    res = deltafmi.simulate(scenario, stop=HOLD, parameters=parameters,
                            record=[f"{p}.contact_force[*]" for p in plants] + [f"{p}.depth" for p in plants])
    t = np.asarray(res["time"])
    found = {}
    for p in plants:
        force = np.column_stack([res[f"{p}.contact_force[{i}]"] for i in (1, 2, 3)])
        size = np.linalg.norm(force, axis=1)
        touch = t[int(np.argmax(size > 0.0))]
        found[p] = dict(t=t, size=size, touch=touch, depth=np.asarray(res[f"{p}.depth"]),
                        ringing=alternation(t, force, None, Window(touch, None)),
                        late_ringing=alternation(t, force, None, Window(HOLD - 10.0, None)))
    return found


@pytest.mark.parametrize("scenario, plants, parameters", [
    ("peg_in_hole", ("plant",), WEDGE),
    ("peg_in_hole", ("plant",), {}),
    ("peg_estimation", ("plant",), {}),
    ("peg_in_hole_mpc", ("plant", "impedance_plant"), {}),
], ids=["wedged", "peg_in_hole", "peg_estimation", "peg_in_hole_mpc"])
def test_assembly_scenarios_held_30_s_stay_stable_within_the_push_bound(scenario, plants, parameters):
    for name, run in _held(scenario, plants, parameters).items():
        after = run["t"] >= run["touch"]
        print(f"{scenario} {name}: touch {run['touch']:.3f} s, max |F| after it {run['size'][after].max():.2f} N "
              f"(bound {BOUND:.2f}), alternation {run['ringing']:.2e} N, last 10 s {run['late_ringing']:.2e} N, "
              f"depth at {HOLD:g} s {run['depth'][-1] * 1e3:.2f} mm")
        # no sustained step-to-step oscillation: the wedged loop's -67/+81 N swing read ~70 N here
        assert run["ringing"] < 0.01 and run["late_ringing"] < 1e-3
        assert run["size"][after].max() <= BOUND
