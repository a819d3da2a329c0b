"""The command line's logic as plain keyword-only functions (the ``cli`` module only parses and prints).

Every engine writes a bag through the same recorder code, and every figure printed for a run is
computed from that bag, so ``report`` on the bag always agrees with what ``run`` printed.
"""

from __future__ import annotations

import dataclasses
import json
import math
import os
import time
from collections.abc import Callable, Sequence
from concurrent.futures import ProcessPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .bag import BagInfo, BagWriter, read_bag
from .config import load_scenario_text, resolve_scenario_path
from .core.control import strategy_names
from .core.metrics import Metrics, compute_metrics
from .core.runner import run_inprocess, with_strategy
from .core.scenario import Scenario
from .errors import ConfigError
from .papers import PAPER_000_TABLE2
from .recording import RunRecorder

__all__ = [
    "ENGINES",
    "RunResult",
    "bench",
    "prepare",
    "report",
    "reproduce",
    "run",
]

ENGINES = ("ros", "composed", "inprocess")


@dataclass
class RunResult:
    scenario: str
    strategy: str
    engine: str
    steps: int
    bag: Path
    wall_s: float
    metrics: Metrics

    def as_dict(self) -> dict[str, Any]:
        return {
            "scenario": self.scenario,
            "strategy": self.strategy,
            "engine": self.engine,
            "steps": self.steps,
            "bag": str(self.bag),
            "wall_s": self.wall_s,
            "metrics": self.metrics.as_dict(),
        }


def prepare(
    scenario: str | Path, *, strategy: str | None = None, duration: float | None = None
) -> tuple[Scenario, str]:
    """Load a scenario with the command line's overrides applied; returns it and its file text."""
    path = resolve_scenario_path(scenario)
    text = path.read_text()
    sc = load_scenario_text(text, path)
    if strategy is not None:
        names = strategy_names(sc.run.machine)
        if strategy not in names:
            raise ConfigError(
                f"--strategy: unknown strategy {strategy!r} for machine "
                f"{sc.run.machine!r}; valid: {', '.join(names)}"
            )
        sc = with_strategy(sc, strategy)
    if duration is not None:
        if not (duration > 0 and math.isfinite(duration)):
            raise ConfigError(f"--duration must be a positive number of seconds, got {duration}")
        sc = dataclasses.replace(sc, run=dataclasses.replace(sc.run, duration=duration))
    return sc, text


def default_bag_dir(sc: Scenario, root: str | Path = "bags") -> Path:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    return Path(root) / f"{sc.name}_{sc.controller.strategy}_{stamp}_{os.getpid()}"


def bag_info(sc: Scenario, text: str, engine: str) -> dict[str, Any]:
    """What a bag stores about its run (the ``predictive_drive`` metadata record)."""
    return {
        "scenario": sc.name,
        "scenario_yaml": text,
        "scenario_source": sc.source,
        "strategy": sc.controller.strategy,
        "duration": repr(sc.run.duration),
        "ts": repr(sc.ts),
        "engine": engine,
        "strategy_names": list(strategy_names(sc.run.machine)),
    }


def switch_steps(sc: Scenario, switches: Sequence[tuple[float, str]]) -> list[tuple[int, str]]:
    names = strategy_names(sc.run.machine)
    out = []
    for t, name in switches:
        if name not in names:
            raise ConfigError(f"--switch {t}:{name}: unknown strategy; valid: {', '.join(names)}")
        if not (0 <= t < sc.run.duration):
            raise ConfigError(f"--switch {t}:{name}: time must lie in [0, {sc.run.duration}) s")
        out.append((math.ceil(t / sc.ts - 1e-9), name))
    return out


def run_inprocess_to_bag(
    sc: Scenario,
    text: str,
    out: Path,
    switches: Sequence[tuple[float, str]] = (),
    progress: Callable[[int], None] | None = None,
) -> int:
    """The in-process engine with recording; returns the number of steps recorded."""
    with BagWriter(out, info=bag_info(sc, text, "inprocess")) as writer:
        rec = RunRecorder(
            writer,
            ts=sc.ts,
            torque_limit=sc.speed_pi.torque_limit,
            strategy_names=strategy_names(sc.run.machine),
            record_tools=True,
        )
        trace = run_inprocess(
            sc, switches=switch_steps(sc, switches), sinks=[rec.record], progress=progress
        )
        rec.finish()
    return trace.steps


def run(
    scenario: str | Path,
    *,
    strategy: str | None = None,
    duration: float | None = None,
    engine: str = "ros",
    out: str | Path | None = None,
    switches: Sequence[tuple[float, str]] = (),
    progress: Callable[[int, int], None] | None = None,
) -> RunResult:
    """Run a scenario on an engine, record it, and evaluate the recording."""
    if engine not in ENGINES:
        raise ConfigError(f"--engine: {engine!r} is not one of {', '.join(ENGINES)}")
    sc, text = prepare(scenario, strategy=strategy, duration=duration)
    bag = Path(out) if out is not None else default_bag_dir(sc)
    n = sc.run.steps
    cb = (lambda k: progress(k, n)) if progress is not None else None
    t0 = time.perf_counter()
    if engine == "inprocess":
        run_inprocess_to_bag(sc, text, bag, switches, cb)
    else:
        from .ros.graph import run_graph  # rclpy only when a ROS engine is asked for

        run_graph(sc, bag, composed=(engine == "composed"), switches=switches, progress=cb)
    wall = time.perf_counter() - t0
    metrics, trace_steps, _ = evaluate(bag)
    return RunResult(sc.name, sc.controller.strategy, engine, trace_steps, bag, wall, metrics)


def metrics_window(sc: Scenario) -> tuple[float, float]:
    """The scenario's metrics window, clipped to the run (a run shorter than the window's start is
    evaluated whole)."""
    lo = sc.logger
    end = min(lo.window_end, sc.run.duration)
    start = lo.window_start if lo.window_start < end else 0.0
    return start, end


def evaluate(bag: str | Path) -> tuple[Metrics, int, BagInfo]:
    """Metrics of a recording over its scenario's window, from the recording alone."""
    trace, info = read_bag(bag)
    start, end = metrics_window(scenario_of(info.info, info.path))
    return compute_metrics(trace, t_start=start, t_end=end), trace.steps, info


def scenario_of(info: dict[str, str], where: Path) -> Scenario:
    sc = load_scenario_text(info["scenario_yaml"], f"{where} (stored scenario)")
    sc = with_strategy(sc, info["strategy"])
    return dataclasses.replace(
        sc, run=dataclasses.replace(sc.run, duration=float(info["duration"]))
    )


def report(bag: str | Path) -> dict[str, Any]:
    """Metrics of a recording, from the recording alone."""
    m, steps, info = evaluate(bag)
    return {
        "bag": str(Path(bag)),
        "scenario": info.info["scenario"],
        "strategy": info.info["strategy"],
        "engine": info.info["engine"],
        "steps": steps,
        "complete": info.complete,
        "metrics": m.as_dict(),
    }


def _reproduce_one(args: tuple[str, str, str, str]) -> dict[str, Any]:
    scenario, strategy, engine, out = args
    r = run(scenario, strategy=strategy, engine=engine, out=out)
    m = r.metrics
    return {
        "strategy": strategy,
        "t_rmse": m.t_rmse,
        "psi_rmse": m.psi_rmse,
        "f_ave_hz": m.f_ave_hz,
        "cal_ave": m.cal_ave,
        "deadbeat_share": m.deadbeat_share,
        "compute_us_per_step": m.compute_ns_median / 1e3,
        "bag": str(r.bag),
        "wall_s": r.wall_s,
    }


PAPER_TABLES = {
    "im_paper": ("paper 000 (Li et al., EMCA 2022) Table 2, window 0.05-6 s", PAPER_000_TABLE2)
}


def reproduce(
    scenario: str,
    *,
    engine: str = "inprocess",
    out_root: str | Path = "bags",
    jobs: int | None = None,
) -> dict[str, Any]:
    """Run every strategy of a paper's table (in parallel) and set the figures beside the paper's."""
    if scenario not in PAPER_TABLES:
        raise ConfigError(
            f"reproduce: no paper table for {scenario!r}; available: {', '.join(PAPER_TABLES)}"
        )
    caption, table = PAPER_TABLES[scenario]
    stamp = time.strftime("%Y%m%d-%H%M%S")
    args = [
        (
            scenario,
            s,
            engine,
            str(Path(out_root) / f"reproduce_{scenario}_{s}_{stamp}_{os.getpid()}"),
        )
        for s in table
    ]
    workers = 1 if engine != "inprocess" else (jobs or min(len(args), os.cpu_count() or 1))
    if workers > 1:
        with ProcessPoolExecutor(workers) as pool:
            rows = list(pool.map(_reproduce_one, args))
    else:
        rows = [_reproduce_one(a) for a in args]
    for row in rows:
        row["paper"] = table[row["strategy"]]
    return {"scenario": scenario, "engine": engine, "paper": caption, "rows": rows}


def graph_rate(engine: str, *, short: float = 0.1, long: float = 1.0) -> dict[str, float]:
    """Steps/s of a graph engine with recording on, start-up excluded: two runs of different
    length, rate = Δsteps / Δwall."""
    import tempfile

    walls = {}
    with tempfile.TemporaryDirectory() as tmp:
        for d in (short, long):
            r = run(
                "im_paper",
                strategy="db_mptc",
                duration=d,
                engine=engine,
                out=Path(tmp) / f"{engine}_{d}",
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
    sc, text = prepare("im_paper", strategy="db_mptc")
    rates = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        run_inprocess(sc, steps=steps)
        rates.append(steps / (time.perf_counter() - t0))
    compute = {}
    for name in strategy_names(sc.run.machine):
        tr = run_inprocess(with_strategy(sc, name), steps=steps)
        m = compute_metrics(tr, t_start=0.05)
        compute[name] = m.compute_ns_median / 1e3
    out: dict[str, Any] = {
        "core_steps_per_s": sorted(rates)[len(rates) // 2],
        "core_steps_per_s_runs": rates,
        "steps": steps,
        "compute_us_per_step": compute,
        "real_time_steps_per_s": 1.0 / sc.ts,
    }
    import tempfile

    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        n = run_inprocess_to_bag(
            dataclasses.replace(sc, run=dataclasses.replace(sc.run, duration=steps * sc.ts)),
            text,
            Path(tmp) / "bench",
        )
        out["inprocess_recorded_steps_per_s"] = n / (time.perf_counter() - t0)
    if ros:
        for engine, key in (("ros", "ros_steps_per_s"), ("composed", "composed_steps_per_s")):
            g = graph_rate(engine)
            out[key] = g["steps_per_s"]
            out[key.replace("steps_per_s", "startup_s")] = g["startup_s"]
    return out


def dumps(obj: Any) -> str:
    return json.dumps(obj, indent=None, default=float)
