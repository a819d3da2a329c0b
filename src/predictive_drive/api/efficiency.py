"""``predictive-drive reproduce efficiency``: the drive's efficiency η over a torque-speed grid
of steady points, one map per strategy family on one machine
(:mod:`predictive_drive.reports.efficiency`), run as a sweep on the local cores or a Dask
cluster; each point checked against its operating point as the fronts check theirs, the ones
that left it blank and listed (docs/reproduction.md#efficiency-maps)."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import apply_settings, load_scenario_text, resolve_scenario_path
from ..core.control.mtpa import mtpa_point
from ..core.machines import Machine
from ..core.scenario import Scenario
from ..errors import ConfigError
from ..reports.efficiency import (
    EFFICIENCY,
    RAMP_STEPS,
    SETTLE_S,
    SHOWN,
    EfficiencyMap,
    EfficiencyStudy,
)
from ..reports.fronts import TOLERANCE
from .fronts import base_current, held, prediction_setting
from .study import Reproduction, StudyRuns
from .sweep import Case

__all__ = [
    "EFFICIENCY_STUDY",
    "EfficiencyChoice",
    "EfficiencyPoint",
    "EfficiencyResult",
    "MapResult",
    "grid_settings",
    "mtpa_flux",
    "reproduce_efficiency",
]

EFFICIENCY_STUDY = "efficiency"

_HOW = (
    "each point one run at a steady operating point: the shaft held at the speed by a load "
    "machine, T* ramped over 10 ms and held, psi* the MTPA flux of T*; the figures over a "
    "window from 0.05 s, at least 0.2 s and two electrical periods long. eta = the energy into "
    "the load over the energy from the DC link (its equations' plus the switching and iron "
    "losses) over the window; P_inverter the six transistors' and diodes' conduction and "
    "switching losses, P_machine the copper and iron losses, each strategy at its own "
    "switching frequency. A point holds its operating point when its mean torque lies within "
    "2 % of T*, its mean |psi_s| within 2 % of psi* and its current's fundamental within 2 % "
    "of the MTPA current of T*, all in continuous time, as on the fronts; the others are blank "
    "on their map and listed."
)


@dataclass(frozen=True)
class EfficiencyPoint:
    """One run of a map: the point (r/min, N·m), its figures (:data:`~..reports.efficiency.
    SHOWN`, by metric key), how far it missed the operating point (signed shares), whether it
    held it (and if not why)."""

    speed_rpm: float
    torque: float
    figures: dict[str, float]
    misses: dict[str, float]
    holds: bool
    reason: str
    wall_s: float


@dataclass(frozen=True)
class MapResult:
    """A strategy's map: its points, speed by speed within torque by torque (rising)."""

    name: str
    strategy: str
    scenario: str
    settings: dict[str, Any]
    points: list[EfficiencyPoint]

    def grid(self, key: str, speeds: Sequence[float], torques: Sequence[float]) -> list[list[
            float | None]]:  # fmt: skip
        """Figure ``key`` as rows of torque by columns of speed; None where the point did not
        hold its operating point."""
        at = {(p.torque, p.speed_rpm): p for p in self.points}
        return [
            [
                at[(t, n)].figures[key] if at[(t, n)].holds else None
                for n in speeds
            ]
            for t in torques
        ]  # fmt: skip


@dataclass(frozen=True)
class EfficiencyResult(Reproduction):
    """``reproduce efficiency``: every map of the study, with the grid, the settings every run
    had and the points that left their operating point."""

    caption: str
    speeds_rpm: tuple[float, ...]
    torques: tuple[float, ...]
    every_run: dict[str, Any]
    tolerance: dict[str, float]
    maps: list[MapResult]
    runs: int
    wall_s: float
    figures: list[Path] = field(default_factory=list)

    def excluded(self) -> list[tuple[str, EfficiencyPoint]]:
        """(map, point) of every point that left its operating point."""
        return [(m.name, p) for m in self.maps for p in m.points if not p.holds]

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            **self.head(),
            "caption": self.caption,
            "speeds_rpm": list(self.speeds_rpm),
            "torques": list(self.torques),
            "every_run": self.every_run,
            "tolerance": self.tolerance,
            "runs": self.runs,
            "wall_s": self.wall_s,
            "maps": [
                {
                    **dataclasses.asdict(m),
                    "efficiency": m.grid("efficiency", self.speeds_rpm, self.torques),
                }
                for m in self.maps
            ],
            "excluded": [
                {"map": name, "speed_rpm": p.speed_rpm, "torque": p.torque, "reason": p.reason}
                for name, p in self.excluded()
            ],
        }
        if self.figures:
            out["figures"] = [str(p) for p in self.figures]
        return out


@dataclass(frozen=True)
class EfficiencyChoice:
    """What of the study a user runs (``reproduce efficiency`` options): the maps by name and
    the grid's speeds (r/min) and torques (N·m); None: all of the study's."""

    maps: Sequence[str] | None = None
    speeds_rpm: Sequence[float] | None = None
    torques: Sequence[float] | None = None

    def study(self, base: EfficiencyStudy = EFFICIENCY) -> EfficiencyStudy:
        """The study this choice makes of ``base``; ConfigError names a map it has not (listing
        those it has) or a speed or torque that is not a positive number."""
        names = [m.name for m in base.maps]
        for n in self.maps or ():
            if n not in names:
                raise ConfigError(f"--maps {n}: no map of that name; the maps: {', '.join(names)}")
        for option, values in (("--speeds-rpm", self.speeds_rpm), ("--torques", self.torques)):
            if values is not None and not values:
                raise ConfigError(f"{option}: give at least one value")
            for v in values or ():
                if not (math.isfinite(v) and v > 0):
                    raise ConfigError(f"{option}: {v!r} is not a positive number")
        return dataclasses.replace(
            base,
            maps=tuple(m for m in base.maps if self.maps is None or m.name in self.maps),
            speeds_rpm=tuple(self.speeds_rpm or base.speeds_rpm),
            torques=tuple(self.torques or base.torques),
        )


def mtpa_flux(sc: Scenario, torque: float) -> float:
    """|ψ_s| (Wb) of the MTPA point of ``torque`` (N·m) on the scenario's machine (paper 002
    eq 8, 10): ψ_d = L_d·i_d + ψ_f, ψ_q = L_q·i_q at the MTPA current and angle."""
    m = sc.plant.motor
    point = mtpa_point(torque, p=m.p, psi_f=m.psi_f, l_d=m.l_d, l_q=m.l_q)
    i_d, i_q = -point.i_s * math.sin(point.theta), point.i_s * math.cos(point.theta)
    return math.hypot(m.l_d * i_d + m.psi_f, m.l_q * i_q)


def grid_settings(
    sc: Scenario, speed_rpm: float, torque: float, min_window: float
) -> dict[str, Any]:
    """The settings that make scenario ``sc`` (a steady one) the grid point: the speed held,
    T* ramped over :data:`~..reports.efficiency.RAMP_STEPS` half-milliseconds and held, ψ* its
    MTPA flux, the window from :data:`~..reports.efficiency.SETTLE_S` at least ``min_window``
    s and two electrical periods long."""
    period = 60.0 / (speed_rpm * sc.plant.motor.p)
    end = SETTLE_S + max(min_window, 2.0 * period)
    ramp = [torque * (k + 1) / RAMP_STEPS for k in range(RAMP_STEPS)]
    return {
        "duration": end,
        "plant.held_speed_times": [0.0],
        "plant.held_speed_rpm": [speed_rpm],
        "speed_pi.speed_times": [0.0],
        "speed_pi.speed_values_rpm": [speed_rpm],
        "speed_pi.torque_times": [5e-4 * k for k in range(RAMP_STEPS)],
        "speed_pi.torque_values": ramp,
        "speed_pi.flux_ref": round(mtpa_flux(sc, torque), 6),
        "metrics_logger.window_start": SETTLE_S,
        "metrics_logger.window_end": end,
        "metrics_logger.thd_window": [SETTLE_S, end],
    }


@dataclass(frozen=True)
class _Plan:
    """A map's cases, the grid point each is, and the scenario it loads (with its settings)."""

    map: EfficiencyMap
    cases: list[Case]
    at: list[tuple[float, float]]
    loaded: Scenario


def _plans(study: EfficiencyStudy, settings: dict[str, Any]) -> list[_Plan]:
    """Each map's cases; every scenario they make is loaded before anything runs (a bad setting
    is refused naming the key)."""
    plans = []
    for m in study.maps:
        path = resolve_scenario_path(m.scenario)
        text = path.read_text(encoding="utf-8")
        base = load_scenario_text(text, path)
        if base.machine != Machine.PMSM:
            raise ConfigError(f"{m.scenario}: the efficiency maps take a PMSM's steady scenario")
        clash = sorted(set(settings) & set(grid_settings(base, 1.0, 1.0, study.min_window)))
        if clash:
            raise ConfigError(f"--set {clash[0]}: the efficiency study sets it at every grid point")
        extra = {**study.settings, **prediction_setting(base), **settings, **m.settings}
        cases, at = [], []
        loaded: Scenario | None = None
        for t in study.torques:
            for n in study.speeds_rpm:
                case = Case(m.strategy, {**extra, **grid_settings(base, n, t, study.min_window)})
                where = f"{path} at {n:g} r/min, {t:g} N·m"
                sc = load_scenario_text(apply_settings(text, case.settings, path), where)
                sc.with_strategy(case.strategy)
                loaded = loaded or sc
                cases.append(case)
                at.append((n, t))
        assert loaded is not None  # a study has at least one point (checked by its choice)
        plans.append(_Plan(m, cases, at, loaded))
    return plans


def reproduce_efficiency(
    runner: StudyRuns,
    *,
    figures: str | Path | None = None,
    settings: dict[str, Any] | None = None,
    study: EfficiencyStudy = EFFICIENCY,
) -> EfficiencyResult:
    """Run every map of ``study`` over its grid (in-process, on the local cores or the Dask
    cluster of ``runner``), each point checked against its operating point. ``settings`` apply
    to every run besides the study's own."""
    settings = dict(settings or {})
    plans = _plans(study, settings)
    t0 = time.perf_counter()
    maps = []
    for plan in plans:
        cases = [
            dataclasses.replace(case, bag=runner.bag(f"efficiency_{plan.map.name}_{i}"))
            for i, case in enumerate(plan.cases)
        ]
        rows = runner.runs(
            plan.map.scenario,
            cases,
            names=[f"{plan.map.name} {n:g} r/min {t:g} N·m" for n, t in plan.at],
        )
        points = [_point(plan.loaded, n, t, row) for (n, t), row in zip(plan.at, rows)]
        maps.append(
            MapResult(
                plan.map.name, plan.map.strategy, plan.map.scenario, plan.map.settings, points
            )  # fmt: skip
        )
    out = EfficiencyResult(
        scenario=EFFICIENCY_STUDY,
        engine=runner.where,
        duration=runner.duration,
        settings=settings,
        paper="the drive's efficiency over a torque-speed grid, one map per strategy family",
        how=_HOW,
        caption=study.caption,
        speeds_rpm=study.speeds_rpm,
        torques=study.torques,
        every_run=dict(study.settings),
        tolerance=dict(TOLERANCE),
        maps=maps,
        runs=sum(len(p.cases) for p in plans),
        wall_s=time.perf_counter() - t0,
    )
    if figures is None:
        return out
    from ..reports.figures import efficiency_figures, save

    drawn = save(efficiency_figures(out), figures, prefix="efficiency_")
    return dataclasses.replace(out, figures=drawn)


def _point(sc: Scenario, speed_rpm: float, torque: float, row: Any) -> EfficiencyPoint:
    """A run's point: its figures and whether it held T*, the MTPA flux and current of T*."""
    m = row.metrics
    base, _ = base_current(sc, torque, 0.0)
    misses, reason = held(m, torque, mtpa_flux(sc, torque), base)
    figures = {k: float(getattr(m, k)) for k in SHOWN}
    return EfficiencyPoint(speed_rpm, torque, figures, misses, not reason, reason, row.wall_s)
