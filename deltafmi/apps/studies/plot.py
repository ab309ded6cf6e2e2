"""Figures of a study's results table: a metric against one varied parameter (one line per value
of a second one, if any), a heat map against two, or a histogram of Monte Carlo results.

Failed cases have no metrics: they are gaps in lines, grey cells in heat maps, and counted in the
titles. Matplotlib with the Agg backend (no display needed).
"""
from __future__ import annotations

import math
from pathlib import Path
from typing import Any, Dict, List, Optional, Sequence

import numpy as np
import pyarrow as pa

from deltafmi.errors import BadInput, did_you_mean

from .store import read_results, study_metadata

__all__ = ["heatmap_cells", "plot_study"]

KINDS = ("line", "heatmap", "histogram")
#: what a heat map's cell shows when several cases share it (Monte Carlo samples at a grid point):
#: their median, or their mean (of a 0/1 metric: the success rate)
CELL_STATISTICS = {"median": np.median, "mean": np.mean}


def plot_study(results: str | Path, output: str | Path, metrics: Sequence[str] = (), x: Optional[str] = None,
               y: Optional[str] = None, kind: Optional[str] = None, log: bool = False, title: str = "",
               cell: str = "median") -> Path:
    """Draw ``metrics`` (default: all) of the results table ``results`` into ``output``; ``cell``
    (a key of :data:`CELL_STATISTICS`) is what a heat map's cell shows of the cases that share it."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    table = read_results(results)
    meta = study_metadata(table)
    if not meta:
        raise BadInput(f"'{results}' has no study description in its metadata: was it written by deltafmi sweep?")
    targets = [t["name"] for t in meta["targets"]]
    kinds = {t["name"]: t["kind"] for t in meta["targets"]}
    units = {t["name"]: t.get("unit", "") for t in meta["targets"]}
    units.update({m["name"]: m.get("unit", "") for m in meta["metrics"]})
    all_metrics = [m["name"] for m in meta["metrics"]]
    chosen = list(metrics) or all_metrics
    for name in chosen:
        if name not in all_metrics:
            raise BadInput(f"no metric '{name}' in '{results}'{did_you_mean(name, all_metrics)} "
                           f"(metrics: {', '.join(all_metrics)})")
    for name in (x, y):
        if name is not None and name not in targets:
            raise BadInput(f"'{name}' is not varied in '{results}'{did_you_mean(name, targets)} "
                           f"(varied: {', '.join(targets)})")
    # the axes chosen when not given: parameters that take more than one value in the table (a
    # grid axis of one value, there to fix it, would make a map of one row)
    varied = [t for t in targets if t in table.column_names and len(set(table.column(t).to_pylist())) > 1]
    axes_from = varied or targets
    kind = kind or _default_kind(axes_from, kinds, x, y)
    if kind == "heatmap":
        x, y = _two_axes(axes_from, kinds, x, y)
    elif kind == "line":
        x = x or next((t for t in axes_from if kinds[t] != "monte_carlo"), axes_from[0])
    ok = np.array([s == "ok" for s in table.column("status").to_pylist()])
    columns = {name: _floats(table.column(name)) for name in chosen}
    failed = int(np.count_nonzero(~ok))

    n = len(chosen)
    ncols = min(n, 3 if kind == "heatmap" else 2)
    nrows = math.ceil(n / ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(5.2 * ncols, 3.8 * nrows), squeeze=False)
    for ax, name in zip(axes.flat, chosen):
        values = np.where(ok, columns[name], np.nan)
        label = _label(name, units)
        logarithmic = log and _spans_decades(values)
        if kind == "histogram":
            _histogram(ax, values, label, logarithmic)
        elif kind == "heatmap":
            assert x is not None and y is not None
            _heatmap(fig, ax, table, x, y, values, label, units, logarithmic, cell)
        else:
            assert x is not None
            _lines(ax, table, x, y if y else _other(axes_from, kinds, x), values, label, units, logarithmic)
    for ax in list(axes.flat)[n:]:
        ax.set_visible(False)
    study = Path(meta.get("study", str(results))).name
    heading = title or f"{study}: {table.num_rows} cases" + (f", {failed} failed" if failed else "")
    fig.suptitle(heading)
    fig.tight_layout()
    output = Path(output)
    output.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(output, dpi=120)
    plt.close(fig)
    return output


def _default_kind(targets: List[str], kinds: Dict[str, str], x: Optional[str], y: Optional[str]) -> str:
    if x is not None and y is not None:
        return "heatmap"
    if x is not None:
        return "line"
    swept = [t for t in targets if kinds[t] != "monte_carlo"]
    if len(swept) >= 2:
        return "heatmap"
    if len(swept) == 1:
        return "line"
    return "histogram"


def _two_axes(targets: List[str], kinds: Dict[str, str], x: Optional[str], y: Optional[str]) -> List[str]:
    swept = [t for t in targets if kinds[t] != "monte_carlo"] or targets
    x = x or swept[0]
    y = y or next((t for t in swept if t != x), None)
    if y is None:
        raise BadInput("a heat map needs two varied parameters; this study varies one (use --kind line)")
    return [x, y]


def _other(targets: List[str], kinds: Dict[str, str], x: str) -> Optional[str]:
    return next((t for t in targets if t != x and kinds[t] != "monte_carlo"), None)


def _spans_decades(values: np.ndarray) -> bool:
    """Positive values whose largest is more than ten times the smallest (worth a log scale)."""
    finite = values[np.isfinite(values)]
    return bool(len(finite) and np.all(finite > 0) and finite.max() > 10 * finite.min())


def _floats(column: pa.ChunkedArray) -> np.ndarray:
    return np.array([math.nan if v is None else v for v in column.to_pylist()], dtype=float)


def _label(name: str, units: Dict[str, str]) -> str:
    unit = units.get(name, "")
    return f"{name} [{unit}]" if unit else name


def _histogram(ax: Any, values: np.ndarray, label: str, log: bool) -> None:
    finite = values[np.isfinite(values)]
    if len(finite) == 0:
        ax.text(0.5, 0.5, "no successful case", ha="center", transform=ax.transAxes)
        return
    bins: Any
    if log and np.all(finite > 0):
        from matplotlib.ticker import NullFormatter

        bins = np.logspace(np.log10(finite.min()), np.log10(finite.max()), 30) if finite.min() < finite.max() else 10
        ax.set_xscale("log")
        ax.xaxis.set_minor_formatter(NullFormatter())  # labelled minor ticks overlap within a decade
    else:
        bins = "auto"
    ax.hist(finite, bins=bins, color="#4477aa", edgecolor="white")
    median, p95 = np.median(finite), np.percentile(finite, 95)
    ax.axvline(median, color="k", lw=1.2, label=f"median {median:.3g}")
    ax.axvline(p95, color="#cc3311", lw=1.2, ls="--", label=f"95th percentile {p95:.3g}")
    ax.set_xlabel(label)
    ax.set_ylabel("cases")
    ax.legend(fontsize="small")
    ax.set_title(f"{len(finite)} cases: mean {finite.mean():.3g}, std {finite.std(ddof=1) if len(finite) > 1 else 0:.2g}",
                 fontsize="small")


def heatmap_cells(xs: Sequence[Any], ys: Sequence[Any], values: np.ndarray,
                  cell: str = "median") -> tuple[list, list, np.ndarray, bool]:
    """The heat map of ``values`` over the points (xs, ys): the sorted distinct x and y values,
    the grid (rows y, columns x) of each cell's statistic ``cell`` over its finite values (NaN where
    it has none), and whether any cell holds several cases."""
    if cell not in CELL_STATISTICS:
        raise BadInput(f"no cell statistic '{cell}'{did_you_mean(cell, list(CELL_STATISTICS))} "
                       f"(choose {', '.join(CELL_STATISTICS)})")
    x_values, y_values = sorted(set(xs)), sorted(set(ys))
    grid = np.full((len(y_values), len(x_values)), np.nan)
    cells: Dict[tuple, List[float]] = {}
    for xv, yv, v in zip(xs, ys, values):
        cells.setdefault((y_values.index(yv), x_values.index(xv)), []).append(v)
    for (i, j), vs in cells.items():
        finite = [v for v in vs if np.isfinite(v)]
        grid[i, j] = CELL_STATISTICS[cell](finite) if finite else np.nan
    return x_values, y_values, grid, any(len(v) > 1 for v in cells.values())


def _heatmap(fig: Any, ax: Any, table: pa.Table, x: str, y: str, values: np.ndarray, label: str,
             units: Dict[str, str], log: bool, cell: str) -> None:
    from matplotlib.colors import LogNorm

    x_values, y_values, grid, several = heatmap_cells(table.column(x).to_pylist(), table.column(y).to_pylist(),
                                                      values, cell)
    masked = np.ma.masked_invalid(grid)
    positive = masked.compressed()
    norm = LogNorm() if log and len(positive) and np.all(positive > 0) else None
    cmap = _colormap()
    image = ax.pcolormesh(np.arange(len(x_values) + 1), np.arange(len(y_values) + 1), masked, cmap=cmap,
                          norm=norm, shading="flat")
    ax.set_xticks(np.arange(len(x_values)) + 0.5, [f"{v:g}" if isinstance(v, float) else str(v) for v in x_values])
    ax.set_yticks(np.arange(len(y_values)) + 0.5, [f"{v:g}" if isinstance(v, float) else str(v) for v in y_values])
    if max(len(tick.get_text()) for tick in ax.xaxis.get_ticklabels()) > 4:
        ax.tick_params(axis="x", labelrotation=45)  # long labels (0.00025) would run together
    if len(x_values) > 12:
        for k, tick in enumerate(ax.xaxis.get_ticklabels()):
            tick.set_visible(k % math.ceil(len(x_values) / 12) == 0)
    ax.set_xlabel(_label(x, units))
    ax.set_ylabel(_label(y, units))
    ax.set_title(label + (f" ({cell} per cell)" if several else ""), fontsize="medium")
    fig.colorbar(image, ax=ax)


def _colormap() -> Any:
    import matplotlib

    return matplotlib.colormaps["viridis"].with_extremes(bad="#bbbbbb")  # grey: failed cases


def _lines(ax: Any, table: pa.Table, x: str, family: Optional[str], values: np.ndarray, label: str,
           units: Dict[str, str], log: bool) -> None:
    xs = np.array(table.column(x).to_pylist(), dtype=float)
    if family is None:
        order = np.argsort(xs, kind="stable")
        ax.plot(xs[order], values[order], "o-", ms=3)
    else:
        groups = table.column(family).to_pylist()
        distinct = sorted(set(groups))
        colors = _colormap()(np.linspace(0, 1, max(len(distinct), 2)))
        for color, group in zip(colors, distinct):
            mask = np.array([g == group for g in groups])
            order = np.argsort(xs[mask], kind="stable")
            shown = f"{group:g}" if isinstance(group, float) else str(group)
            ax.plot(xs[mask][order], values[mask][order], "o-", ms=3, color=color,
                    label=f"{family} = {shown}")
        ax.legend(fontsize="x-small", ncol=2 if len(distinct) > 6 else 1)
    if log:
        ax.set_yscale("log")
    ax.set_xlabel(_label(x, units))
    ax.set_ylabel(label)
    ax.grid(True, alpha=0.3)
