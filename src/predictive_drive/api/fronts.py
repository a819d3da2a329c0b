"""``predictive-drive reproduce fronts``: every strategy's front of distortion against switching
frequency at each steady operating point (:mod:`predictive_drive.reports.fronts`), FOC + SVPWM
the baseline, run as a sweep on the local cores or a Dask cluster; the fronts compared at common
switching frequencies and ranked there
(docs/reproduction.md#fronts-distortion-against-switching-frequency)."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import apply_settings, load_scenario, load_scenario_text, resolve_scenario_path
from ..errors import ConfigError
from ..reports.fronts import (
    COMMON_FSW,
    FRONTS,
    HOLD_SHARE,
    KNOBS,
    MAX_GAP,
    RANKED,
    SHOWN,
    Curve,
    OperatingPoint,
)
from .study import Reproduction, StudyRuns
from .sweep import Case

__all__ = [
    "FrontCurve",
    "FrontPoint",
    "FrontTable",
    "FrontsResult",
    "interpolate",
    "pareto",
    "reproduce_fronts",
    "with_knob_values",
]

FRONTS_STUDY = "fronts"

_HOW = (
    "each point one run at a steady operating point (the shaft held by a load machine, T* "
    "held), its figures over the scenario's window in continuous time (the plant's period "
    "means): T_ripple cont = RMS of the torque about its mean, THD_i cont = the stator "
    "current's distortion over its fundamental (every frequency, three phases), f_sw = "
    "turn-on events per device per second. A point whose mean torque misses T* by more than "
    "half has left the operating point: listed, not on the front. The front of a curve is its "
    "points no other point of the curve beats in both f_sw and the figure; between them it is "
    "interpolated log-log, '-' outside its range or across a gap of more than twice in f_sw. "
    "Rank: lowest first at each frequency."
)


@dataclass(frozen=True)
class FrontPoint:
    """One run of a curve: its knob value, figures (:data:`~..reports.fronts.SHOWN`, by metric
    key), whether it held the operating point, and on which figures' fronts it lies."""

    value: float
    figures: dict[str, float]
    holds: bool
    on_front: dict[str, bool]
    wall_s: float


@dataclass(frozen=True)
class FrontCurve:
    """A strategy traced over its knob at one operating point."""

    name: str
    strategy: str
    scenario: str
    knob: str
    settings: dict[str, Any]
    points: list[FrontPoint]

    def front(self, key: str) -> list[tuple[float, float]]:
        """(f_sw, figure) of the front of figure ``key``, by rising f_sw."""
        pts = [(p.figures["f_sw_hz"], p.figures[key]) for p in self.points if p.on_front[key]]
        return sorted(pts)


@dataclass(frozen=True)
class FrontTable:
    """One operating point: its curves, each front at the common frequencies (``at[metric]
    [curve]``, None outside the curve's range) and the ranking there (``ranking[metric]``, per
    frequency the curves best first), beside the papers' ranking."""

    point: str
    caption: str
    curves: list[FrontCurve]
    at: dict[str, dict[str, list[float | None]]]
    ranking: dict[str, list[list[str]]]
    papers_ranking: tuple[str, ...]
    papers_source: str
    torque_ref: float


@dataclass(frozen=True)
class FrontsResult(Reproduction):
    """``reproduce fronts``: every operating point's curves and their comparison."""

    frequencies: tuple[float, ...]
    points: list[FrontTable]
    runs: int
    wall_s: float
    figures: list[Path] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            **self.head(),
            "frequencies_hz": list(self.frequencies),
            "runs": self.runs,
            "wall_s": self.wall_s,
            "points": [dataclasses.asdict(t) for t in self.points],
        }
        if self.figures:
            out["figures"] = [str(p) for p in self.figures]
        return out


def pareto(points: Sequence[tuple[float, float]]) -> list[bool]:
    """Which of (f_sw, figure) pairs lie on the front: no other pair has a lower-or-equal f_sw
    and a lower-or-equal figure, one of them lower. NaN pairs never do."""
    out = []
    for i, (f, v) in enumerate(points):
        if not (math.isfinite(f) and math.isfinite(v)):
            out.append(False)
            continue
        dominated = any(
            j != i and g <= f and w <= v and (g < f or w < v)
            for j, (g, w) in enumerate(points)
            if math.isfinite(g) and math.isfinite(w)
        )
        out.append(not dominated)
    return out


def interpolate(
    front: Sequence[tuple[float, float]], f: float, *, max_gap: float = MAX_GAP
) -> float | None:
    """The front (f_sw, figure) pairs, rising in f_sw, at ``f`` Hz: log-log linear between the
    neighbours (linear where a figure is not positive); None outside the front's range and
    between neighbours more than ``max_gap`` times apart."""
    if not front or f < front[0][0] or f > front[-1][0]:
        return None
    for (f0, v0), (f1, v1) in zip(front, front[1:]):
        if f0 <= f <= f1:
            if f == f0 or f == f1:
                return v0 if f == f0 else v1
            if f1 > max_gap * f0:
                return None
            s = (math.log(f) - math.log(f0)) / (math.log(f1) - math.log(f0))
            if v0 > 0 and v1 > 0:
                return math.exp(math.log(v0) + s * (math.log(v1) - math.log(v0)))
            return v0 + s * (v1 - v0)
    return front[0][1]  # a front of one point, at exactly its frequency


def with_knob_values(
    study: Mapping[str, OperatingPoint],
    *,
    lambda_sw: Sequence[float] | None = None,
    fsw_khz: Sequence[float] | None = None,
    lambda_u: Sequence[float] | None = None,
) -> dict[str, OperatingPoint]:
    """The study with every finite-control-set curve traced over ``lambda_sw``, every
    direct_mpc curve over ``lambda_u`` and every FOC curve over the carriers ``fsw_khz``
    (ts = 1/f_sw) instead of its own values; ConfigError names a value outside the knob's
    range (:data:`~..reports.fronts.KNOBS`)."""
    given = {
        "torque_controller.lambda_sw": lambda_sw,
        "torque_controller.lambda_u": lambda_u,
        "ts": None,
    }
    if fsw_khz is not None:
        for f in fsw_khz:
            if not (math.isfinite(f) and f > 0):
                raise ConfigError(f"--fsw-khz: {f!r} is not a positive number of kHz")
        given["ts"] = [1.0 / (1e3 * f) for f in fsw_khz]
    for key, values in given.items():
        if values is None:
            continue
        lo, hi = KNOBS[key]
        if not values:
            raise ConfigError(f"{_knob_option(key)}: give at least one value")
        for v in values:
            if not (math.isfinite(v) and lo <= v <= hi):
                shown = v if key != "ts" else 1e-3 / v
                rng = f"{lo:g}..{hi:g}" if key != "ts" else f"{1e-3 / hi:g}..{1e-3 / lo:g} kHz"
                raise ConfigError(f"{_knob_option(key)}: {shown!r} is outside {rng}")
    out = {}
    for name, op in study.items():
        curves = tuple(
            dataclasses.replace(c, values=tuple(given[c.knob] or c.values)) for c in op.curves
        )
        out[name] = dataclasses.replace(op, curves=curves)
    return out


def _knob_option(key: str) -> str:
    return {"torque_controller.lambda_sw": "--lambda-sw", "torque_controller.lambda_u":
            "--lambda-u"}.get(key, "--fsw-khz")  # fmt: skip


def _plans(
    study: Mapping[str, OperatingPoint], settings: dict[str, Any]
) -> list[tuple[str, OperatingPoint, dict[str, list[tuple[Curve, Case]]]]]:
    """Per operating point, its cases grouped by scenario file; every scenario the cases make is
    checked before anything runs (a bad setting is refused naming the key)."""
    clash = sorted(set(settings) & set(KNOBS))
    if clash:
        raise ConfigError(
            f"--set {clash[0]}: the fronts study sweeps it itself (--lambda-sw, --lambda-u, "
            f"--fsw-khz choose its values)"
        )
    plans = []
    for name, op in study.items():
        by_scenario: dict[str, list[tuple[Curve, Case]]] = {}
        for c in op.curves:
            for v in c.values:
                case = Case(c.strategy, {**settings, **c.settings, c.knob: v})
                by_scenario.setdefault(c.scenario, []).append((c, case))
        for scenario, pairs in by_scenario.items():
            path = resolve_scenario_path(scenario)
            text = path.read_text(encoding="utf-8")
            seen = set()
            for _, case in pairs:
                key = repr(sorted(case.settings.items()))
                if key in seen:
                    continue
                seen.add(key)
                where = f"{path} with " + ", ".join(f"{k}={v}" for k, v in case.settings.items())
                sc = load_scenario_text(apply_settings(text, case.settings, path), where)
                sc.with_strategy(case.strategy)
                if not sc.plant.period_means:
                    raise ConfigError(
                        f"{where}: the fronts need plant.period_means: true (distortion "
                        f"between the samples)"
                    )
        plans.append((name, op, by_scenario))
    return plans


def reproduce_fronts(
    runner: StudyRuns,
    *,
    figures: str | Path | None = None,
    settings: dict[str, Any] | None = None,
    study: Mapping[str, OperatingPoint] = FRONTS,
) -> FrontsResult:
    """Run every curve of every operating point of ``study`` (in-process, on the local cores or
    the Dask cluster of ``runner``) and compare the fronts. ``settings`` apply to every run
    (e.g. a real drive's delay with its compensation); a shortened run (``runner.duration``)
    clips the windows: a quick look, not the study."""
    settings = dict(settings or {})
    plans = _plans(study, settings)
    t0 = time.perf_counter()
    tables = []
    for name, op, groups in plans:
        rows: dict[tuple[str, float], Any] = {}
        for scenario, pairs in groups.items():
            cases = [
                dataclasses.replace(case, bag=runner.bag(f"fronts_{name}_{curve.name}_{i}"))
                for i, (curve, case) in enumerate(pairs)
            ]
            for (curve, case), row in zip(pairs, runner.runs(scenario, cases)):
                rows[(curve.name, case.settings[curve.knob])] = row
        tables.append(_table(name, op, rows))
    out = FrontsResult(
        scenario=FRONTS_STUDY,
        engine=runner.where,
        duration=runner.duration,
        settings=settings,
        paper="each strategy's distortion against its switching frequency at a steady "
        "operating point, FOC + SVPWM the baseline",
        how=_HOW,
        frequencies=COMMON_FSW,
        points=tables,
        runs=sum(len(pairs) for _, _, groups in plans for pairs in groups.values()),
        wall_s=time.perf_counter() - t0,
    )
    if figures is None:
        return out
    from ..reports.figures import fronts_figures, save

    drawn = save(fronts_figures(out), figures, prefix="fronts_")
    return dataclasses.replace(out, figures=drawn)


def _table(name: str, op: OperatingPoint, rows: Mapping[tuple[str, float], Any]) -> FrontTable:
    t_ref = abs(load_scenario(op.curves[0].scenario).speed_pi_params.torque_values[-1])
    curves = []
    for c in op.curves:
        figs = []
        for v in c.values:
            m = rows[(c.name, v)].metrics
            f = {k: float(getattr(m, k)) for k in SHOWN}
            miss = math.sqrt(max(0.0, f["t_rmse_cont"] ** 2 - f["t_ripple_cont"] ** 2))
            figs.append((v, f, miss <= HOLD_SHARE * t_ref, rows[(c.name, v)].wall_s))
        fronts = {
            key: pareto(
                [(f["f_sw_hz"], f[key]) if ok else (math.nan, math.nan) for _, f, ok, _ in figs]
            )
            for key in RANKED
        }
        points = [
            FrontPoint(v, f, ok, {k: fronts[k][i] for k in RANKED}, wall)
            for i, (v, f, ok, wall) in enumerate(figs)
        ]
        curves.append(FrontCurve(c.name, c.strategy, c.scenario, c.knob, c.settings, points))
    at = {
        key: {c.name: [interpolate(c.front(key), f) for f in COMMON_FSW] for c in curves}
        for key in RANKED
    }
    ranking = {key: [_ranked(at[key], i) for i in range(len(COMMON_FSW))] for key in RANKED}
    return FrontTable(
        name, op.caption, curves, at, ranking, op.papers_ranking, op.papers_source, t_ref
    )


def _ranked(values: Mapping[str, list[float | None]], i: int) -> list[str]:
    """The curves with a figure at frequency ``i``, lowest first."""
    known = [(x, n) for n, v in values.items() if (x := v[i]) is not None]
    return [n for _, n in sorted(known)]
