"""``predictive-drive bench``: throughput figures of this machine (printed, never asserted)."""

from __future__ import annotations

import tempfile
import time
from pathlib import Path
from typing import Any

from ..config import load_scenario
from ..core.control import strategy_names
from ..core.metrics import compute_metrics
from ..core.runner import run_inprocess
from .run import run, run_inprocess_to_bag

__all__ = ["bench", "graph_rate"]


def graph_rate(
    engine: str,
    *,
    short: float = 0.1,
    long: float = 1.0,
    affinity: str = "paired",
    sched: str = "batch",
) -> dict[str, float]:
    """Steps/s of a graph engine with recording on, start-up excluded: two runs of different
    length, rate = Δsteps / Δwall."""
    walls = {}
    with tempfile.TemporaryDirectory() as tmp:
        for d in (short, long):
            r = run(
                "im_paper",
                strategy="db_mptc",
                duration=d,
                engine=engine,
                out=Path(tmp) / f"{engine}_{d}",
                affinity=affinity,
                sched=sched,
            )
            walls[d] = (r.steps, r.wall_s)
    (n0, w0), (n1, w1) = walls[short], walls[long]
    return {
        "steps_per_s": (n1 - n0) / (w1 - w0),
        "startup_s": w0 - n0 * (w1 - w0) / (n1 - n0),
        "long_run_wall_s": w1,
        "long_run_steps": n1,
    }


def bench(*, repeats: int = 3, steps: int = 20000, ros: bool = True) -> dict[str, Any]:
    """Throughput figures (printed by ``predictive-drive bench``; never asserted in tests)."""
    sc = load_scenario("im_paper", strategy="db_mptc")
    rates = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run_inprocess(sc, steps=steps)
        rates.append(steps / (time.perf_counter() - t0))
    compute = {}
    for name in strategy_names(sc.family):
        tr = run_inprocess(sc.with_strategy(name), steps=steps)
        m = compute_metrics(tr, t_start=0.05)
        compute[name] = m.compute_ns_median / 1e3
    out: dict[str, Any] = {
        "core_steps_per_s": sorted(rates)[len(rates) // 2],
        "core_steps_per_s_runs": rates,
        "steps": steps,
        "compute_us_per_step": compute,
        "real_time_steps_per_s": 1.0 / sc.ts,
    }
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        n = run_inprocess_to_bag(sc.with_duration(steps * sc.ts), Path(tmp) / "bench")
        out["inprocess_recorded_steps_per_s"] = n / (time.perf_counter() - t0)
    if ros:
        for engine, affinity, sched, key in (
            ("ros", "paired", "batch", "ros_steps_per_s"),  # the defaults
            ("ros", "paired", "other", "ros_sched_other_steps_per_s"),
            ("ros", "none", "other", "ros_unpinned_steps_per_s"),  # all left to the kernel
            ("composed", "none", "other", "composed_steps_per_s"),  # one process: nothing to place
        ):
            g = graph_rate(engine, affinity=affinity, sched=sched)
            out[key] = g["steps_per_s"]
            out[key.replace("steps_per_s", "startup_s")] = g["startup_s"]
    return out
