"""Plot signals of a result over time with matplotlib (Agg backend: no display needed).

A signal is a recorded name, a pattern (``plant.z[*]``, ``trajectory.r[1:3]``, ``osc.*``), an
array's name (``plant.z``: its elements), or the difference of two of them with the same number
of elements, written with spaces around the minus as in a study's metrics:
``plant.z - trajectory.r`` (FMI names may contain ``-``, never `` - ``). With ``compare=`` the
signals of a second result are subtracted from the first's (on the first's time points).

Axes carry units from the result (``.parquet`` and ``.mat`` files and :class:`Result` objects
have them, ``.csv`` files do not): signals of different units get different axes, differences
get their own axis, and each axis scales its unit by an SI prefix so that its numbers are
readable (a tracking error in um under positions in m).
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Collection, Dict, List, Optional, Sequence, Tuple

import numpy as np

from deltafmi.errors import did_you_mean

from ..scenario.resolve import pattern_regex
from .result import Result, read_result

#: `` - `` between two signals: their difference
_DIFFERENCE = " - "
#: units an SI prefix may be put in front of (the prefix scales their first symbol)
_PREFIXABLE = re.compile(r"(m|rad|N|s|V|A|W|J|Pa|Hz)([./].*)?\Z")
_PREFIXES = ((1.0, ""), (1e-3, "m"), (1e-6, "u"), (1e-9, "n"))
_ELEMENT = re.compile(r"(.*)\[(\d+)\]\Z")
_DASHES = ("-", "--", ":", "-.")


class UnknownSignal(LookupError):
    """A requested signal (or pattern) matches no column; the message carries a suggestion."""


@dataclass
class Series:
    """One curve: its label, values, unit ("" unknown or none) and whether it is a difference."""

    label: str
    values: np.ndarray
    unit: str
    difference: bool


def select_columns(names: Sequence[str], signals: Sequence[str], texts: Collection[str] = ()) -> List[str]:
    """Columns matching ``signals`` (exact names, ``*``/``?`` globs, ``[i:j]`` ranges, an array's
    name for its elements), in order; the ``texts`` columns (Strings) are left out, and a signal
    matching only those is an error."""
    chosen: List[str] = []
    for signal in signals:
        chosen.extend(h for h in _columns_of(names, signal, texts) if h not in chosen)
    return chosen


def _columns_of(names: Sequence[str], signal: str, texts: Collection[str]) -> List[str]:
    regex = pattern_regex(signal)
    hits = [n for n in names if n != "time" and regex.match(n)]
    if not hits:  # an array's name: its elements
        element = re.compile(re.escape(signal) + r"\[\d+\]\Z")
        hits = [n for n in names if element.match(n)]
    numbers = [n for n in hits if n not in texts]
    if not numbers:
        if hits == [signal]:
            raise UnknownSignal(f"'{signal}' is a String column: a plot draws numbers")
        if hits:
            raise UnknownSignal(f"'{signal}' matches only String columns ({', '.join(hits)}): a plot draws numbers")
        raise UnknownSignal(f"no column '{signal}' in the result{did_you_mean(signal, names)}")
    return numbers


def _texts(result: Result) -> set:
    return {name for name in result.names if result[name].dtype == object or result[name].dtype.kind in "US"}


def series_of(result: Result, signals: Sequence[str], compare: Optional[Result] = None,
              compare_label: str = "") -> List[Series]:
    """The curves of ``signals`` in ``result`` (minus those of ``compare`` when given)."""
    names, texts = ["time", *result.names], _texts(result)
    found: List[Series] = []
    for signal in signals:
        left_text, sep, right_text = signal.partition(_DIFFERENCE)
        left = _columns_of(names, left_text.strip(), texts)
        if not sep:
            found.extend(Series(n, result[n].astype(float), result.units.get(n, ""), False)
                         for n in left if not any(s.label == n and not s.difference for s in found))
            continue
        right = _columns_of(names, right_text.strip(), texts)
        if len(left) != len(right):
            raise UnknownSignal(f"'{signal}': {len(left)} signal(s) minus {len(right)}: "
                                "a difference needs the same number on both sides")
        for a, b in zip(left, right):
            unit_a, unit_b = result.units.get(a, ""), result.units.get(b, "")
            if unit_a and unit_b and unit_a != unit_b:
                raise UnknownSignal(f"'{a} - {b}': {a} is in {unit_a}, {b} in {unit_b}")
            found.append(Series(f"{a} - {b}", result[a].astype(float) - result[b].astype(float),
                                unit_a or unit_b, True))
    if compare is None:
        return found
    try:
        other = series_of(compare, [s.label for s in found])
    except UnknownSignal as exc:
        raise UnknownSignal(f"{compare_label or 'compared result'}: {exc}") from None
    return [Series(f"{s.label} ({compare_label})" if compare_label else s.label,
                   s.values - _on_times(compare.time, o.values, result.time), s.unit, True)
            for s, o in zip(found, other)]


def _on_times(time: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``values`` sampled at ``time`` (events repeat a time) at the times ``at``: the same rows
    when the times agree, else linear interpolation."""
    if len(time) == len(at) and np.array_equal(time, at):
        return values
    return np.interp(at, time, values)


def _scale(unit: str, values: Sequence[np.ndarray]) -> Tuple[float, str]:
    """A factor and the unit shown, so that the largest magnitude reads between 0.1 and 100
    (m -> mm, um, nm; a unit without SI prefixes, or an unknown one, stays)."""
    if not unit or not _PREFIXABLE.match(unit):
        return 1.0, unit
    finite = [np.max(np.abs(v[np.isfinite(v)])) for v in values if np.isfinite(v).any()]
    largest = max(finite, default=0.0)
    if largest == 0.0:
        return 1.0, unit
    for factor, prefix in _PREFIXES:
        if largest >= 0.1 * factor:
            return 1.0 / factor, prefix + unit
    return 1.0 / _PREFIXES[-1][0], _PREFIXES[-1][1] + unit


def _styles(members: Sequence[Series]) -> List[Dict[str, object]]:
    """Line styles: elements of several arrays on one axis (``plant.z[i]`` and ``trajectory.r[i]``)
    share a colour per index and a dash pattern per array, so each pair reads as one."""
    parts = [_ELEMENT.match(curve.label) for curve in members]
    bases = list(dict.fromkeys(p.group(1) for p in parts if p))
    if any(curve.difference for curve in members) or not all(parts) or len(bases) < 2 or len(bases) > len(_DASHES):
        return [{} for _ in members]
    indices = list(dict.fromkeys(int(p.group(2)) for p in parts if p))
    return [{"color": f"C{indices.index(int(p.group(2))) % 10}", "linestyle": _DASHES[bases.index(p.group(1))]}
            for p in parts if p]


def _axis_label(unit: str, series: Sequence[Series]) -> str:
    """``plant.z[1] [m]`` for one curve, ``[m]`` or ``difference [um]`` for several."""
    brackets = f" [{unit}]" if unit else ""
    if len(series) == 1:
        return series[0].label + brackets
    what = "difference" if all(s.difference for s in series) else ""
    return (what + brackets).strip()


def plot_result(result: str | Path | Result, signals: Sequence[str], output: str | Path,
                separate: bool = False, title: str = "", compare: str | Path | Result | None = None) -> Path:
    """Plot ``signals`` of ``result`` (a result file or a :class:`Result`) over time into
    ``output`` (png, pdf, svg); one axis per unit, differences on axes of their own
    (``separate``: one axis per curve). ``compare``: plot ``result - compare`` for each signal.
    Raises :class:`UnknownSignal` for a signal that is not there, :class:`~deltafmi.errors.BadInput`
    for a file that is no result."""
    fig = result_figure(result, signals, separate, title, compare)
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=120)
    return output


def result_figure(result: str | Path | Result, signals: Sequence[str], separate: bool = False, title: str = "",
                  compare: str | Path | Result | None = None) -> Any:
    """The matplotlib ``Figure`` :func:`plot_result` saves (made without pyplot: it leaves the
    caller's backend and figures alone)."""
    from matplotlib.figure import Figure

    first = result if isinstance(result, Result) else read_result(result)
    other = None
    label = ""
    if compare is not None:
        other = compare if isinstance(compare, Result) else read_result(compare)
        try:
            series_of(other, signals)
        except UnknownSignal as exc:
            raise UnknownSignal(f"{_name(compare, 'the compared result')}: {exc}") from None
        label = f"{_name(result, 'result')} - {_name(compare, 'compared')}"
    curves = series_of(first, signals, other, label)
    groups: Dict[object, List[Series]] = {}
    for i, curve in enumerate(curves):
        groups.setdefault(i if separate else (curve.unit, curve.difference), []).append(curve)
    rows = len(groups)
    fig = Figure(figsize=(8, 2.2 + 1.8 * rows))
    axes = fig.subplots(rows, 1, sharex=True, squeeze=False)
    time = first.time
    for ax, members in zip(axes[:, 0], groups.values()):
        factor, unit = _scale(members[0].unit, [m.values for m in members])
        for curve, style in zip(members, _styles(members)):
            ax.plot(time, curve.values * factor, label=curve.label, **style)
        ax.set_ylabel(_axis_label(unit, members))
        ax.grid(True, alpha=0.3)
        if len(members) > 1 or curve.difference and compare is not None:
            ax.legend(loc="best", fontsize="small")
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle(title or (label if compare is not None else _name(result, "result")))
    fig.align_ylabels(axes[:, 0])
    fig.tight_layout()
    return fig


def _name(result: str | Path | Result, default: str) -> str:
    return default if isinstance(result, Result) else Path(result).name


__all__ = ["plot_result", "result_figure", "select_columns", "series_of", "Series", "UnknownSignal"]
