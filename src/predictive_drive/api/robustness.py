"""``predictive-drive reproduce robustness``: each point's strategies ranked over N drawn drives
(:mod:`predictive_drive.reports.robustness`), the same drives for every strategy (common random
numbers), run as one sweep on the local cores or a Dask cluster; per strategy the mean of each
figure with its 95 % interval and the chance of ranking first with its interval; beside them the
single-error conditions (a 20 % L_q error, saturation) run once (docs/reproduction.md#robustness).
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import apply_settings, load_scenario_text, parse_yaml, resolve_scenario_path
from ..errors import ConfigError
from ..reports.robustness import RANKED, ROBUSTNESS, SHOWN, RobustnessPoint
from .draws import Spread, StrategyFigures, draw_cases, drawn, figure, parse_spread, summarize
from .study import Reproduction, StudyRuns
from .sweep import Case, Row

__all__ = [
    "ROBUSTNESS_STUDY",
    "PointResult",
    "RobustnessResult",
    "reproduce_robustness",
    "robustness_points",
]

ROBUSTNESS_STUDY = "robustness"
#: a condition's value that copies the plant's group of that name (the controller given the
#: plant's own flux map: ``torque_controller.saturation``)
COPY_PLANT = "plant"

_HOW = (
    "N drives drawn per point: each spread key's value times 1 + S·z (normal) or 1 + S·u "
    "(uniform in -1..1), each key its own stream of the seed; every strategy runs on the same N "
    "drives (common random numbers), the controller keeping its nominal model. Mean with its "
    "95 % interval by the t-distribution (n - 1 degrees of freedom); P(first): the share of "
    "drives on which the strategy has the lowest figure (a tie shares the drive), with its "
    "95 % Wilson score interval. T_RMSE: true torque against T* over the scenario's window; "
    "THD: phase-a current over the THD window; f_sw: turn-on events per device per second. "
    "Conditions: one run per strategy on the nominal drive and with one error each (the "
    "plant's L_q 20 % above or below the controller's; the plant saturating, L_q down 20 % "
    "at rated current); degradation: the condition's T_RMSE over the nominal's."
)


@dataclass(frozen=True)
class PointResult:
    """One point: its drives' spreads, each strategy's figures over them (``figures``) and raw
    values (``values[strategy][key]``, draw by draw: what the box plots draw), and each
    condition's single run (``conditions[name][strategy][key]``)."""

    point: str
    caption: str
    scenario: str
    spreads: list[str]
    settings: dict[str, Any]
    figures: list[StrategyFigures]
    values: dict[str, dict[str, list[float]]]
    conditions: dict[str, dict[str, dict[str, float]]]
    papers_ranking: tuple[str, ...]
    papers_source: str

    def ranking(self, key: str) -> list[str]:
        """The strategies by their mean figure over the drives, lowest first."""
        means = {f.strategy: f.mean[key].value for f in self.figures}
        return sorted((s for s in means if math.isfinite(means[s])), key=means.__getitem__)

    def as_dict(self) -> dict[str, Any]:
        return {
            "point": self.point,
            "caption": self.caption,
            "scenario": self.scenario,
            "spreads": self.spreads,
            "settings": self.settings,
            "figures": [f.as_dict() for f in self.figures],
            "ranking": {k: self.ranking(k) for k in RANKED},
            "values": self.values,
            "conditions": self.conditions,
            "papers_ranking": list(self.papers_ranking),
            "papers_source": self.papers_source,
        }


@dataclass(frozen=True)
class RobustnessResult(Reproduction):
    """``reproduce robustness``: every point's strategies over the drawn drives."""

    draws: int
    seed: int
    shown: tuple[str, ...]
    ranked: tuple[str, ...]
    points: list[PointResult]
    runs: int
    wall_s: float
    figures: list[Path] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            **self.head(),
            "draws": self.draws,
            "seed": self.seed,
            "shown": list(self.shown),
            "ranked": list(self.ranked),
            "runs": self.runs,
            "wall_s": self.wall_s,
            "points": [p.as_dict() for p in self.points],
        }
        if self.figures:
            out["figures"] = [str(p) for p in self.figures]
        return out


def robustness_points(
    names: Sequence[str] | None, spreads: Sequence[str] = ()
) -> dict[str, RobustnessPoint]:
    """The study's points (``names``: a choice of them, None: all), each with ``spreads``
    (``KEY=normal:S``) replacing its own of the same key or added; ConfigError names what is
    wrong before anything runs."""
    chosen = list(ROBUSTNESS) if not names else list(names)
    unknown = [n for n in chosen if n not in ROBUSTNESS]
    if unknown:
        raise ConfigError(
            f"--points {unknown[0]}: not a point of the robustness study; one of "
            f"{', '.join(ROBUSTNESS)}"
        )
    given = {s.key: s for s in (parse_spread(t) for t in spreads)}
    out = {}
    for n in chosen:
        p = ROBUSTNESS[n]
        own = {s.key: s for s in (parse_spread(t) for t in p.spreads)}
        merged = {**own, **given}
        out[n] = dataclasses.replace(p, spreads=tuple(s.text for s in merged.values()))
    return out


def _text(scenario: str) -> str:
    return resolve_scenario_path(scenario).read_text(encoding="utf-8")


def _copied(scenario: str, settings: dict[str, Any]) -> dict[str, Any]:
    """Settings with :data:`COPY_PLANT` values replaced by the plant's group of that name."""
    if COPY_PLANT not in settings.values():
        return settings
    path = resolve_scenario_path(scenario)
    plant = parse_yaml(path.read_text(encoding="utf-8"), path)["/drive/plant"]["ros__parameters"]
    out = dict(settings)
    for k, v in settings.items():
        if v == COPY_PLANT:
            group = k.rsplit(".", 1)[-1]
            if group not in plant:
                raise ConfigError(f"{path}: the plant has no {group!r} group to copy into {k}")
            out[k] = plant[group]
    return out


def reproduce_robustness(
    runner: StudyRuns,
    *,
    draws: int,
    seed: int,
    points: dict[str, RobustnessPoint],
    figures: str | Path | None = None,
    settings: dict[str, Any] | None = None,
) -> RobustnessResult:
    """The study: every point's strategies on ``draws`` drives of ``seed``, and its conditions.
    Every drive is drawn and checked, every condition loaded, before anything runs; a drive a
    strategy fails on (its currents leave a flux map, ...) counts as failed, not as a figure."""
    t0 = time.perf_counter()
    settings = dict(settings or {})
    plans = []
    for name, p in points.items():
        base = {**p.settings, **settings}
        spreads = [parse_spread(s) for s in p.spreads]
        drives = drawn(p.scenario, spreads, draws, seed, base)
        cases = draw_cases([Case(s, dict(base)) for s in p.strategies], drives)
        for i, c in enumerate(cases):
            assert c.draw is not None
            bag = runner.bag(f"reproduce_robustness_{name}_{c.strategy}_draw{c.draw['index']}")
            cases[i] = dataclasses.replace(c, bag=bag)
        single = []
        for cond, cs in p.conditions.items():
            extra = _copied(p.scenario, {**base, **cs})
            for s in p.strategies:
                bag = runner.bag(f"reproduce_robustness_{name}_{s}_{cond.replace(' ', '_')}")
                single.append((cond, Case(s, extra, bag)))
        for cond, c in single[:: max(1, len(p.strategies))]:  # each condition, loaded
            where = f"{p.scenario} with the condition {cond!r}"
            load_scenario_text(apply_settings(_text(p.scenario), c.settings, where), where)
        plans.append((name, p, spreads, cases, single, base))
    results = []
    runs = 0
    for name, p, spreads, cases, single, base in plans:
        rows = runner.runs(p.scenario, [*cases, *(c for _, c in single)], failures=True)
        runs += len(rows)
        drive_rows, single_rows = rows[: len(cases)], rows[len(cases) :]
        results.append(_point(name, p, spreads, drive_rows, single, single_rows, base))
    out = RobustnessResult(
        scenario=ROBUSTNESS_STUDY,
        engine=runner.where,
        duration=runner.duration,
        settings=settings,
        paper="each family's strategies ranked over many drawn drives: model error and "
        "saturation as distributions, with confidence intervals",
        how=_HOW,
        draws=draws,
        seed=seed,
        shown=SHOWN,
        ranked=RANKED,
        points=results,
        runs=runs,
        wall_s=time.perf_counter() - t0,
    )
    if figures is None:
        return out
    from ..reports.figures import robustness_figures, save

    table = {r.point: r.values for r in out.points}
    drawn_figures = save(robustness_figures(table, SHOWN), figures, prefix="robustness_")
    return dataclasses.replace(out, figures=drawn_figures)


def _point(
    name: str,
    p: RobustnessPoint,
    spreads: Sequence[Spread],
    drive_rows: Sequence[Row],
    single: Sequence[tuple[str, Case]],
    single_rows: Sequence[Row],
    base: dict[str, Any],
) -> PointResult:
    keys = [s.key for s in spreads]
    figures = summarize(drive_rows, SHOWN, RANKED, keys)
    values = {
        s: {k: [figure(r, k) for r in drive_rows if r.strategy == s] for k in SHOWN}
        for s in p.strategies
    }
    conditions: dict[str, dict[str, dict[str, float]]] = {}
    for (cond, _), row in zip(single, single_rows):
        conditions.setdefault(cond, {})[row.strategy] = {k: figure(row, k) for k in SHOWN}
    return PointResult(
        name, p.caption, p.scenario, [s.text for s in spreads], base, figures, values,
        conditions, p.papers_ranking, p.papers_source,
    )  # fmt: skip
