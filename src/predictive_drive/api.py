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

import numpy as np

from .bag import BagInfo, BagWriter, read_bag
from .config import load_scenario_text, resolve_scenario_path
from .core.control import strategy_names
from .core.metrics import Metrics, compute_metrics
from .core.runner import run_inprocess, with_strategy
from .core.scenario import Scenario
from .errors import ConfigError
from .papers import PAPER_000_TABLE2, PAPER_001_TABLE1, PAPER_001_TABLE2, PAPER_001_TABLE9
from .recording import RunRecorder

__all__ = [
    "ENGINES",
    "PAPER_TABLES",
    "RunResult",
    "analyze",
    "bench",
    "controller_replay",
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
    switches: Sequence[tuple[int, str]] = (),
    progress: Callable[[int], None] | None = None,
) -> int:
    """The in-process engine with recording; returns the number of steps recorded. ``switches``:
    (step, strategy) pairs, as :func:`switch_steps` makes them."""
    with BagWriter(out, info=bag_info(sc, text, "inprocess")) as writer:
        rec = RunRecorder(
            writer,
            ts=sc.ts,
            torque_limit=sc.speed_pi.torque_limit,
            strategy_names=strategy_names(sc.run.machine),
            record_tools=True,
        )
        trace = run_inprocess(sc, switches=switches, sinks=[rec.record], progress=progress)
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
    affinity: str = "paired",
    sched: str = "batch",
) -> RunResult:
    """Run a scenario on an engine, record it, and evaluate the recording. ``affinity`` and
    ``sched``: CPU placement (``paired`` | ``none``, see
    :func:`predictive_drive.ros.graph.cpu_plan`) and scheduling policy (``batch`` | ``other``) of
    the ``ros`` engine's node processes."""
    if engine not in ENGINES:
        raise ConfigError(f"--engine: {engine!r} is not one of {', '.join(ENGINES)}")
    sc, text = prepare(scenario, strategy=strategy, duration=duration)
    bag = Path(out) if out is not None else default_bag_dir(sc)
    n = sc.run.steps
    cb = (lambda k: progress(k, n)) if progress is not None else None
    # checked for every engine, so a bad --switch fails before anything starts
    at_steps = switch_steps(sc, switches)
    t0 = time.perf_counter()
    if engine == "inprocess":
        run_inprocess_to_bag(sc, text, bag, at_steps, cb)
    else:
        from .ros.graph import run_graph  # rclpy only when a ROS engine is asked for

        run_graph(
            sc,
            bag,
            composed=(engine == "composed"),
            switches=switches,
            progress=cb,
            affinity=affinity,
            sched=sched,
        )
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
    sc = scenario_of(info.info, info.path)
    start, end = metrics_window(sc)
    thd = sc.logger.thd_window
    if thd and thd[1] > trace.steps * trace.ts:
        thd = ()  # a run (or a cut recording) that ends before the THD window: no THD
    return compute_metrics(trace, t_start=start, t_end=end, thd_window=thd), trace.steps, info


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


@dataclass(frozen=True)
class PaperRow:
    """One row of a paper's table: the strategy, a torque-threshold override (N·m) or None, and the
    paper's figures."""

    strategy: str
    torque_threshold: float | None
    paper: dict[str, float]


@dataclass(frozen=True)
class PaperTable:
    caption: str
    how: str  #: how our figures were computed (printed under the table)
    rows: tuple[PaperRow, ...]
    compute_ratios: bool = False  #: replay each run through its controller to time it


PAPER_TABLES: dict[str, PaperTable] = {
    "im_paper": PaperTable(
        "paper 000 (Li et al., EMCA 2022) Table 2, window 0.05-6 s",
        "true plant torque/flux at each sample k against the reference in force at k over "
        "0.05-6 s; f_ave counts two device transitions per leg change (the paper gives no f_ave); "
        "compute = median wall time of the control law per step on this machine. The paper's MPTC "
        "T_RMSE (0.2582) was not reproduced under any reading tried; an independent "
        "implementation of the same SPEC got 0.230.",
        tuple(PaperRow(s, None, v) for s, v in PAPER_000_TABLE2.items()),
    ),
    "spmsm_analysis": PaperTable(
        "paper 001 (Li et al., CTA 2023) Table 2: SPMSM, strategy-1 threshold sweep, 0-4 s",
        "T_rip/psi_rip = RMSE of the true torque/flux against the references over all 80 000 "
        "samples; Cal_ave = vector predictions per step; f_ave = device transitions / (6 t), two "
        "per leg change (the paper's own f_ave figures are lower under every reading tried). "
        "J (not in the paper) is assumed 0.001 kg m^2; T_rip depends on it through the speed "
        "PI, which amplifies speed ripple into T*.",
        (PaperRow("mptc", None, PAPER_001_TABLE2[None]),)
        + tuple(
            PaperRow("simplified1", th, v) for th, v in PAPER_001_TABLE2.items() if th is not None
        ),
    ),
    "ipmsm_validation": PaperTable(
        "paper 001 (Li et al., CTA 2023) Table 9 (IPMSM, 0-2 s), zero-vector shares of §6, "
        "compute time relative to conventional of Table 11",
        "T_rip/psi_rip over the whole 2 s; THD = phase-a current distortion over the whole "
        "electrical cycles in 0.2-0.5 s (every spectral line up to 10 kHz but DC and the "
        "fundamental; integer harmonics alone in the next column); f_ave two transitions per leg "
        "change; compute ratio = the strategy's decision time over the run relative to "
        "conventional MPTC, its decisions replayed in a tight loop on the run's recorded "
        "estimates (the paper's per-case method) less the cost of the same loop without the "
        "decision, runs interleaved in 500-step chunks, median "
        "of 5 repeats; µs/step the same time per step (JSON also gives the per-step figures of "
        "a controller stepping through the run: compute_ratio_in_loop). U_dc, J, psi*, the PI "
        "gains are assumed (see the scenario file).",
        tuple(PaperRow(s, None, v) for s, v in PAPER_001_TABLE9.items()),
        compute_ratios=True,
    ),
}


def with_threshold(path: Path, threshold: float, out_dir: Path) -> Path:
    """A copy of a PMSM scenario file with torque_controller.torque_threshold replaced (comments
    kept; the copy is what the run's bag stores)."""
    import re

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
    import tempfile

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


def controller_replay(
    bags: Sequence[str | Path], *, repeats: int = 5, chunk: int = 500
) -> list[dict[str, Any]]:
    """Time runs' strategies on the runs' own inputs, as paper 001 Table 11 does (recorded cases,
    counts × per-case time).

    Each run's recorded states and references are fed again through a fresh controller. Two
    figures per run, both per step and the median over ``repeats``: ``hot_ns`` times the strategy's
    decisions alone in a tight loop over the recorded estimates (where the estimate is a function
    of the state: PMSM) — the paper's method — less the harness's own cost per case (the same loop
    without the decision, timed after each chunk; the median over chunks, so a preempted one
    cannot eat into the decision time); ``loop_ns`` sums the per-step ``compute_ns`` of the controller
    stepping through the run (every engine's figure, caches cooled by the rest of each step).
    The runs are replayed side by side, ``chunk`` steps of each in turn, so a slow spell of this
    noisy machine hits all of them alike; ratios are per repeat against the first bag,
    then the median. Also checks that every replay decides as recorded."""
    from .core.runner import build_controller
    from .core.signals import Reference, State

    runs = []
    for bag in bags:
        trace, info = read_bag(bag)
        sc = scenario_of(info.info, info.path)
        n = trace.steps
        states = [State(*row) for row in trace.state[:n].tolist()]
        refs = [Reference(*row) for row in trace.reference[:n].tolist()]
        ctrl = build_controller(sc.controller, ts=sc.ts)
        inputs = ctrl.decision_inputs(states)
        cases = None
        if inputs is not None:
            cases = [(m, r.torque_ref, r.flux_ref) for m, r in zip(inputs, refs)]
        runs.append((sc, states, refs, trace.col("command", "vector"), cases))
    loop: list[list[float]] = [[] for _ in runs]
    hot: list[list[float]] = [[] for _ in runs]
    identical = [True] * len(runs)
    longest = max(len(r[1]) for r in runs)
    harness: list[float] = []  # ns per case of the bare timing loop, per chunk
    for _ in range(repeats):
        ctrls = [build_controller(sc.controller, ts=sc.ts) for sc, *_ in runs]
        loop_t = [0.0] * len(runs)
        hot_t = [0.0] * len(runs)
        vectors: list[list[float]] = [[] for _ in runs]
        for lo in range(0, longest, chunk):
            for j, (_, states, refs, _, inputs) in enumerate(runs):
                step = ctrls[j].step
                total = 0.0
                out = vectors[j]
                for s, ref in zip(states[lo : lo + chunk], refs[lo : lo + chunk]):
                    c = step(s, ref)
                    total += c.compute_ns
                    out.append(c.vector)
                loop_t[j] += total
                if inputs is not None:
                    decide = ctrls[j].strategy.decide
                    part = inputs[lo : lo + chunk]
                    t0 = time.perf_counter_ns()
                    for m, t_ref, psi_ref in part:
                        decide(m, t_ref, psi_ref)
                    t1 = time.perf_counter_ns()
                    for _m, _t, _p in part:  # the harness alone: same unpacking, no decision
                        pass
                    harness.append((time.perf_counter_ns() - t1) / len(part))
                    hot_t[j] += t1 - t0
        for j, (_, states, _, recorded, inputs) in enumerate(runs):
            loop[j].append(loop_t[j] / len(states))
            hot[j].append(hot_t[j] / len(states) if inputs is not None else math.nan)
            identical[j] = identical[j] and bool(np.array_equal(np.asarray(vectors[j]), recorded))

    per_case = float(np.median(harness)) if harness else 0.0
    hot = [[t - per_case for t in h] for h in hot]  # NaN stays NaN

    def ratio(times: list[float], base: list[float]) -> float:
        return float(np.median(np.asarray(times) / np.asarray(base)))

    return [
        {
            "hot_ns": float(np.median(hot[j])),
            "loop_ns": float(np.median(loop[j])),
            "hot_ratio": ratio(hot[j], hot[0]),
            "loop_ratio": ratio(loop[j], loop[0]),
            "loop_runs_ns": loop[j],
            "hot_runs_ns": hot[j],
            "identical": identical[j],
            "steps": len(runs[j][1]),
        }
        for j in range(len(runs))
    ]


def analyze(
    bag: str | Path,
    *,
    threshold: float | None = None,
    write_tables: str | Path | None = None,
) -> dict[str, Any]:
    """Vector utilization of a recording (paper 001 Tables 1, 3-8) and the candidate sets it
    derives, compared with the tables strategies 2 and 3 use."""
    from .core.analysis import DERIVATION_RULE, derive_candidates, utilization
    from .core.pmsm_control import TABLES, class_document

    trace, info = read_bag(bag)
    sc = scenario_of(info.info, info.path)
    if threshold is None:
        threshold = getattr(sc.controller, "torque_threshold", None)
        if threshold is None:
            raise ConfigError(
                f"analyze: {bag} is a {sc.run.machine} run without a torque threshold; give "
                f"--threshold N·m"
            )
    if not (math.isfinite(threshold) and threshold >= 0):
        raise ConfigError(f"--threshold must be a torque >= 0 N·m, got {threshold}")
    start, end = metrics_window(sc)
    u = utilization(trace, threshold=threshold, t_start=start, t_end=min(end, trace.steps * sc.ts))
    derived = class_document(derive_candidates(u.six), derive_candidates(u.twelve))
    used = class_document(TABLES.six, TABLES.twelve)
    differences = [
        f"{table.split('_')[0]} sectors, {cls}, θ{s + 1}: derived {d}, used {u_}"
        for table, classes in derived.items()
        for cls, cells in classes.items()
        for s, (d, u_) in enumerate(zip(cells, used[table][cls]))
        if d != u_
    ]
    shares = class_document(u.shares(u.six), u.shares(u.twelve), cell=np.ndarray.tolist)
    counts = class_document(u.six.sum(axis=-1), u.twelve.sum(axis=-1), cell=int)
    bands = [
        {
            "band": None if math.isinf(b) else b,
            "n": n,
            "n_v0": n0,
            "eta_v0": n0 / n if n else math.nan,
            "paper": PAPER_001_TABLE1.get(None if math.isinf(b) else b),
        }
        for b, n, n0 in u.bands
    ]
    out: dict[str, Any] = {
        "bag": str(Path(bag)),
        "scenario": info.info["scenario"],
        "strategy": info.info["strategy"],
        "threshold": threshold,
        "window": [start, end],
        "steps": u.steps,
        "bands": bands,
        "class_steps": counts,
        "utilization": shares,
        "rule": DERIVATION_RULE,
        "derived": derived,
        "matches_tables": not differences,
        "differences": differences,
    }
    if write_tables is not None:
        doc = {
            "source": f"predictive-drive analyze {Path(bag)}",
            "rule": DERIVATION_RULE,
            **derived,
        }
        dest = Path(write_tables)
        tmp = dest.with_name(dest.name + ".tmp")
        tmp.write_text(json.dumps(doc, indent=1) + "\n")
        tmp.replace(dest)  # never a half-written table
        out["written"] = str(dest)
    return out


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


def _finite(obj: Any) -> Any:
    """NaN/inf → None, so ``--json`` prints strict JSON (null where a figure does not exist)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, np.floating):
        return _finite(float(obj))
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def dumps(obj: Any) -> str:
    return json.dumps(_finite(obj), indent=None, allow_nan=False)
