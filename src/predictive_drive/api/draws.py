"""Drawn drives (``sweep --draw N``, ``reproduce robustness``; docs/reproduction.md#robustness):
N drives whose plant parameters are drawn from stated spreads around the scenario's values, the
same N for every strategy (common random numbers), reproduced by their seed; and what the runs
on them say, strategy by strategy: the mean of each figure with its 95 % interval, the chance of
ranking first with its interval.

A spread is ``KEY=normal:S`` (the value times 1 + S·z, z standard normal) or
``KEY=uniform:S`` (times 1 + S·u, u uniform in [-1, 1]); KEY a scenario setting (``plant.motor.l_q``).
Each key draws from its own stream, seeded by the seed and the key: adding a spread leaves the
others' draws as they were. Every drawn value is checked against its parameter's range, and every
drawn drive loaded as a scenario, before anything runs.
"""

from __future__ import annotations

import dataclasses
import math
import zlib
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..config import apply_settings, load_scenario_text, nested_types, section_class
from ..core.fields import spec_of
from ..core.metrics import METRICS
from ..core.scenario import RunParams, Scenario
from ..core.stats import Interval, first_shares, mean_interval, wilson_interval
from ..errors import ConfigError
from ..interface import NODES
from .sweep import DRAW_COLUMNS, DRAW_RANKED, Case, Row, SweepResult, parse_set, sweep

__all__ = [
    "DISTRIBUTIONS",
    "Draw",
    "Spread",
    "StrategyFigures",
    "draw_cases",
    "drawn",
    "parse_spread",
    "summarize",
    "sweep_drawn",
]

DISTRIBUTIONS = ("normal", "uniform")
#: keys of a saturating plant's machine that its magnetic model replaces (a spread on them
#: would change nothing)
_MAP_REPLACES = ("plant.motor.l_d", "plant.motor.l_q", "plant.motor.psi_f")


@dataclass(frozen=True)
class Spread:
    """One parameter's spread: ``kind`` (:data:`DISTRIBUTIONS`) with relative ``width`` (the
    normal's σ, the uniform's half-width, as a share of the value)."""

    key: str
    kind: str
    width: float

    @property
    def text(self) -> str:
        return f"{self.key}={self.kind}:{self.width:g}"

    def factors(self, n: int, seed: int) -> np.ndarray:
        """The n factors 1 + width·z of draws 0..n-1, from this key's own stream."""
        rng = np.random.default_rng([seed, zlib.crc32(self.key.encode())])
        z = rng.standard_normal(n) if self.kind == "normal" else rng.uniform(-1.0, 1.0, n)
        f: np.ndarray = 1.0 + self.width * z
        return f


def parse_spread(text: str) -> Spread:
    """``KEY=normal:S`` or ``KEY=uniform:S`` → :class:`Spread`; ConfigError names what is wrong."""
    key, sep, rest = text.partition("=")
    kind, colon, width = rest.partition(":")
    if not sep or not colon or not key.strip():
        raise ConfigError(
            f"--spread {text!r}: expected KEY=normal:S or KEY=uniform:S (S the relative "
            f"spread, e.g. plant.motor.l_q=normal:0.1)"
        )
    key, kind = key.strip(), kind.strip()
    if kind not in DISTRIBUTIONS:
        raise ConfigError(
            f"--spread {key}: distribution {kind!r} is not one of {', '.join(DISTRIBUTIONS)}"
        )
    try:
        w = float(width)
    except ValueError:
        raise ConfigError(f"--spread {key}: the spread {width!r} is not a number") from None
    if not (math.isfinite(w) and w >= 0.0):
        raise ConfigError(
            f"--spread {key}: the spread must be a finite number >= 0 (a share of the value), "
            f"got {width}"
        )
    return Spread(key, kind, w)


@dataclass(frozen=True)
class Draw:
    """Drive ``index`` of the draws of ``seed``: each key's factor and the value it gives."""

    index: int
    seed: int
    factors: dict[str, float]
    values: dict[str, float]

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def _field(sc: Scenario, key: str) -> tuple[Any, Any]:
    """(the present value, the field's spec) of a setting key in a loaded scenario."""
    node, _, rest = key.partition(".")
    if node in NODES and rest:
        owner = {
            "plant": sc.plant, "speed_pi": sc.speed_pi, "torque_controller": sc.controller,
            "metrics_logger": sc.logger,
        }[node]  # fmt: skip
        cls, nested = section_class(node, sc.run.machine, sc.family)
        path = rest.split(".")
    elif not rest:
        owner, cls, nested, path = sc.run, RunParams, {}, [node]
    else:
        raise ConfigError(f"--spread {key}: not a setting (<node>.<key> or a shared key)")
    for part in path[:-1]:
        if part not in nested:
            raise ConfigError(f"--spread {key}: {part!r} is not a group of {node}")
        cls, owner = nested[part], getattr(owner, part, None)
        nested = nested_types(cls)
        if owner is None:
            raise ConfigError(
                f"--spread {key}: this scenario's {node}.{part} is off (its model is none): "
                f"give it a model first (--set {node}.{part}.model=...)"
            )
    fields = {f.name: f for f in dataclasses.fields(cls)}
    if path[-1] not in fields:
        raise ConfigError(
            f"--spread {key}: {path[-1]!r} is not a key there; keys: {', '.join(fields)}"
        )
    return getattr(owner, path[-1]), spec_of(fields[path[-1]])


def drawn(
    scenario: str | Path,
    spreads: Sequence[Spread],
    n: int | None,
    seed: int,
    settings: dict[str, Any] | None = None,
) -> list[Draw]:
    """The n drives the spreads draw around the scenario (with ``settings`` applied first: a
    drawn key's value there is the one drawn around),
    every value checked against its parameter's range and every drive loaded: ConfigError names
    the key, the draw and the range before anything runs."""
    from ..config import resolve_scenario_path

    if n is None:
        raise ConfigError("--spread: give --draw N too (the number of drives to draw, at least 1)")
    if n < 1:
        raise ConfigError(f"--draw {n}: the number of drawn drives must be at least 1")
    if not spreads:
        raise ConfigError("--draw: give the spreads to draw from (--spread KEY=normal:S ...)")
    keys = [s.key for s in spreads]
    if len(set(keys)) != len(keys):
        raise ConfigError(f"--spread: a key given twice ({', '.join(keys)})")
    settings = dict(settings or {})  # a drawn key's value here is its nominal
    path = resolve_scenario_path(scenario)
    text = apply_settings(path.read_text(encoding="utf-8"), settings, path)
    base = load_scenario_text(text, path)
    nominal: dict[str, float] = {}
    for s in spreads:
        value, spec = _field(base, s.key)
        if base.plant.saturation is not None and s.key in _MAP_REPLACES:
            raise ConfigError(
                f"--spread {s.key}: this scenario's plant saturates: its magnetic model "
                f"(plant.saturation) replaces l_d, l_q and psi_f; spread the model's keys "
                f"(plant.saturation.lq_drop, .a_q0, ...)"
            )
        if isinstance(value, bool) or not isinstance(value, float) or spec is None:
            raise ConfigError(f"--spread {s.key}: {value!r} is not a real-valued parameter to draw")
        nominal[s.key] = value
    factors = {s.key: s.factors(n, seed) for s in spreads}
    out = []
    for i in range(n):
        f = {k: float(v[i]) for k, v in factors.items()}
        values = {k: nominal[k] * f[k] for k in keys}
        for s in spreads:
            spec = _field(base, s.key)[1]
            try:
                spec.check(s.key, values[s.key])
            except ConfigError as e:
                raise ConfigError(
                    f"--spread {s.text}: draw {i} of {n} (seed {seed}) gives {e}: the spread "
                    f"reaches beyond the parameter's range (narrow it)"
                ) from None
        where = f"{path} with draw {i} of seed {seed}"
        load_scenario_text(apply_settings(text, values, where), where)  # cross-checks (σ > 0 ...)
        out.append(Draw(i, seed, f, values))
    return out


def draw_cases(cases: Sequence[Case], draws: Sequence[Draw]) -> list[Case]:
    """Every case on every drawn drive (draw by draw, the cases in their order within each)."""
    return [
        dataclasses.replace(c, settings={**c.settings, **d.values}, draw=d.as_dict())
        for d in draws
        for c in cases
    ]


@dataclass(frozen=True)
class StrategyFigures:
    """One strategy (with the settings of its group) over the drawn drives: per metric key its
    mean with the 95 % interval, its quartiles; per ranked key the share of draws it ranks
    first with its Wilson interval; the drives it failed on."""

    strategy: str
    settings: dict[str, Any]
    mean: dict[str, Interval]
    quartiles: dict[str, tuple[float, float, float]]
    first: dict[str, Interval]
    failed: int
    #: per ranked key: the mean over the drives of this strategy's figure minus the best
    #: strategy's (lowest mean) on the same drive, with its 95 % interval (paired: common
    #: random numbers make it far tighter than the means' intervals)
    versus_best: dict[str, Interval] = dataclasses.field(default_factory=dict)

    def as_dict(self) -> dict[str, Any]:
        return {
            "strategy": self.strategy,
            "settings": self.settings,
            "mean": {k: v._asdict() for k, v in self.mean.items()},
            "quartiles": {k: list(v) for k, v in self.quartiles.items()},
            "first": {k: v._asdict() for k, v in self.first.items()},
            "versus_best": {k: v._asdict() for k, v in self.versus_best.items()},
            "failed": self.failed,
        }


def figure(row: Row, key: str) -> float:
    """A row's figure by metric key (NaN for a failed run)."""
    if row.metrics is None:
        return math.nan
    return float(getattr(row.metrics, key))


def summarize(
    rows: Sequence[Row], keys: Sequence[str], ranked: Sequence[str], drawn_keys: Sequence[str]
) -> list[StrategyFigures]:
    """Rows of drawn drives → each strategy's figures. Rows group by their settings other than
    the drawn keys (a sweep's grid point); within a group the strategies are ranked draw by draw
    (common random numbers: the same drive for each)."""
    for k in (*keys, *ranked):
        if k not in METRICS:
            raise ConfigError(f"robustness column {k!r}: not a metric; one of {', '.join(METRICS)}")
    groups: dict[str, list[Row]] = {}
    for r in rows:
        fixed = {k: v for k, v in r.settings.items() if k not in drawn_keys}
        groups.setdefault(repr(sorted(fixed.items())), []).append(r)
    out = []
    for members in groups.values():
        by_strategy: dict[str, list[Row]] = {}
        for r in members:
            by_strategy.setdefault(r.strategy, []).append(r)
        by_draw: dict[int, dict[str, Row]] = {}
        for r in members:
            by_draw.setdefault(_index(r), {})[r.strategy] = r
        firsts = {
            key: first_shares([{s: figure(r, key) for s, r in d.items()} for d in by_draw.values()])
            for key in ranked
        }
        for strategy, rs in by_strategy.items():
            fixed = {k: v for k, v in rs[0].settings.items() if k not in drawn_keys}
            mean, quart = {}, {}
            for key in keys:
                values = [figure(r, key) for r in rs]
                mean[key] = mean_interval(values)
                finite = [v for v in values if math.isfinite(v)]
                q = np.percentile(finite, [25, 50, 75]) if finite else [math.nan] * 3
                quart[key] = (float(q[0]), float(q[1]), float(q[2]))
            first = {k: wilson_interval(f[0][strategy], f[1]) for k, f in firsts.items()}
            failed = sum(r.metrics is None for r in rs)
            out.append(StrategyFigures(strategy, fixed, mean, quart, first, failed))
        _versus_best(out[-len(by_strategy) :], by_draw, ranked)
    return out


def _versus_best(
    group: list[StrategyFigures], by_draw: dict[int, dict[str, Row]], ranked: Sequence[str]
) -> None:
    """Fill each strategy's :attr:`StrategyFigures.versus_best` within one group."""
    for key in ranked:
        means = {f.strategy: f.mean[key].value for f in group if math.isfinite(f.mean[key].value)}
        if not means:
            continue
        best = min(means, key=means.__getitem__)
        for f in group:
            diffs = [
                figure(d[f.strategy], key) - figure(d[best], key)
                for d in by_draw.values()
                if f.strategy in d and best in d
            ]
            f.versus_best[key] = mean_interval(diffs)


def _index(row: Row) -> int:
    return int(row.draw["index"]) if row.draw else -1


def sweep_drawn(
    scenario: str | Path,
    *,
    draw: int | None,
    spreads: Sequence[str],
    seed: int = 0,
    sets: Sequence[str] = (),
    **kwargs: Any,
) -> SweepResult:
    """``sweep --draw N``: :func:`~.sweep.sweep` with every case of its grid on each of ``draw``
    drives drawn from ``spreads`` by ``seed`` (drawn and checked before anything runs), and each
    strategy summarised over them (:attr:`~.sweep.SweepResult.drawn`). ``kwargs``: the sweep's."""
    spread = [parse_spread(s) for s in spreads]
    parsed = [parse_set(s) for s in sets]
    both = sorted({s.key for s in spread} & {k for k, _ in parsed})
    if both:
        raise ConfigError(f"--spread {both[0]}: also --set; a key is drawn or set, not both")
    drives = drawn(scenario, spread, draw, seed, {k: v[0] for k, v in parsed})
    result = sweep(scenario, sets=sets, expand=lambda cases: draw_cases(cases, drives), **kwargs)
    result.drawn = summarize(result.rows, DRAW_COLUMNS, DRAW_RANKED, [s.key for s in spread])
    result.spreads, result.seed = [s.text for s in spread], seed
    return result
