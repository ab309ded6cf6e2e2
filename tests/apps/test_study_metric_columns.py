"""A case's metrics from its recorded rows in one gather per signal (RecordedColumns.block, the
signal shared by the metrics of one signal and norm, the window's rows found by bisection of the
recorded times) are the metrics computed column by column from plain arrays, bit for bit, for every
norm and statistic, vectors shorter and longer than numpy's 8-element pairwise block; a norm of
fewer than 8 elements summed column after column is numpy's sum over each row, bit for bit."""
from __future__ import annotations

import numpy as np
import pytest

from deltafmi.apps.studies.metrics import Metric, reduce
from deltafmi.apps.studies.runner import RecordedColumns
from deltafmi.apps.studies.spec import MetricSpec, Window

STATISTICS = ("max", "min", "final", "mean", "rms", "alternation")


def recorded(elements: int, rows: int = 2001, seed: int = 3):
    """Rows of two recorded vectors ``a``, ``b`` and a scalar ``s`` (an event row: time repeated)."""
    rng = np.random.default_rng(seed)
    time = np.linspace(0.0, 2.0, rows)
    time[1000] = time[999]
    names = [f"a[{i}]" for i in range(1, elements + 1)] + [f"b[{i}]" for i in range(1, elements + 1)] + ["s"]
    values = rng.standard_normal((rows, len(names))) * rng.choice([1e-9, 1.0, 1e7], (rows, len(names)))
    return np.column_stack([time, values]), names


@pytest.mark.parametrize("elements", [1, 3, 7, 8, 12])
@pytest.mark.parametrize("norm", [None, "2", "inf", "1"])
def test_metrics_from_gathered_rows_equal_column_by_column(elements, norm):
    rows, names = recorded(elements)
    left = tuple(f"a[{i}]" for i in range(1, elements + 1))
    right = tuple(f"b[{i}]" for i in range(1, elements + 1))
    plain = {"time": rows[:, 0].copy(), **{name: rows[:, i + 1].copy() for i, name in enumerate(names)}}
    columns = RecordedColumns(rows, names, ["Real"] * len(names))
    for statistic in STATISTICS:
        # a window from or to the time of the event's two rows, and one between two samples
        for window in (Window(), Window(0.5, 1.5), Window(rows[999, 0], None), Window(None, rows[999, 0]),
                       Window(0.5002, 0.5003)):
            for signal in ((left, right), (left, ()), (("s",), ())):
                spec = MetricSpec(name="m", signal="x", left="a", right=None, statistic=statistic, norm=norm,
                                  window=window)
                metric = Metric(spec, *signal)
                expected, got = metric.value(plain), metric.value(columns)
                assert np.float64(expected).tobytes() == np.float64(got).tobytes(), (statistic, window, signal)
    assert columns.signals  # the signals were kept for the metrics after the first


@pytest.mark.parametrize("elements", range(1, 8))
def test_numpy_reduces_short_rows_alike_in_either_layout(elements):
    """What RecordedColumns.block relies on to hand over column-major blocks of < 8 columns."""
    rng = np.random.default_rng(elements)
    values = rng.standard_normal((50_000, elements)) * rng.choice([1e-8, 1.0, 1e8], (50_000, elements))
    c, f = np.ascontiguousarray(values), np.asfortranarray(values)
    for reduction in (lambda v: np.sum(v * v, axis=1), lambda v: np.sum(np.abs(v), axis=1),
                      lambda v: np.max(np.abs(v), axis=1)):
        assert reduction(c).tobytes() == reduction(f).tobytes()


@pytest.mark.parametrize("elements", range(1, 8))
def test_short_norms_column_by_column_are_numpys_row_reductions(elements):
    """metrics.reduce sums fewer than 8 elements column after column: numpy's sum (and max) over
    each row of the same values, bit for bit, in either layout."""
    rng = np.random.default_rng(10 + elements)
    values = rng.standard_normal((50_000, elements)) * rng.choice([1e-8, 1.0, 1e8], (50_000, elements))
    values[7, 0] = np.nan
    for layout in (np.ascontiguousarray(values), np.asfortranarray(values), values[::2]):
        for norm, expected in (("2", np.sqrt(np.sum(layout * layout, axis=1))),
                               ("1", np.sum(np.abs(layout), axis=1)), ("inf", np.max(np.abs(layout), axis=1))):
            assert reduce(layout, norm).tobytes() == expected.tobytes(), norm
