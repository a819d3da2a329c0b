"""``predictive-drive reproduce``: every row of a paper's table run again (in parallel across the
cores), our figures beside the paper's (:mod:`predictive_drive.reports.papers`)."""

from __future__ import annotations

import os
import re
import tempfile
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path
from typing import Any

from ..config import resolve_scenario_path
from ..errors import ConfigError
from ..reports.papers import PAPER_TABLES
from .controller_replay import controller_replay
from .run import run

__all__ = ["reproduce", "with_threshold"]


def with_threshold(path: Path, threshold: float, out_dir: Path) -> Path:
    """A copy of a PMSM scenario file with torque_controller.torque_threshold replaced (comments
    kept; the copy is what the run's bag stores)."""
    text = path.read_text()
    new, n = re.subn(
        r"^(\s*torque_threshold:\s*)[^\s#]+.*$",
        lambda m: f"{m.group(1)}{threshold!r}  # N m, set by the threshold sweep",
        text,
        count=1,
        flags=re.MULTILINE,
    )
    if n != 1:
        raise ConfigError(f"{path}: no torque_threshold key to sweep")
    out = out_dir / f"{path.stem}_threshold_{threshold:g}.yaml"
    out.write_text(new)
    return out


def _reproduce_one(
    args: tuple[str, str, float | None, str, str, float | None],
) -> dict[str, Any]:
    scenario, strategy, threshold, engine, out, duration = args
    with tempfile.TemporaryDirectory() as tmp:
        path = resolve_scenario_path(scenario)
        if threshold is not None:
            path = with_threshold(path, threshold, Path(tmp))
        r = run(path, strategy=strategy, engine=engine, out=out, duration=duration)
    m = r.metrics
    row: dict[str, Any] = {"strategy": strategy}
    if threshold is not None:
        row["torque_threshold"] = threshold
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


def reproduce(
    scenario: str,
    *,
    engine: str = "inprocess",
    out_root: str | Path = "bags",
    jobs: int | None = None,
    repeats: int = 5,
    duration: float | None = None,
) -> dict[str, Any]:
    """Run every row of a paper's table (independent runs in parallel across the cores) and set
    our figures beside the paper's. ``duration`` shortens every run (a quick look; the figures
    then do not compare with the paper's)."""
    if scenario not in PAPER_TABLES:
        raise ConfigError(
            f"reproduce: no paper table for {scenario!r}; available: {', '.join(PAPER_TABLES)}"
        )
    table = PAPER_TABLES[scenario]
    stamp = time.strftime("%Y%m%d-%H%M%S")
    args = []
    for row in table.rows:
        tag = (
            row.strategy
            if row.torque_threshold is None
            else f"{row.strategy}_{row.torque_threshold:g}"
        )
        out = Path(out_root) / f"reproduce_{scenario}_{tag}_{stamp}_{os.getpid()}"
        args.append((scenario, row.strategy, row.torque_threshold, engine, str(out), duration))
    workers = 1 if engine != "inprocess" else (jobs or min(len(args), os.cpu_count() or 1))
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            rows = list(pool.map(_reproduce_one, args))
    else:
        rows = [_reproduce_one(a) for a in args]
    for row, spec in zip(rows, table.rows):
        row["paper"] = spec.paper
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
    return {
        "scenario": scenario,
        "engine": engine,
        "duration": duration,
        "paper": table.caption,
        "how": table.how,
        "rows": rows,
    }
