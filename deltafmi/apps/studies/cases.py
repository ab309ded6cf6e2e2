"""The cases of a study: the product of its grid axes, its zipped lists and its Monte Carlo samples.

Case ``i`` is the i-th element of ``itertools.product(grid axis 1, ..., grid axis n, zipped rows,
Monte Carlo samples)``: the first grid axis varies slowest, every grid point sees the same Monte
Carlo samples (common random numbers). Monte Carlo samples are reproducible: each parameter draws
from its own stream, spawned from the seed in declaration order, so asking for more samples keeps
the first ones.
"""
from __future__ import annotations

import itertools
import json
from dataclasses import dataclass
from typing import Any, Dict, List, Mapping, Sequence, Tuple

import numpy as np

from .spec import Distribution, MonteCarlo, Vary

__all__ = ["Case", "case_key", "generate_cases"]


@dataclass(frozen=True)
class Case:
    """One run of a study: its id and the values of every varied target (column order)."""

    id: int
    values: Dict[str, Any]

    @property
    def key(self) -> str:
        """Identifies the case by its values (what a resumed study matches on)."""
        return case_key(self.values)

    def describe(self) -> str:
        """``controller.pole=3, plant.payload=6``."""
        return ", ".join(f"{name}={value:.6g}" if isinstance(value, float) else f"{name}={value}"
                         for name, value in self.values.items())


def case_key(values: Mapping[str, Any]) -> str:
    """A text key of the values (floats exact: JSON writes their shortest round-trip repr)."""
    return json.dumps(dict(values), sort_keys=True)


def draw(distribution: Distribution, generator: np.random.Generator, samples: int,
         nominal: float = 1.0) -> np.ndarray:
    """``samples`` draws of ``distribution`` (times ``nominal`` when it is relative)."""
    a, b = distribution.a, distribution.b
    if distribution.kind == "uniform":
        values = generator.uniform(a, b, samples)
    elif distribution.kind == "normal":
        values = generator.normal(a, b, samples)
    else:
        values = generator.lognormal(a, b, samples)
    return values * nominal if distribution.relative else values


def monte_carlo_samples(mc: MonteCarlo, nominal: Mapping[str, float]) -> Dict[str, np.ndarray]:
    """Every parameter's samples; ``nominal[name]`` scales relative distributions."""
    streams = np.random.SeedSequence(mc.seed).spawn(len(mc.parameters))
    return {target.name: draw(dist, np.random.default_rng(stream), mc.samples, nominal.get(target.name, 1.0))
            for (target, dist), stream in zip(mc.parameters, streams)}


def generate_cases(vary: Vary, nominal: Mapping[str, float] = {}) -> List[Case]:
    """All cases of a study, numbered from 0 (see the module docstring for the order)."""
    axes: List[Sequence[Tuple[Tuple[str, Any], ...]]] = [
        [((target.name, _plain(value)),) for value in values] for target, values in vary.grid]
    if vary.zipped:
        columns = [[(target.name, _plain(v)) for v in values] for target, values in vary.zipped]
        axes.append(list(zip(*columns)))
    if vary.monte_carlo is not None:
        samples = monte_carlo_samples(vary.monte_carlo, nominal)
        columns = [[(name, float(v)) for v in values] for name, values in samples.items()]
        axes.append(list(zip(*columns)))
    return [Case(i, dict(pair for part in combination for pair in part))
            for i, combination in enumerate(itertools.product(*axes))]


def _plain(value: Any) -> Any:
    """numpy scalars as Python scalars (so values compare, hash and serialize plainly)."""
    return value.item() if isinstance(value, np.generic) else value
