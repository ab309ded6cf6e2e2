"""The initialization's connections copied by a plan made once per list of links
(:class:`~deltafmi.master.stepping.initial_links._CopyPlan`) make exactly the FMI calls, with the
same arguments, that the copy worked out as it goes makes, on real FMUs; a kept plan used again
(a study's next case) makes them again, with the values of its own run."""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from deltafmi import resolve_system
from deltafmi.master.scenario.spec import load_scenario
from deltafmi.master.stepping import initial_links
from deltafmi.master.stepping.master import Master
from deltafmi.master.stepping.unit_base import Unit

ROOT = Path(__file__).resolve().parents[2]

CHAIN = """\
experiment: {stop: 0.1, step: 1.0e-3}
components:
  a: {source: fmu_src/oscillator.py, interface: CS, parameters: {x: 0.3}}
  b: {source: fmu_src/oscillator.py, interface: CS}
  c: {source: fmu_src/oscillator.py, interface: CS}
  d: {source: fmu_src/oscillator.py, interface: CS}
connections:
  - {from: a.energy, to: b.F, factor: 0.05, offset: 0.25}
  - {from: a.energy, to: c.F, factor: -3.0}
  - {from: b.energy, to: d.F, factor: 2.0}
outputs: [a.energy, b.energy, c.energy, d.energy, b.F, c.F]
"""


def _system(tmp_path: Path, text: str):
    path = tmp_path / "s.yaml"
    path.write_text(text)
    return resolve_system(load_scenario(path))


def _calls(system, tmp_path: Path, copy, monkeypatch, start_value=None) -> list:
    """The FMI calls (function, arguments) of ``copy(links, by_name)`` on a master brought to
    initialization mode."""
    master = Master(system, result=tmp_path / "unused.csv")
    made: list = []
    try:
        master._load()
        for unit in master.units:
            unit.instantiate(master.start, master.stop)
            unit.apply_start_values()
        master._wire()
        for unit in master.units:
            unit.enter_initialization()
        if start_value is not None:
            name, vr, value = start_value
            master._by_name[name].fmu.setReal([vr], [value])
        original = Unit.call

        def spy(unit, function, *args, **kwargs):
            result = original(unit, function, *args, **kwargs)
            made.append((unit.name, function.__name__, [list(a) if isinstance(a, (list, tuple)) else a for a in args],
                         result if isinstance(result, (list, type(None), int)) else list(result)))
            return result

        monkeypatch.setattr(Unit, "call", spy)
        copy(system.init_links, master._by_name)
        monkeypatch.setattr(Unit, "call", original)
    finally:
        master.close()
    return made


@pytest.mark.parametrize("text", ["flagship", CHAIN])
def test_planned_copy_makes_the_calls_of_the_copy_as_it_goes(tmp_path, monkeypatch, text):
    text = (ROOT / "scenarios" / "delta_tracking.yaml").read_text() if text == "flagship" else text
    system = _system(tmp_path, textwrap.dedent(text))
    assert len(system.init_links) >= 3
    reference = _calls(system, tmp_path, initial_links._copy_one_by_one, monkeypatch)
    planned = _calls(system, tmp_path, initial_links.copy_initial_links, monkeypatch)
    assert reference and planned == reference
    assert any(name.startswith("set") for _, name, _, _ in reference)
    # the kept plan, used again, makes the calls with this run's values
    kept = initial_links._CopyPlan._kept[id(system.init_links)][2]
    if text is CHAIN:
        a = next(c for c in system.components if c.name == "a")
        changed = ("a", next(v.valueReference for v in a.info.md.modelVariables if v.name == "x"), 0.75)
        again = _calls(system, tmp_path, initial_links.copy_initial_links, monkeypatch, changed)
        assert initial_links._CopyPlan._kept[id(system.init_links)][2] is kept
        assert again == _calls(system, tmp_path, initial_links._copy_one_by_one, monkeypatch, changed)
        assert again != planned  # other values read and set
