"""``predictive-drive reproduce``: every row of a paper's table run again (in parallel across the
cores), our figures beside the paper's (:mod:`predictive_drive.reports.papers`); and the MTPA
studies, every strategy at every load step with and without parameter mismatch."""

from __future__ import annotations

import math
import os
import re
import tempfile
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any, TypeVar

from ..config import apply_settings, load_scenario, resolve_scenario_path
from ..core.analysis import load_steps
from ..core.control.mtpa import mtpa_point
from ..errors import ConfigError
from ..reports.papers import MTPA_STUDIES, PAPER_TABLES, MTPAStudy
from .compare import compare
from .controller_replay import controller_replay
from .report import evaluate
from .run import RunResult, run

__all__ = ["reproduce", "scenario_with"]

T = TypeVar("T")
R = TypeVar("R")


def scenario_with(scenario: str | Path, settings: dict[str, Any], out_dir: Path) -> Path:
    """The scenario as a file with ``settings`` applied (the file itself when there are none);
    the copy is what the run's bag stores."""
    path = resolve_scenario_path(scenario)
    if not settings:
        return path
    tag = "_".join(f"{k.rsplit('.', 1)[-1]}_{v}" for k, v in settings.items())
    out = out_dir / f"{path.stem}_{re.sub(r'[^A-Za-z0-9_.-]', '', tag)}.yaml"
    out.write_text(apply_settings(path.read_text(), settings, path))
    return out


def _run_with(
    scenario: str,
    strategy: str,
    settings: dict[str, Any],
    engine: str,
    out: str,
    duration: float | None,
) -> RunResult:
    with tempfile.TemporaryDirectory() as tmp:
        path = scenario_with(scenario, settings, Path(tmp))
        return run(path, strategy=strategy, engine=engine, out=out, duration=duration)


def _table_row(args: tuple[str, str, dict[str, Any], str, str, float | None]) -> dict[str, Any]:
    r = _run_with(*args)
    m = r.metrics
    strategy, settings = args[1], args[2]
    row: dict[str, Any] = {"strategy": strategy, "settings": settings}
    row.update(
        t_rmse=m.t_rmse,
        psi_rmse=m.psi_rmse,
        f_ave_hz=m.f_ave_hz,
        cal_ave=m.cal_ave,
        deadbeat_share=m.deadbeat_share,
        zero_share=m.utilization[0],
        thd=m.thd,
        thd_harmonics=m.thd_harmonics,
        compute_us_per_step=m.compute_ns_median / 1e3,
        compute_us_mean=m.compute_ns_mean / 1e3,
        bag=str(r.bag),
        wall_s=r.wall_s,
    )
    return row


def _in_parallel(fn: Callable[[T], R], args: Sequence[T], engine: str, jobs: int | None) -> list[R]:
    """``fn`` over ``args``, across the cores for the in-process engine (the ROS engines run one
    graph at a time: each already uses the cores)."""
    workers = 1 if engine != "inprocess" else (jobs or min(len(args), os.cpu_count() or 1))
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            return list(pool.map(fn, args))
    return [fn(a) for a in args]


def reproduce(
    scenario: str,
    *,
    engine: str = "inprocess",
    out_root: str | Path = "bags",
    jobs: int | None = None,
    repeats: int = 5,
    duration: float | None = None,
    figures: str | Path | None = None,
) -> dict[str, Any]:
    """Run every row of a paper's table (independent runs in parallel across the cores) and set
    our figures beside the paper's, or run an MTPA study. ``duration`` shortens every run (a
    quick look; the figures then do not compare with the paper's). ``figures``: a folder for
    the runs drawn overlaid (PNG)."""
    if scenario in MTPA_STUDIES:
        out = reproduce_mtpa(
            scenario, engine=engine, out_root=out_root, jobs=jobs, duration=duration
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
    args = []
    for row in table.rows:
        tag = re.sub(r"[^A-Za-z0-9_.-]", "", row.name.replace(" ", "_"))
        out = Path(out_root) / f"reproduce_{scenario}_{tag}_{stamp}"
        args.append((scenario, row.strategy, row.settings, engine, str(out), duration))
    rows = _in_parallel(_table_row, args, engine, jobs)
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


def _mtpa_rows(
    args: tuple[str, str, dict[str, Any], str, str, float | None, dict[str, float]],
) -> list[dict[str, Any]]:
    """Run one case of an MTPA study and describe each of its load steps."""
    scenario, strategy, settings, engine, out, duration, mismatch = args
    r = _run_with(scenario, strategy, settings, engine, out, duration)
    ev = evaluate(r.bag)
    sc, plant = ev.scenario, ev.scenario.plant.motor
    steps = load_steps(
        ev.trace,
        load_times=sc.plant.load_times,
        load_values=sc.plant.load_values,
        average_s=1.0 / sc.controller.injection_hz,
    )
    rows = []
    for st in steps:
        best = mtpa_point(
            st.load_torque, p=plant.p, psi_f=plant.psi_f, l_d=plant.l_d, l_q=plant.l_q
        )
        rows.append(
            {
                "strategy": strategy,
                "form": sc.controller.injection_form if strategy == "foc_injection" else None,
                "mismatch": mismatch,
                "load_torque": st.load_torque,
                "theta_deg": math.degrees(st.theta),
                "theta_mtpa_deg": math.degrees(best.theta),
                "i_s": st.i_s,
                "i_s_mtpa": best.i_s,
                "i_s_zero_d": best.i_s_zero_d,
                "settle_s": st.settle_s,
                "t_start": st.t_start,
                "t_end": st.t_end,
                "bag": str(r.bag),
            }
        )
    return rows


def reproduce_mtpa(
    scenario: str,
    *,
    engine: str = "inprocess",
    out_root: str | Path = "bags",
    jobs: int | None = None,
    duration: float | None = None,
) -> dict[str, Any]:
    """An MTPA study (:data:`~predictive_drive.reports.papers.MTPA_STUDIES`): one row per run and
    load step; the paper's claims checked per load where it makes any."""
    study = MTPA_STUDIES[scenario]
    load_scenario(scenario)  # a bad scenario fails before anything runs
    stamp = f"{time.strftime('%Y%m%d-%H%M%S')}_{os.getpid()}"
    args = []
    for strategy, settings, mismatch in _mtpa_runs(study):
        tag = f"{strategy}_ld{mismatch['l_d']:g}_lq{mismatch['l_q']:g}"
        if settings.get("torque_controller.injection_form") == "as_printed":
            tag += "_as_printed"
        out = Path(out_root) / f"reproduce_{scenario}_{tag}_{stamp}"
        args.append((scenario, strategy, settings, engine, str(out), duration, mismatch))
    rows = [row for rs in _in_parallel(_mtpa_rows, args, engine, jobs) for row in rs]
    return {
        "scenario": scenario,
        "engine": engine,
        "duration": duration,
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
