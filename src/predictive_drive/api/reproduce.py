"""``predictive-drive reproduce``: every row of a paper's table run again (in parallel across the
cores), our figures beside the paper's (:mod:`predictive_drive.reports.papers`); and the MTPA
studies, every strategy at every load step with and without parameter mismatch; and the realism
study, the papers' strategies on a drive with computation delay, dead time and sensors."""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import (
    apply_settings,
    load_scenario,
    load_scenario_text,
    resolve_scenario_path,
)
from ..core.analysis import load_steps
from ..core.control.mtpa import mtpa_point
from ..core.metrics import unequal_switching
from ..core.scenario import Scenario
from ..core.trace import Trace
from ..errors import ConfigError
from ..outputs import check_output_dir
from ..reports.fronts import FRONTS
from ..reports.papers import MTPA_STUDIES, PAPER_TABLES, Column, MTPAStudy
from ..reports.realism import (
    CONDITIONS,
    HARDWARE_KEYS,
    RANKED,
    REALISM,
    SHOWN,
    STUDY_KEY,
    condition_settings,
)
from ..reports.robustness import DEFAULT_DRAWS, DEFAULT_SEED
from .compare import compare
from .controller_replay import controller_replay
from .efficiency import (
    EFFICIENCY_STUDY,
    EfficiencyChoice,
    EfficiencyResult,
    reproduce_efficiency,
)
from .fronts import FRONTS_STUDY, FrontsChoice, FrontsResult, reproduce_fronts
from .robustness import (
    ROBUSTNESS_STUDY,
    RobustnessResult,
    reproduce_robustness,
    robustness_points,
)
from .study import Reproduction, StudyRuns, studying
from .sweep import Case, Row

__all__ = [
    "FRONTS_STUDY",
    "ROBUSTNESS_STUDY",
    "STUDIES",
    "MTPAClaim",
    "MTPARow",
    "MTPAStudyResult",
    "PaperTableResult",
    "RealismCell",
    "RealismResult",
    "Reproduction",
    "TableRow",
    "mtpa_steps",
    "reproduce",
    "reproduce_realism",
]

#: the named study that is neither a paper's table nor an MTPA study
REALISM_STUDY = "realism"
#: the studies across scenarios (each a sweep, in-process, on the local cores or Dask)
STUDIES = (REALISM_STUDY, FRONTS_STUDY, ROBUSTNESS_STUDY, EFFICIENCY_STUDY)

#: the figures of a table row, by metric key (:data:`~..core.metrics.METRICS`)
TABLE_FIGURES = (
    "t_rmse", "psi_rmse", "f_ave_hz", "f_sw_hz", "cal_ave", "deadbeat_share", "zero_share", "thd",
    "thd_harmonics", "compute_us_per_step",
)  # fmt: skip


@dataclass
class TableRow:
    """One row of a reproduced table: its label, strategy and settings, our ``figures`` and the
    paper's (``paper``), both by metric key, and the run's bag. With compute ratios, also
    whether the timing replay decided as recorded (``replay_identical``)."""

    label: str
    strategy: str
    settings: dict[str, Any]
    figures: dict[str, float]
    paper: dict[str, float]
    bag: str | None
    wall_s: float
    replay_identical: bool | None = None

    def as_dict(self) -> dict[str, Any]:
        out = {
            "label": self.label,
            "strategy": self.strategy,
            "settings": self.settings,
            **self.figures,
            "paper": self.paper,
            "bag": self.bag,
            "wall_s": self.wall_s,
        }
        if self.replay_identical is not None:
            out["replay_identical"] = self.replay_identical
        return out


@dataclass(frozen=True)
class PaperTableResult(Reproduction):
    """``reproduce`` of a paper's table: every row run again, ours beside the paper's."""

    columns: tuple[Column, ...]
    rows: list[TableRow]
    figures: list[Path] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        out = {**self.head(), "rows": [r.as_dict() for r in self.rows]}
        if self.figures:
            out["figures"] = [str(p) for p in self.figures]
        return out


@dataclass(frozen=True)
class MTPARow:
    """One load step of one run of an MTPA study: the strategy (and injection form), the
    controller's L_d, L_q factors, and where the current settled (measured) against the true
    MTPA point."""

    strategy: str
    form: str | None
    mismatch: dict[str, float]
    load_torque: float
    theta_deg: float
    theta_mtpa_deg: float
    i_s: float
    i_s_mtpa: float
    i_s_zero_d: float
    settle_s: float
    t_start: float
    t_end: float
    bag: str | None

    @property
    def exact(self) -> bool:
        """The controller's inductances equal the plant's."""
        return self.mismatch["l_d"] == 1.0 and self.mismatch["l_q"] == 1.0


@dataclass(frozen=True)
class MTPAClaim:
    """Paper 002's claims at one load, checked on the corrected injection at exact parameters:
    settling under a second, and less current than i_d = 0 (measured, against the
    measurement's resolution): ``less_current_than_zero_d`` is confirmed, refuted or not
    resolved."""

    load_torque: float
    settle_s: float
    settles_under_1_s: bool
    i_s: float
    i_s_zero_d_measured: float
    saving_vs_zero_d: float
    saving_possible: float
    resolution: float
    less_current_than_zero_d: str


@dataclass(frozen=True)
class MTPAStudyResult(Reproduction):
    """``reproduce`` of an MTPA study: every run's load steps, and the paper's claims."""

    rows: list[MTPARow]
    claims: list[MTPAClaim]
    figures: list[Path] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        out = {
            **self.head(),
            "rows": [dataclasses.asdict(r) for r in self.rows],
            "claims": [dataclasses.asdict(c) for c in self.claims],
        }
        if self.figures:
            out["figures"] = [str(p) for p in self.figures]
        return out


@dataclass(frozen=True)
class RealismCell:
    """One run of the realism study: a strategy of a scenario under one column's conditions,
    its figures (:data:`~..reports.realism.SHOWN`, by metric key) and its rank among the
    scenario's strategies in that column by each of :data:`~..reports.realism.RANKED` (1 =
    lowest; None where the figure is not a number)."""

    scenario: str
    strategy: str
    condition: str
    settings: dict[str, Any]
    figures: dict[str, float]
    rank: dict[str, int | None]
    wall_s: float


@dataclass(frozen=True)
class RealismResult(Reproduction):
    """``reproduce realism``: every scenario's strategies under every column's conditions. The
    real drive's settings per scenario are in ``hardware``, the study's own per scenario in
    ``scenario_settings``."""

    conditions: tuple[str, ...]
    strategies: dict[str, tuple[str, ...]]
    hardware: dict[str, dict[str, Any]]
    scenario_settings: dict[str, dict[str, Any]]
    cells: list[RealismCell]
    figures: list[Path] = field(default_factory=list)

    def cell(self, scenario: str, strategy: str, condition: str) -> RealismCell:
        for c in self.cells:
            if (c.scenario, c.strategy, c.condition) == (scenario, strategy, condition):
                return c
        raise KeyError((scenario, strategy, condition))

    def unequal_fsw(self) -> dict[str, dict[str, str]]:
        """Per scenario and column, the sentence saying its strategies' switching frequencies
        differ too much for their ranks to compare them at equal f_sw (columns where they do
        not are left out)."""
        out: dict[str, dict[str, str]] = {}
        for scenario, strategies in self.strategies.items():
            for c in self.conditions:
                f = {s: self.cell(scenario, s, c).figures["f_sw_hz"] for s in strategies}
                if (text := unequal_switching(f)) is not None:
                    out.setdefault(scenario, {})[c] = text
        return out

    def as_dict(self) -> dict[str, Any]:
        out = {
            **self.head(),
            "conditions": list(self.conditions),
            "strategies": {k: list(v) for k, v in self.strategies.items()},
            "hardware": self.hardware,
            "scenario_settings": self.scenario_settings,
            "cells": [dataclasses.asdict(c) for c in self.cells],
            "unequal_fsw": self.unequal_fsw(),
        }
        if self.figures:
            out["figures"] = [str(p) for p in self.figures]
        return out


def _figures(row: Row) -> dict[str, float]:
    """A run's figures for a table row, by metric key."""
    m = row.metrics
    assert m is not None  # a failed case failed the reproduction (_runs)
    return {
        "t_rmse": m.t_rmse,
        "psi_rmse": m.psi_rmse,
        "f_ave_hz": m.f_ave_hz,
        "f_sw_hz": m.f_sw_hz,
        "cal_ave": m.cal_ave,
        "deadbeat_share": m.deadbeat_share,
        "zero_share": m.utilization[0],
        "thd": m.thd,
        "thd_harmonics": m.thd_harmonics,
        "compute_us_per_step": m.compute_ns_median / 1e3,
        "compute_us_mean": m.compute_ns_mean / 1e3,
    }


def reproduce(
    scenario: str,
    *,
    engine: str = "inprocess",
    out_root: str | Path | None = None,
    jobs: int | None = None,
    repeats: int = 5,
    duration: float | None = None,
    figures: str | Path | None = None,
    settings: dict[str, Any] | None = None,
    scheduler: str | None = None,
    progress: Callable[..., None] | None = None,
    fronts: FrontsChoice | None = None,
    draws: int | None = None,
    seed: int | None = None,
    points: Sequence[str] | None = None,
    spreads: Sequence[str] = (),
    efficiency: EfficiencyChoice | None = None,
) -> (
    PaperTableResult | MTPAStudyResult | RealismResult | FrontsResult | RobustnessResult
    | EfficiencyResult
):  # fmt: skip
    """Run every row of a paper's table (independent runs in parallel across the cores) and set
    our figures beside the paper's, or run an MTPA study, or the realism study
    (:func:`reproduce_realism`, the one that runs on a Dask cluster at ``scheduler`` too).
    ``duration`` shortens every run (a quick look; the figures then do not compare with the
    paper's). ``figures``: a folder for the runs drawn overlaid (PNG). ``settings``: scenario
    settings applied to every run (e.g. ``{"speed_pi.speed_loop": "immediate"}``), besides each
    row's own. ``out_root``: keep every run's bag in this folder (None: the bags a study needs
    go to a temporary folder, removed at the end). ``progress(done, planned[, name])``: told as
    each run ends. The fronts study (:func:`~.fronts.reproduce_fronts`) runs what ``fronts``
    chooses of it (its knobs' values, points, curves, a controller of one's own); the
    robustness study (:func:`~.robustness.reproduce_robustness`) draws ``draws`` drives by
    ``seed`` at ``points`` (None: all), ``spreads`` replacing or adding to each point's; the
    efficiency study (:func:`~.efficiency.reproduce_efficiency`) runs the maps and grid
    ``efficiency`` chooses."""
    settings = dict(settings or {})
    robust = (draws, seed, points)
    if scenario != ROBUSTNESS_STUDY and (any(x is not None for x in robust) or spreads):
        raise ConfigError(
            f"reproduce {scenario}: --draws, --seed, --points and --spread choose the "
            f"robustness study's drives"
        )
    if scenario != FRONTS_STUDY and fronts is not None and fronts != FrontsChoice():
        raise ConfigError(
            f"reproduce {scenario}: --lambda-sw, --lambda-u, --fsw-khz, --periods-us, --points, "
            f"--curves, --no-horizons, --external, --label and --knob choose the fronts study's "
            f"runs"
        )
    if scenario != EFFICIENCY_STUDY and efficiency is not None and efficiency != EfficiencyChoice():
        raise ConfigError(
            f"reproduce {scenario}: --maps, --speeds-rpm and --torques choose the efficiency "
            f"study's runs"
        )
    if scenario in STUDIES:
        if engine != "inprocess":
            raise ConfigError(
                f"reproduce {scenario} runs as a sweep (in-process, on the local cores or a "
                f"Dask cluster), not on the {engine} engine: every engine gives the same figures"
            )
    elif scheduler is not None:
        raise ConfigError(
            f"reproduce {scenario}: a Dask scheduler serves the realism, fronts, robustness and "
            f"efficiency studies only (the tables' bags are drawn and timed here)"
        )
    elif scenario not in MTPA_STUDIES and scenario not in PAPER_TABLES:
        raise ConfigError(
            f"reproduce: no paper table or study {scenario!r}; available: "
            f"{', '.join([*PAPER_TABLES, *MTPA_STUDIES, *STUDIES])}"
        )
    if scenario == FRONTS_STUDY:  # its knobs, checked before anything runs
        study = (fronts or FrontsChoice()).study(FRONTS)
    if scenario == ROBUSTNESS_STUDY:
        chosen = robustness_points(points, spreads)
    if scenario == EFFICIENCY_STUDY:
        grid = (efficiency or EfficiencyChoice()).study()
    check_output_dir(figures, option="--figures")  # before the work, not after it
    with studying(
        out_root,
        engine=engine,
        duration=duration,
        jobs=jobs,
        scheduler=scheduler,
        progress=progress,
    ) as runner:
        result: PaperTableResult | MTPAStudyResult | RealismResult | FrontsResult
        result_r: RobustnessResult
        if scenario == ROBUSTNESS_STUDY:
            result_r = reproduce_robustness(
                runner,
                draws=DEFAULT_DRAWS if draws is None else draws,
                seed=DEFAULT_SEED if seed is None else seed,
                points=chosen,
                figures=figures,
                settings=settings,
            )
            return dataclasses.replace(result_r, windows=runner.windows, bags=runner.kept())
        if scenario == EFFICIENCY_STUDY:
            result_e = reproduce_efficiency(runner, figures=figures, settings=settings, study=grid)
            return dataclasses.replace(result_e, windows=runner.windows, bags=runner.kept())
        if scenario == FRONTS_STUDY:
            result = reproduce_fronts(runner, figures=figures, settings=settings, study=study)
        elif scenario == REALISM_STUDY:
            result = reproduce_realism(runner, figures=figures, settings=settings)
        elif scenario in MTPA_STUDIES:
            result = reproduce_mtpa(scenario, runner, figures=figures, settings=settings)
        else:
            result = reproduce_table(
                scenario, runner, repeats=repeats, figures=figures, settings=settings
            )
        kept = runner.kept()
        result = dataclasses.replace(result, windows=runner.windows, bags=kept)
    rows = getattr(result, "rows", None)
    if kept is None and rows is not None:  # their bags went with the temporary folder
        forgotten: Any = [dataclasses.replace(r, bag=None) for r in rows]
        result = dataclasses.replace(result, rows=forgotten)
    return result


def reproduce_table(
    scenario: str,
    runner: StudyRuns,
    *,
    repeats: int = 5,
    figures: str | Path | None = None,
    settings: dict[str, Any] | None = None,
) -> PaperTableResult:
    """A paper's table (:data:`~predictive_drive.reports.papers.PAPER_TABLES`): every row run
    again, ours beside the paper's; with compute ratios, each run's decisions replayed and
    timed afterwards in this process."""
    settings = dict(settings or {})
    table = PAPER_TABLES[scenario]
    cases = []
    for spec in table.rows:
        tag = re.sub(r"[^A-Za-z0-9_.-]", "", spec.name.replace(" ", "_"))
        bag = runner.bag(
            f"reproduce_{scenario}_{tag}", needed=table.compute_ratios or figures is not None
        )
        cases.append(Case(spec.strategy, {**settings, **spec.settings}, bag))
    runs = runner.runs(scenario, cases)
    rows = [
        TableRow(spec.name, r.strategy, r.settings, _figures(r), spec.paper, r.bag, r.wall_s)
        for r, spec in zip(runs, table.rows)
    ]
    if table.compute_ratios:
        # in this process, after the runs: timing must not share the cores. Conventional first:
        # the ratios are relative to it
        order = sorted(rows, key=lambda r: r.strategy != "mptc")
        times = controller_replay([str(r.bag) for r in order], repeats=repeats)
        for r, t in zip(order, times):
            r.replay_identical = t["identical"]
            r.figures.update(
                compute_ns_hot=t["hot_ns"],
                compute_ratio=t["hot_ratio"],
                compute_ns_in_loop=t["loop_ns"],
                compute_ratio_in_loop=t["loop_ratio"],
            )
    drawn = []
    if figures is not None:
        drawn = compare([str(r.bag) for r in rows], figures=figures).figures
    used = "; ".join(f"{lo:.4g}-{hi:.4g} s" for lo, hi in runner.windows[scenario])
    return PaperTableResult(
        scenario,
        runner.engine,
        runner.duration,
        settings,
        table.text(table.caption, used),
        table.text(table.how, used),
        table.columns,
        rows,
        drawn,
    )


def _mtpa_runs(study: MTPAStudy) -> list[tuple[str, dict[str, Any], dict[str, float]]]:
    """(strategy, settings, mismatch factors) of every run of a study."""
    out: list[tuple[str, dict[str, Any], dict[str, float]]] = [
        (s, {}, {"l_d": 1.0, "l_q": 1.0}) for s in study.strategies
    ]
    for f_d, f_q in study.mismatches:
        for s in study.mismatch_strategies:
            settings = {
                "torque_controller.motor.l_d": f"*{f_d}",
                "torque_controller.motor.l_q": f"*{f_q}",
            }
            out.append((s, settings, {"l_d": f_d, "l_q": f_q}))
    printed = {"torque_controller.injection_form": "as_printed"}
    out.append(("foc_injection", printed, {"l_d": 1.0, "l_q": 1.0}))
    return out


def mtpa_steps(trace: Trace, sc: Scenario) -> dict[str, Any]:
    """The load steps of a run of an MTPA study, each with the true machine's MTPA point (run
    in the sweep's worker)."""
    plant = sc.plant.motor
    steps = load_steps(
        trace,
        load_times=sc.plant.load_times,
        load_values=sc.plant.load_values,
        average_s=1.0 / sc.controller.injection_hz,
    )
    out = []
    for st in steps:
        best = mtpa_point(
            st.load_torque, p=plant.p, psi_f=plant.psi_f, l_d=plant.l_d, l_q=plant.l_q
        )
        out.append(
            {
                "load_torque": st.load_torque,
                "theta_deg": math.degrees(st.theta),
                "theta_mtpa_deg": math.degrees(best.theta),
                "i_s": st.i_s,
                "i_s_mtpa": best.i_s,
                "i_s_zero_d": best.i_s_zero_d,
                "settle_s": st.settle_s,
                "t_start": st.t_start,
                "t_end": st.t_end,
            }
        )
    form = sc.controller.injection_form if sc.strategy == "foc_injection" else None
    return {"form": form, "load_steps": out}


def reproduce_mtpa(
    scenario: str,
    runner: StudyRuns,
    *,
    figures: str | Path | None = None,
    settings: dict[str, Any] | None = None,
) -> MTPAStudyResult:
    """An MTPA study (:data:`~predictive_drive.reports.papers.MTPA_STUDIES`): a sweep of the
    strategies over the controller-side inductance mismatches, one row per run and load step;
    the paper's claims checked per load where it makes any. ``figures``: the runs at exact
    parameters drawn overlaid, one per strategy and form."""
    study = MTPA_STUDIES[scenario]
    load_scenario(scenario)  # a bad scenario fails before anything runs
    cases, mismatches = [], []
    for strategy, case_settings, mismatch in _mtpa_runs(study):
        tag = f"{strategy}_ld{mismatch['l_d']:g}_lq{mismatch['l_q']:g}"
        if case_settings.get("torque_controller.injection_form") == "as_printed":
            tag += "_as_printed"
        drawn = mismatch == {"l_d": 1.0, "l_q": 1.0} and figures is not None
        bag = runner.bag(f"reproduce_{scenario}_{tag}", needed=drawn)
        cases.append(Case(strategy, {**(settings or {}), **case_settings}, bag))
        mismatches.append(mismatch)
    runs = runner.runs(scenario, cases, analysis=mtpa_steps)
    rows = [
        MTPARow(
            strategy=r.strategy,
            form=r.extra["form"],
            mismatch=mismatch,
            **step,
            bag=r.bag,
        )
        for r, mismatch in zip(runs, mismatches)
        for step in r.extra["load_steps"]
    ]
    out = MTPAStudyResult(
        scenario=scenario,
        engine=runner.engine,
        duration=runner.duration,
        settings=settings or {},
        paper=study.caption,
        how=study.how,
        rows=rows,
        claims=_check_claims(study, rows),
    )
    if figures is None:
        return out
    bags = list(dict.fromkeys(str(r.bag) for r in rows if r.exact))
    return dataclasses.replace(out, figures=compare(bags, figures=figures).figures)


def _check_claims(study: MTPAStudy, rows: list[MTPARow]) -> list[MTPAClaim]:
    """Per load: does the corrected injection settle under a second, and does it draw less
    current than i_d = 0 (both measured, same scenario, exact parameters)? The current saving is
    judged against the measurement's resolution: how far the i_d = 0 run's measured |i_s| lies
    from the model's, at that load."""
    if not study.claims:
        return []
    zero = {r.load_torque: r for r in rows if r.exact and r.strategy == "foc_zero_d"}
    out = []
    for r in rows:
        corrected = r.strategy == "foc_injection" and r.form == "corrected"
        if not (r.exact and corrected) or r.load_torque not in zero:
            continue
        z = zero[r.load_torque]
        saving = 1.0 - r.i_s / z.i_s
        resolution = abs(z.i_s / z.i_s_zero_d - 1.0)
        verdict = (
            "confirmed"
            if saving > resolution
            else "refuted"
            if saving < -resolution
            else "not resolved"
        )
        out.append(
            MTPAClaim(
                load_torque=r.load_torque,
                settle_s=r.settle_s,
                settles_under_1_s=r.settle_s < 1.0,
                i_s=r.i_s,
                i_s_zero_d_measured=z.i_s,
                saving_vs_zero_d=saving,
                saving_possible=1.0 - r.i_s_mtpa / r.i_s_zero_d,
                resolution=resolution,
                less_current_than_zero_d=verdict,
            )
        )
    return out


def _checked(scenario: str, cases: Sequence[Case]) -> None:
    """Every case's scenario is valid: a bad setting is refused before anything runs, naming
    the key and what it may be."""
    path = resolve_scenario_path(scenario)
    text = path.read_text(encoding="utf-8")
    seen: set[str] = set()
    for c in cases:
        tag = repr(sorted(c.settings.items()))
        if tag in seen:
            continue
        seen.add(tag)
        where = f"{path} with " + ", ".join(f"{k}={v}" for k, v in c.settings.items())
        load_scenario_text(apply_settings(text, c.settings, path), where)


def _ranks(values: dict[str, float]) -> dict[str, int | None]:
    """Each strategy's place by its figure, lowest first (1); None for a figure that is not a
    number. Equal figures share a place."""
    finite = sorted(v for v in values.values() if math.isfinite(v))
    return {s: (finite.index(v) + 1 if math.isfinite(v) else None) for s, v in values.items()}


_REALISM_HOW = (
    "the columns add, left to right: one period of computation delay (the command for step k "
    "acts during period k+1); its compensation (the state at k+1 predicted with the command in "
    "force, the decision made on it); inverter dead time and device drops; the sensors (noise "
    "and ADC rounding of two phase currents, encoder angle, speed over a window). MPTC has no "
    "dead-time compensation. T_RMSE/psi_RMSE of the true torque and flux against the references "
    "over the scenario's window; THD of the true phase-a current over the THD window; f_sw "
    "turn-on events per device per second. Rank: place among the scenario's strategies in that "
    "column, lowest first."
)


def reproduce_realism(
    runner: StudyRuns,
    *,
    figures: str | Path | None = None,
    settings: dict[str, Any] | None = None,
) -> RealismResult:
    """The realism study (:mod:`predictive_drive.reports.realism`): every strategy of paper
    000's induction motor and paper 001's IPMSM, ideal and under each column's conditions, run as
    a sweep on the local cores or the Dask cluster (``runner.scheduler``). ``settings`` of the real
    drive's keys (:data:`~..reports.realism.HARDWARE_KEYS`) replace the study's values in the
    columns that have them; any other applies to every run."""
    settings = dict(settings or {})
    if STUDY_KEY in settings:
        raise ConfigError(
            f"--set {STUDY_KEY}: the realism study sets it itself (false in the 'delay' "
            f"column, true from 'compensated' on)"
        )
    overrides = {k: v for k, v in settings.items() if k in HARDWARE_KEYS}
    common = {k: v for k, v in settings.items() if k not in HARDWARE_KEYS}
    plans = []
    for name, study in REALISM.items():
        hardware = {**study.hardware, **overrides}
        cases, where = [], []
        for strategy in study.strategies:
            for condition, cs in condition_settings(hardware):
                bag = runner.bag(f"reproduce_realism_{name}_{strategy}_{condition}")
                cases.append(Case(strategy, {**study.settings, **common, **cs}, bag))
                where.append(condition)
        _checked(name, cases)
        plans.append((name, hardware, cases, where))
    cells = []
    for name, _, cases, where in plans:
        runs: list[tuple[Row, str, dict[str, float]]] = []
        for row, condition in zip(runner.runs(name, cases), where):
            assert row.metrics is not None  # a failed run failed the study (runner.runs)
            runs.append((row, condition, {k: float(getattr(row.metrics, k)) for k in SHOWN}))
        ranks: dict[tuple[str, str], dict[str, int | None]] = {}
        for condition in CONDITIONS:
            column = [(r.strategy, f) for r, c, f in runs if c == condition]
            for key in RANKED:
                for strategy, place in _ranks({s: f[key] for s, f in column}).items():
                    ranks.setdefault((strategy, condition), {})[key] = place
        cells += [
            RealismCell(name, r.strategy, c, r.settings, f, ranks[(r.strategy, c)], r.wall_s)
            for r, c, f in runs
        ]
    out = RealismResult(
        scenario=REALISM_STUDY,
        engine=runner.where,
        duration=runner.duration,
        settings=settings,
        paper="the papers' strategies on a drive as real drives are: computation delay, "
        "dead time, sensors",
        how=_REALISM_HOW,
        conditions=CONDITIONS,
        strategies={n: s.strategies for n, s in REALISM.items()},
        hardware={n: h for n, h, _, _ in plans},
        scenario_settings={n: {**s.settings, **common} for n, s in REALISM.items()},
        cells=cells,
    )
    if figures is None:
        return out
    from ..reports.figures import realism_figures, save

    table = {
        n: {
            s: {k: [out.cell(n, s, c).figures[k] for c in CONDITIONS] for k in SHOWN}
            for s in strategies
        }
        for n, strategies in out.strategies.items()
    }
    drawn = save(realism_figures(table, CONDITIONS), figures, prefix="realism_")
    return dataclasses.replace(out, figures=drawn)
