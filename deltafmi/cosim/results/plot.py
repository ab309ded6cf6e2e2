"""Plot columns of a result file with matplotlib (Agg backend: no display needed)."""
from __future__ import annotations

from pathlib import Path
from typing import Collection, List, Sequence

from deltafmi.errors import did_you_mean

from ..scenario.resolve import pattern_regex
from .csv_file import read_csv


class UnknownSignal(LookupError):
    """A requested signal (or pattern) matches no column; the message carries a suggestion."""


def select_columns(names: Sequence[str], signals: Sequence[str], texts: Collection[str] = ()) -> List[str]:
    """Columns matching ``signals`` (exact names, ``*``/``?`` globs, ``[i:j]`` ranges), in order;
    the ``texts`` columns (Strings) are left out, and a signal matching only those is an error."""
    chosen: List[str] = []
    for signal in signals:
        regex = pattern_regex(signal)
        hits = [n for n in names if n != "time" and regex.match(n)]
        numbers = [n for n in hits if n not in texts]
        if not numbers:
            if hits == [signal]:
                raise UnknownSignal(f"'{signal}' is a String column: a plot draws numbers")
            if hits:
                raise UnknownSignal(f"'{signal}' matches only String columns ({', '.join(hits)}): a plot draws numbers")
            raise UnknownSignal(f"no column '{signal}' in the result{did_you_mean(signal, names)}")
        chosen.extend(h for h in numbers if h not in chosen)
    return chosen


def plot_result(result: str | Path, signals: Sequence[str], output: str | Path,
                separate: bool = False, title: str = "") -> Path:
    """Plot ``signals`` of ``result`` over time into ``output`` (png, pdf, svg)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    names, data = read_csv(result)
    texts = {name for i, name in enumerate(names)
             if data.dtype == object and any(isinstance(value, str) for value in data[:, i])}
    chosen = select_columns(names, signals, texts)
    time = data[:, 0]
    rows = len(chosen) if separate else 1
    fig, axes = plt.subplots(rows, 1, sharex=True, figsize=(8, 2.2 + 1.6 * rows), squeeze=False)
    for i, name in enumerate(chosen):
        ax = axes[i if separate else 0, 0]
        ax.plot(time, data[:, names.index(name)], label=name)
        ax.grid(True, alpha=0.3)
        ax.legend(loc="best", fontsize="small")
    axes[-1, 0].set_xlabel("time [s]")
    fig.suptitle(title or Path(result).name)
    fig.tight_layout()
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=120)
    plt.close(fig)
    return output
