"""Plot signals of a result over time with matplotlib (Agg backend: no display needed).

A signal is a recorded name, a pattern (``plant.z[*]``, ``trajectory.r[1:3]``, ``osc.*``), an
array's name (``plant.z``: its elements), or the difference of two of them with the same number
of elements, written with spaces around the minus as in a study's metrics:
``plant.z - trajectory.r`` (FMI names may contain ``-``, never `` - ``). With ``compare=`` the
signals of a second result are subtracted from the first's (on the first's time points).

Axes carry units from the result (``.parquet`` and ``.mat`` files and :class:`Result` objects
have them, ``.csv`` files do not): signals of different units get different axes, differences
get their own axis, and each axis scales its unit by an SI prefix so that its numbers are
readable (a tracking error in um under positions in m); an axis without a unit, or with one that
takes no prefix, says the power of ten in its label (``(×1e-6)``), never in an offset beside the
axis. An axis names what its curves show (``plant.z, trajectory.r [m]``).
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Collection, Dict, List, Optional, Sequence, Tuple

import numpy as np

from deltafmi.errors import BadInput, DeltaFmiError, did_you_mean

from ..scenario.modelinfo import split_element

if TYPE_CHECKING:
    from .result import Result

#: `` - `` between two signals: their difference
_DIFFERENCE = " - "
#: units an SI prefix may be put in front of (the prefix scales their first symbol)
_PREFIXABLE = re.compile(r"(m|rad|N|s|V|A|W|J|Pa|Hz)([./].*)?\Z")
_PREFIXES = ((1.0, ""), (1e-3, "m"), (1e-6, "u"), (1e-9, "n"))
_DASHES = ("-", "--", ":", "-.")
#: an axis shared by several curves names what they are while that stays short, else the legend does
_LABEL_NAMES, _LABEL_LENGTH = 3, 40


class UnknownSignal(DeltaFmiError, LookupError):
    """A requested signal (or pattern) matches no column; the message carries a suggestion."""

    exit_code = 2  # bad input


@dataclass
class Series:
    """One curve: its label, values, unit ("" unknown or none), whether it is a difference, and
    the quantity it shows (its label without element indices: ``plant.z - trajectory.r``)."""

    label: str
    values: np.ndarray
    unit: str
    difference: bool
    quantity: str = ""


def _quantity(name: str) -> str:
    element = split_element(name)
    return element[0] if element else name


def _known(result: Result, signal: str) -> bool:
    return bool(result.match(signal) or result.elements(signal))


def _columns_of(result: Result, signal: str, texts: Collection[str]) -> List[str]:
    """The numeric columns ``signal`` names: a name, a pattern, or an array's name (its elements)."""
    hits = result.match(signal) or result.elements(signal)
    numbers = [n for n in hits if n not in texts]
    if numbers:
        return numbers
    if hits == [signal]:
        raise UnknownSignal(f"'{signal}' is a String column: a plot draws numbers")
    if hits:
        raise UnknownSignal(f"'{signal}' matches only String columns ({', '.join(hits)}): a plot draws numbers")
    for at in [i for i, c in enumerate(signal) if c == "-"]:  # 'a-b' meant as a difference?
        left, right = signal[:at].strip(), signal[at + 1:].strip()
        if left and right and _known(result, left) and _known(result, right):
            raise UnknownSignal(f"no column '{signal}' in the result; a difference is written with spaces: "
                                f"'{left}{_DIFFERENCE}{right}'")
    raise UnknownSignal(f"no column '{signal}' in the result{did_you_mean(signal, ['time', *result.names])}")


def _texts(result: Result) -> set:
    return {name for name in result.names if result[name].dtype == object or result[name].dtype.kind in "US"}


def series_of(result: Result, signals: Sequence[str], compare: Optional[Result] = None,
              compare_name: str = "the compared result") -> List[Series]:
    """The curves of ``signals`` in ``result``; with ``compare``, each minus the same signal of
    ``compare`` (on ``result``'s times). An error about ``compare`` starts with ``compare_name``."""
    texts = _texts(result)
    found: List[Series] = []
    for signal in signals:
        left_text, sep, right_text = signal.partition(_DIFFERENCE)
        left = _columns_of(result, left_text.strip(), texts)
        if not sep:
            found.extend(Series(n, result[n].astype(float), result.units.get(n, ""), False, _quantity(n))
                         for n in left if not any(s.label == n and not s.difference for s in found))
            continue
        right = _columns_of(result, right_text.strip(), texts)
        if len(left) != len(right):
            raise UnknownSignal(f"'{signal}': {len(left)} signal(s) minus {len(right)}: "
                                "a difference needs the same number on both sides")
        for a, b in zip(left, right):
            unit_a, unit_b = result.units.get(a, ""), result.units.get(b, "")
            if unit_a and unit_b and unit_a != unit_b:
                raise UnknownSignal(f"'{a} - {b}': {a} is in {unit_a}, {b} in {unit_b}")
            found.append(Series(f"{a} - {b}", result[a].astype(float) - result[b].astype(float),
                                unit_a or unit_b, True, f"{_quantity(a)} - {_quantity(b)}"))
    if compare is None:
        return found
    try:
        other = series_of(compare, [s.label for s in found])
    except UnknownSignal as exc:
        raise UnknownSignal(f"{compare_name}: {exc}") from None
    return [replace(s, values=s.values - _on_times(compare.time, o.values, result.time), difference=True,
                    quantity=f"{s.quantity} difference")
            for s, o in zip(found, other)]


def _on_times(time: np.ndarray, values: np.ndarray, at: np.ndarray) -> np.ndarray:
    """``values`` sampled at ``time`` (events repeat a time) at the times ``at``: the same rows
    when the times agree, else linear interpolation."""
    if len(time) == len(at) and np.array_equal(time, at):
        return values
    return np.interp(at, time, values)


def _scale(unit: str, values: Sequence[np.ndarray]) -> Tuple[float, str]:
    """A factor and the axis's unit text, so that the largest magnitude reads between 0.1 and 100:
    an SI prefix for a unit that takes one (m -> mm, um, nm: `` [um]``), a power of ten after any
    other unit and without one (`` (×1e-6)``: a CSV result has no units)."""
    brackets = f" [{unit}]" if unit else ""
    finite = [np.max(np.abs(v[np.isfinite(v)])) for v in values if np.isfinite(v).any()]
    largest = max(finite, default=0.0)
    if largest == 0.0:
        return 1.0, brackets
    factor, prefix = next(((f, p) for f, p in _PREFIXES if largest >= 0.1 * f), _PREFIXES[-1])
    if factor == 1.0:
        return 1.0, brackets
    if unit and _PREFIXABLE.match(unit):
        return 1.0 / factor, f" [{prefix}{unit}]"
    return 1.0 / factor, f"{brackets} (×1e{round(math.log10(factor))})"


def _styles(members: Sequence[Series]) -> List[Dict[str, object]]:
    """Line styles: elements of several arrays on one axis (``plant.z[i]`` and ``trajectory.r[i]``)
    share a colour per index and a dash pattern per array, so each pair reads as one."""
    parts = [split_element(curve.label) for curve in members]
    bases = list(dict.fromkeys(p[0] for p in parts if p))
    if any(curve.difference for curve in members) or not all(parts) or len(bases) < 2 or len(bases) > len(_DASHES):
        return [{} for _ in members]
    indices = list(dict.fromkeys(p[1] for p in parts if p))
    return [{"color": f"C{indices.index(p[1]) % 10}", "linestyle": _DASHES[bases.index(p[0])]}
            for p in parts if p]


def _axis_label(unit: str, series: Sequence[Series]) -> str:
    """``plant.z[1] [m]`` for one curve; for several, the quantities they show while that is short
    (``plant.z, trajectory.r [m]``, ``plant.z - trajectory.r [um]``), else ``value [m]`` or
    ``difference [um]`` (the legend names the curves). ``unit``: the text :func:`_scale` gives."""
    if len(series) == 1:
        return series[0].label + unit
    quantities = list(dict.fromkeys(s.quantity or s.label for s in series))
    named = ", ".join(quantities)
    if len(quantities) > _LABEL_NAMES or len(named) > _LABEL_LENGTH:
        named = "difference" if all(s.difference for s in series) else "value"
    return named + unit


def checked_figure_file(output: str | Path) -> Path:
    """``output`` when matplotlib writes its format (by the extension), else BadInput listing them."""
    from matplotlib.backend_bases import FigureCanvasBase

    output = Path(output)
    formats = FigureCanvasBase.get_supported_filetypes()
    suffix = output.suffix.lower()
    if suffix[1:] not in formats:
        what = f"unknown format '{suffix}'" if suffix else "no extension"
        raise BadInput(f"figure file '{output}': {what}; use {', '.join('.' + f for f in formats)}")
    return output


def figure_of(first: "Result", signals: Sequence[str], separate: bool = False, title: str = "",
              other: "Optional[Result]" = None,
              names: Tuple[str, str, str] = ("result", "compared", "the compared result")) -> Any:
    """The matplotlib ``Figure`` of ``signals`` of the result ``first`` (minus ``other``'s, when
    given), made without pyplot: it leaves the caller's backend and figures alone. ``names``:
    what the title calls the result and the compared one, and what messages call the compared one."""
    from matplotlib.figure import Figure

    curves = series_of(first, signals, other, names[2])
    label = f"{names[0]} - {names[1]}" if other is not None else ""
    if label:
        curves = [replace(curve, label=f"{curve.label} ({label})") for curve in curves]
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
        ax.ticklabel_format(style="plain", useOffset=False)  # the scale is in the label, never beside the axis
        ax.grid(True, alpha=0.3)
        if len(members) > 1 or curve.difference and other is not None:
            ax.legend(loc="best", fontsize="small")
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle(title or label or names[0])
    fig.align_ylabels(axes[:, 0])
    fig.tight_layout()
    return fig


def save_figure(fig: Any, output: Path) -> Path:
    """Write ``fig`` to ``output`` (a :func:`checked_figure_file`)."""
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=120)
    return output


__all__ = ["checked_figure_file", "figure_of", "save_figure", "series_of", "Series", "UnknownSignal"]
