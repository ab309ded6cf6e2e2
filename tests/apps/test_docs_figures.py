"""benchmarks/docs_figures.py, the list of where every figure of the assembly and robot-contact
docs comes from, still quotes what the docs say: a figure changed in a doc without the list (or the
other way round) fails here, and every row names a source that exists."""
from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
import docs_figures  # noqa: E402

KINDS = {"printed", "asserted", "parameter", "derived", "owned", "historical"}


def test_every_listed_figure_is_quoted_where_the_list_says():
    assert [f"{f.file}: {f.text!r}" for f in docs_figures.missing()] == []


def test_every_row_names_its_kind_and_a_source_file_that_exists():
    wrong = []
    for figure in docs_figures.FIGURES:
        named = figure.source.split("::")[0].split(" ")[0]
        if figure.kind not in KINDS:
            wrong.append(f"{figure.text!r}: kind {figure.kind!r}")
        elif figure.kind in {"printed", "asserted"} and "/" in named and not (ROOT / named).is_file():
            wrong.append(f"{figure.text!r}: no file {named}")
        elif "::" in figure.source and named.startswith("tests/"):
            name = re.match(r"\w+", figure.source.split("::")[1]).group()
            if name not in (ROOT / named).read_text():
                wrong.append(f"{figure.text!r}: {named} has no {name}")
    assert wrong == []


def test_a_changed_figure_is_reported(tmp_path, monkeypatch):
    doc = tmp_path / "doc.md"
    doc.write_text("the peg is 9.2 mm\nbelow the top\n")
    monkeypatch.setattr(docs_figures, "ROOT", tmp_path)
    kept = docs_figures.Figure("doc.md", "9.2 mm below the top", "printed", "x")
    changed = docs_figures.Figure("doc.md", "9.3 mm below the top", "printed", "x")
    assert docs_figures.missing([kept, changed]) == [changed]


def test_the_insertion_model_has_the_documented_size():
    """docs/assembly.md, section 7: the insertion MPC's model, the loop impedance + robot, has 36
    states, of which the MPC keeps 6 (its stage: tip, tip velocity and the reference's position and
    velocity along the hole's three axes, reduced; asserted in tests/models/test_insertion_mpc.py)."""
    from deltafmi.physics.control.model_file import LinearModelFile
    model = LinearModelFile.read(str(ROOT / "scenarios" / "peg_in_hole_mpc_model.npz"))
    assert model.A.shape == (36, 36)
