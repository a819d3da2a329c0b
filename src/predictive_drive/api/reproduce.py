"""``predictive-drive reproduce``: every row of a paper's table run again (in parallel across the
cores), our figures beside the paper's (:mod:`predictive_drive.reports.papers`); and the MTPA
studies, every strategy at every load step with and without parameter mismatch."""

from __future__ import annotations

import math
import os
import re
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..bag import check_new_bag
from ..config import load_scenario, scenario_with
from ..core.analysis import load_steps
from ..core.control.mtpa import mtpa_point
from ..core.scenario import Scenario
from ..core.trace import Trace
from ..errors import ConfigError, PredictiveDriveError
from ..reports.papers import MTPA_STUDIES, PAPER_TABLES, MTPAStudy
from .compare import compare
from .controller_replay import controller_replay
from .report import evaluate
from .run import run
from .sweep import Analysis, Case, Row, run_cases

__all__ = ["mtpa_steps", "reproduce"]


def _runs(
    scenario: str,
    cases: Sequence[Case],
    *,
    engine: str,
    duration: float | None,
    jobs: int | None,
    analysis: Analysis | None = None,
) -> list[Row]:
    """The cases, each recorded to its bag: a sweep across the cores (in-process), or one
    graph at a time (a ROS engine, which already uses the cores). A failed case fails the
    reproduction, naming it."""
    if engine == "inprocess":
        result = run_cases(scenario, cases, duration=duration, jobs=jobs, analysis=analysis)
        if result.interrupted:
            raise KeyboardInterrupt
        rows = result.rows
    else:
        rows = []
        for c in cases:
            with tempfile.TemporaryDirectory() as tmp:
                path = scenario_with(scenario, c.settings, Path(tmp))
                r = run(path, strategy=c.strategy, engine=engine, out=c.bag, duration=duration)
            ev = evaluate(r.bag)
            extra = analysis(ev.trace, ev.scenario) if analysis is not None else {}
            rows.append(
                Row(c.strategy, c.settings, ev.metrics.as_dict(), None, r.wall_s, c.bag, extra)
            )
    for row in rows:
        if row.error:
            raise PredictiveDriveError(
                f"reproduce {scenario}: the run {row.strategy} {row.settings or ''} failed: "
                f"{row.error}"
            )
    return rows


def _table_row(row: Row) -> dict[str, Any]:
    m = row.metrics or {}
    return {
        "strategy": row.strategy,
        "settings": row.settings,
        "t_rmse": m["t_rmse"],
        "psi_rmse": m["psi_rmse"],
        "f_ave_hz": m["f_ave_hz"],
        "cal_ave": m["cal_ave"],
        "deadbeat_share": m["deadbeat_share"],
        "zero_share": m["utilization"][0],
        "thd": m["thd"],
        "thd_harmonics": m["thd_harmonics"],
        "compute_us_per_step": m["compute_ns_median"] / 1e3,
        "compute_us_mean": m["compute_ns_mean"] / 1e3,
        "bag": row.bag,
        "wall_s": row.wall_s,
    }


def _bag(out_root: str | Path, name: str) -> str:
    return str(check_new_bag(Path(out_root) / name).resolve())


def reproduce(
    scenario: str,
    *,
    engine: str = "inprocess",
    out_root: str | Path = "bags",
    jobs: int | None = None,
    repeats: int = 5,
    duration: float | None = None,
    figures: str | Path | None = None,
    settings: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Run every row of a paper's table (independent runs in parallel across the cores) and set
    our figures beside the paper's, or run an MTPA study. ``duration`` shortens every run (a
    quick look; the figures then do not compare with the paper's). ``figures``: a folder for
    the runs drawn overlaid (PNG). ``settings``: scenario settings applied to every run (e.g.
    ``{"speed_pi.speed_loop": "immediate"}``), besides each row's own."""
    settings = dict(settings or {})
    if scenario in MTPA_STUDIES:
        out = reproduce_mtpa(
            scenario,
            engine=engine,
            out_root=out_root,
            jobs=jobs,
            duration=duration,
            settings=settings,
        )
        if figures is not None:  # the runs at exact parameters, one per strategy and form
            bags = list(dict.fromkeys(r["bag"] for r in out["rows"] if _exact(r, r["strategy"])))
            out["figures"] = compare(bags, figures=figures)["figures"]
        return out
    if scenario not in PAPER_TABLES:
        raise ConfigError(
            f"reproduce: no paper table for {scenario!r}; available: "
            f"{', '.join([*PAPER_TABLES, *MTPA_STUDIES])}"
        )
    table = PAPER_TABLES[scenario]
    stamp = f"{time.strftime('%Y%m%d-%H%M%S')}_{os.getpid()}"
    cases = []
    for row in table.rows:
        tag = re.sub(r"[^A-Za-z0-9_.-]", "", row.name.replace(" ", "_"))
        bag = _bag(out_root, f"reproduce_{scenario}_{tag}_{stamp}")
        cases.append(Case(row.strategy, {**settings, **row.settings}, bag))
    runs = _runs(scenario, cases, engine=engine, duration=duration, jobs=jobs)
    rows = [_table_row(r) for r in runs]
    for row, spec in zip(rows, table.rows):
        row["paper"] = spec.paper
        row["label"] = spec.name
    if table.compute_ratios:
        # in this process, after the runs: timing must not share the cores. Conventional first:
        # the ratios are relative to it
        order = sorted(rows, key=lambda r: r["strategy"] != "mptc")
        times = controller_replay([r["bag"] for r in order], repeats=repeats)
        for r, t in zip(order, times):
            r["replay_identical"] = t["identical"]
            r["compute_ns_hot"] = t["hot_ns"]
            r["compute_ratio"] = t["hot_ratio"]
            r["compute_ns_in_loop"] = t["loop_ns"]
            r["compute_ratio_in_loop"] = t["loop_ratio"]
    out = {
        "scenario": scenario,
        "engine": engine,
        "duration": duration,
        "settings": settings,
        "paper": table.caption,
        "how": table.how,
        "rows": rows,
    }
    if figures is not None:
        out["figures"] = compare([r["bag"] for r in rows], figures=figures)["figures"]
    return out


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
    *,
    engine: str = "inprocess",
    out_root: str | Path = "bags",
    jobs: int | None = None,
    duration: float | None = None,
    settings: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """An MTPA study (:data:`~predictive_drive.reports.papers.MTPA_STUDIES`): a sweep of the
    strategies over the controller-side inductance mismatches, one row per run and load step;
    the paper's claims checked per load where it makes any."""
    study = MTPA_STUDIES[scenario]
    load_scenario(scenario)  # a bad scenario fails before anything runs
    stamp = f"{time.strftime('%Y%m%d-%H%M%S')}_{os.getpid()}"
    cases, mismatches = [], []
    for strategy, case_settings, mismatch in _mtpa_runs(study):
        tag = f"{strategy}_ld{mismatch['l_d']:g}_lq{mismatch['l_q']:g}"
        if case_settings.get("torque_controller.injection_form") == "as_printed":
            tag += "_as_printed"
        bag = _bag(out_root, f"reproduce_{scenario}_{tag}_{stamp}")
        cases.append(Case(strategy, {**(settings or {}), **case_settings}, bag))
        mismatches.append(mismatch)
    runs = _runs(scenario, cases, engine=engine, duration=duration, jobs=jobs, analysis=mtpa_steps)
    rows = [
        {
            "strategy": r.strategy,
            "form": r.extra["form"],
            "mismatch": mismatch,
            **step,
            "bag": r.bag,
        }
        for r, mismatch in zip(runs, mismatches)
        for step in r.extra["load_steps"]
    ]
    return {
        "scenario": scenario,
        "engine": engine,
        "duration": duration,
        "settings": settings or {},
        "paper": study.caption,
        "how": study.how,
        "rows": rows,
        "claims": _check_claims(study, rows),
    }


def _exact(row: dict[str, Any], strategy: str, form: str | None = None) -> bool:
    m = row["mismatch"]
    return (
        row["strategy"] == strategy
        and m["l_d"] == 1.0
        and m["l_q"] == 1.0
        and (form is None or row["form"] == form)
    )


def _check_claims(study: MTPAStudy, rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Per load: does the corrected injection settle under a second, and does it draw less
    current than i_d = 0 (both measured, same scenario, exact parameters)? The current saving is
    judged against the measurement's resolution: how far the i_d = 0 run's measured |i_s| lies
    from the model's, at that load."""
    if not study.claims:
        return []
    zero = {r["load_torque"]: r for r in rows if _exact(r, "foc_zero_d")}
    out = []
    for r in rows:
        if not _exact(r, "foc_injection", "corrected") or r["load_torque"] not in zero:
            continue
        z = zero[r["load_torque"]]
        saving = 1.0 - r["i_s"] / z["i_s"]
        resolution = abs(z["i_s"] / z["i_s_zero_d"] - 1.0)
        verdict = (
            "confirmed"
            if saving > resolution
            else "refuted"
            if saving < -resolution
            else "not resolved"
        )
        out.append(
            {
                "load_torque": r["load_torque"],
                "settle_s": r["settle_s"],
                "settles_under_1_s": r["settle_s"] < 1.0,
                "i_s": r["i_s"],
                "i_s_zero_d_measured": z["i_s"],
                "saving_vs_zero_d": saving,
                "saving_possible": 1.0 - r["i_s_mtpa"] / r["i_s_zero_d"],
                "resolution": resolution,
                "less_current_than_zero_d": verdict,
            }
        )
    return out
