"""The peg-in-hole insertion succeeding and failing where the geometry says it must, measured by
the real study machinery (``deltafmi sweep`` on a Dask LocalCluster, the peg_in_hole scenario's
FMUs, the metrics of scenarios/studies/peg_robustness.yaml).

The chamfer (width w = 2 mm, 45 deg) centres the peg when its rim lands on it: a rigidly held peg
(wrist stiffness 500 N m/rad) offset by d from the hole is captured for d < w + c (c = 0.1 mm the
radial clearance; the edges' 0.2 mm fillets add at most 0.2 tan(22.5 deg) = 0.08 mm), and beyond
it lands on the flat top, whose normal has no lateral part: it stays there. The compliant wrist
(1 N m/rad about the tip, the scenario's) also tilts in from d = 2.5 mm, the push on the flat's
edge turning the peg about its tip, but not from 3.5 mm, where the tilted peg's face still rests
on the top. An unobstructed insertion reaches the 20 mm target when the program does:
approach_time + (approach_height + entry_depth) / entry_speed + (target - entry_depth) /
insertion_speed = 0.5 + 14 mm / 10 mm/s + 16 mm / 20 mm/s = 2.7 s (the reference carries its own
velocity, so the critically damped impedance tracks it without lag), later only by the bore's
friction drag F_f, which holds the tip F_f / K_ax behind the reference (K_ax = 1500 N/m: 13 ms
per newton at 20 mm/s; 30 ms allows 2 N, mu 0.3 on the ~7 N of the contacts that align the peg).
"""
from __future__ import annotations

import math
from pathlib import Path

import pyarrow.parquet as pq
import pytest
from click.testing import CliRunner

from deltafmi.apps.cli import main
from deltafmi.physics.assembly import PHASE_DESCENT, make_program, reference
from deltafmi.physics.assembly.rotation import TOOL_DOWN
from deltafmi.apps.studies.driver import dask_client

ROOT = Path(__file__).resolve().parents[2]
STIFF, SOFT = 500.0, 1.0   # N m/rad: a rigidly held peg; the scenario's compliant wrist
STUDY = f"""\
scenario: {ROOT / 'scenarios' / 'peg_in_hole.yaml'}
vary:
  zip:                                     # the TRUE hole d along x; the nominal one at the origin
    plant.hole_position[1]: [0.001, 0.0015, 0.0025, 0.0025, 0.0035]
    plant.hole_position[2]: [0.0, 0.0, 0.0, 0.0, 0.0]   # (the scenario's hole is 1 mm off in y
    plant.hole_tilt[1]: [0.0, 0.0, 0.0, 0.0, 0.0]       #  and tilted 1 degree: here it is upright)
    controller.rot_stiffness[1]: [{SOFT}, {STIFF}, {STIFF}, {SOFT}, {SOFT}]
    controller.rot_stiffness[2]: [{SOFT}, {STIFF}, {STIFF}, {SOFT}, {SOFT}]
    controller.rot_stiffness[3]: [{SOFT}, {STIFF}, {STIFF}, {SOFT}, {SOFT}]
    controller.inertia[1]: [0.02, 0.05, 0.05, 0.02, 0.02]
    controller.inertia[2]: [0.02, 0.05, 0.05, 0.02, 0.02]
    controller.inertia[3]: [0.02, 0.05, 0.05, 0.02, 0.02]
metrics:
  success: {{signal: plant.success, statistic: final}}
  insertion_time: {{signal: plant.depth, statistic: first_crossing, level: 0.02, direction: rising}}
  peak_force: {{signal: plant.contact_force, statistic: max}}
  final_depth: {{signal: plant.depth, statistic: final}}
"""


@pytest.fixture(scope="module")
def rows(tmp_path_factory) -> list:
    folder = tmp_path_factory.mktemp("peg_study")
    study = folder / "peg.yaml"
    study.write_text(STUDY)
    with dask_client(workers=2) as client:
        result = CliRunner().invoke(main, ["sweep", str(study), "--scheduler", client.scheduler.address,
                                           "-o", str(folder / "peg.parquet")])
    assert result.exit_code == 0, result.output
    table = pq.read_table(folder / "peg.parquet").to_pylist()
    assert [r["status"] for r in table] == ["ok"] * 5, [r["error"] for r in table]
    return table


def test_inside_the_chamfer_the_peg_goes_in_on_the_programs_schedule(rows):
    soft, stiff = rows[0], rows[1]
    for row in (soft, stiff):
        assert row["success"] == 1
        assert 2.7 - 1e-3 <= row["insertion_time"] <= 2.7 + 0.03, row
        # quasi-static ceiling: the push bound (20 N) plus the axial damping at the speed in the
        # bore, D v = 2 sqrt(K_ax M_ax) v = 2 sqrt(1500 * 10) * 0.02 = 4.9 N; the slow entry keeps
        # the first contact's impact below it
        assert row["peak_force"] <= 20.0 + 4.9, row


def test_past_the_chamfer_a_rigid_peg_stays_on_top_and_a_compliant_one_tilts_in(rows):
    rigid, compliant, far = rows[2], rows[3], rows[4]
    assert rigid["success"] == 0 and math.isnan(rigid["insertion_time"])
    assert abs(rigid["final_depth"]) < 5e-4, rigid       # on the top plane (penalty give < 0.5 mm)
    assert compliant["success"] == 1, compliant
    assert far["success"] == 0 and far["final_depth"] < 2e-3, far   # not past the chamfer's 2 mm


def test_the_program_enters_slowly_and_inserts_fast():
    # the descent's closed form: depth = -h + v_e s down to entry_depth (s = tau - approach_time),
    # then entry_depth + v (s - s_e) with s_e = (entry_depth + h) / v_e; continuous at s_e
    h, v_e, d_e, v = 0.01, 0.01, 0.004, 0.02
    prog = make_program((0.0, 0.0, -1.2), (0.0, 0.0), approach_height=h, approach_time=0.5, insertion_speed=v,
                        final_depth=0.035, push_force=20.0, axial_stiffness=1500.0, entry_speed=v_e, entry_depth=d_e)
    start, rot = (0.0, 0.0, -1.17), TOOL_DOWN
    far = (0.0, 0.0, -1.3)   # a tip far below the reference: the push bound stays out of the way
    s_e = (d_e + h) / v_e
    for s in (0.0, 0.3, s_e - 1e-6, s_e, s_e + 0.2, s_e + 0.7):
        ref = reference(prog, 0.5 + s, far, start, rot)
        slow = s < s_e
        expected = -h + v_e * s if slow else d_e + v * (s - s_e)
        assert ref.depth == pytest.approx(expected, abs=1e-12) and ref.phase == PHASE_DESCENT
        assert ref.rd[2] == pytest.approx(-(v_e if slow else v), abs=1e-15)   # down the (upright) axis
    # one speed throughout when entry_speed is not given: the program as before
    single = make_program((0.0, 0.0, -1.2), (0.0, 0.0), approach_height=h, insertion_speed=v, entry_depth=d_e)
    assert reference(single, 0.5 + 1.0, far, start, rot).depth == pytest.approx(-h + v * 1.0, abs=1e-12)
    with pytest.raises(ValueError, match="entry_speed must be > 0"):
        make_program((0.0, 0.0, -1.2), (0.0, 0.0), entry_speed=0.0)
