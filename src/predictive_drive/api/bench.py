"""``predictive-drive bench``: throughput figures of this machine (printed, never asserted)."""

from __future__ import annotations

import dataclasses
import math
import shlex
import shutil
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..config import (
    apply_settings,
    load_scenario,
    load_scenario_text,
    resolve_scenario_path,
    scenario_with,
)
from ..core.control import strategy_names
from ..core.losses_kernel import kernel_unavailable
from ..core.metrics import compute_metrics
from ..core.runner import run_inprocess
from ..core.signals import EXTERNAL_PREFIX, external_name
from ..errors import ConfigError
from .report import evaluate
from .run import run, run_inprocess_to_bag

__all__ = [
    "GRAPH_RUNS",
    "HORIZON_RUNS",
    "QUICK_RUNS",
    "Bench",
    "GraphRate",
    "GraphRun",
    "HorizonRate",
    "LOSS_DRIVE",
    "LossRate",
    "bench",
    "graph_rate",
    "graph_runs",
    "horizon_rate",
]


def graph_rate(
    engine: str,
    *,
    duration: float = 2.0,
    affinity: str = "paired",
    sched: str = "batch",
    speed_loop: str = "one_step",
    external: dict[str, str | None] | None = None,
) -> dict[str, Any]:
    """Steps/s of a graph engine with recording on, in one run (im_paper, db_mptc): the
    least-squares slope of step against wall time over the /clock samples the launcher sees
    between 20 % and 90 % of the run (start-up and the end excluded). The launcher's /clock
    watch runs meanwhile (it costs the graph a few per cent). ``steps_per_s`` is None when the
    run gave too few samples for a slope. ``speed_loop``: the scenario's speed-loop timing
    (``immediate``: the controller waits for the speed PI's answer to each state);
    ``external``: nodes of the user's own in place of ours (``run --external``)."""
    samples: list[tuple[float, int]] = []

    def seen(k: int, n: int) -> None:
        samples.append((time.perf_counter(), k))

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        settings = {} if speed_loop == "one_step" else {"speed_pi.speed_loop": speed_loop}
        r = run(
            scenario_with("im_paper", settings, Path(tmp)),
            strategy=None if external else "db_mptc",
            duration=duration,
            engine=engine,
            out=Path(tmp) / engine,
            affinity=affinity,
            sched=sched,
            progress=seen,
            external=external,
        )
    n = r.steps
    mid = np.array([(t, k) for t, k in samples if 0.2 * n <= k <= 0.9 * n])
    rate = None
    if len(mid) >= 3 and np.ptp(mid[:, 0]) > 0:
        slope = float(np.polyfit(mid[:, 0], mid[:, 1], 1)[0])
        rate = slope if math.isfinite(slope) and slope > 0 else None
    return {
        "steps_per_s": rate,
        "startup_s": (samples[0][0] - t0) if samples else math.nan,
        "run_wall_s": r.wall_s,
        "run_steps": n,
        "samples": len(mid),
    }


@dataclass(frozen=True)
class GraphRun:
    """A graph engine's configuration in a bench: engine, CPU placement, scheduling policy,
    speed-loop timing, the figure's key, and what it is in words."""

    engine: str
    affinity: str
    sched: str
    speed_loop: str
    key: str
    what: str
    #: the torque controller is the example of one's own (examples/dtc_im), run this long (s)
    example_dtc: float = 0.0
    #: the torque controller is a node of the user's own started by this command (bench
    #: --external), run 0.5 s
    command: str = ""


#: the graph runs of a full bench
GRAPH_RUNS = (
    GraphRun("ros", "paired", "batch", "one_step", "ros_steps_per_s",
             "four processes, paired CPUs, SCHED_BATCH, recording on"),  # the defaults
    GraphRun("ros", "paired", "batch", "immediate", "ros_immediate_steps_per_s",
             "the same, speed_loop immediate: the controller waits for the speed PI"),
    GraphRun("ros", "paired", "other", "one_step", "ros_sched_other_steps_per_s",
             "four processes, paired CPUs, --sched other, recording on"),
    GraphRun("ros", "none", "other", "one_step", "ros_unpinned_steps_per_s",
             "four processes, --affinity none --sched other, recording on"),
    GraphRun("composed", "none", "other", "one_step", "composed_steps_per_s",
             "one process, recording on"),
    GraphRun("ros", "paired", "batch", "one_step", "ros_example_dtc_steps_per_s",
             "four processes, the torque controller examples/dtc_im (a user's rclpy node, "
             "rclpy's EventsExecutor), recording on", example_dtc=0.5),
)  # fmt: skip
#: ``--quick``: the defaults of each engine, short runs (a smoke test of the figures, not a
#: measurement)
QUICK_RUNS = (GRAPH_RUNS[0], GRAPH_RUNS[-2])


def example_dtc() -> str | None:
    """The command of the example controller (examples/dtc_im): the source checkout's, or the
    ``dtc_node`` a colcon build of it installed; None where neither is."""
    node = Path(__file__).resolve().parents[3] / "examples" / "dtc_im" / "dtc_im" / "dtc_node.py"
    if node.is_file():
        return f"{shlex.quote(sys.executable)} {shlex.quote(str(node))}"
    found = shutil.which("dtc_node")
    return shlex.quote(found) if found else None


@dataclass(frozen=True)
class GraphRate:
    """One graph run's throughput (steps/s, None when too few samples gave no slope), how long
    it took to start (wall s until its first /clock), and the core loop measured right before
    and right after it (the mean of the two; NaN where the run was not made)."""

    run: GraphRun
    steps_per_s: float | None
    startup_s: float
    core_near_steps_per_s: float = math.nan


#: the long-horizon laws a bench times: (strategy, scenario, horizons)
HORIZON_RUNS = (
    ("mptc", "im_paper", (1, 2, 3, 5)),
    ("direct_mpc", "ipmsm_steady_mpc", (1, 3, 5, 10)),
)


@dataclass(frozen=True)
class HorizonRate:
    """One law at one horizon: steps/s of the whole in-process loop (plant, speed loop,
    controller; no recording) over ``steps`` from the start, that as a share of the call's core
    loop (``of_core``) and of the core loop run right before and after it (``of_core_near``: the
    machine drifts within a call), the controller's compute time per step (median, 99th
    percentile), the nodes its search visited per step (mean and 99th percentile: the compute
    time's spread without the machine's) and the steps whose search ran out of its node budget
    (``suboptimal_steps``, with the law's default budget)."""

    strategy: str
    scenario: str
    horizon: int
    steps: int
    steps_per_s: float
    of_core: float
    compute_us_median: float
    compute_us_p99: float
    nodes_mean: float
    decoder: str
    suboptimal_steps: int = 0
    nodes_p99: float = math.nan
    core_near_steps_per_s: float = math.nan
    of_core_near: float = math.nan

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def horizon_rate(
    strategy: str, scenario: str, horizon: int, steps: int, core: float
) -> HorizonRate:
    """Time ``strategy`` at ``horizon`` on ``scenario`` for ``steps`` (see :class:`HorizonRate`)."""
    sc = load_scenario(scenario, strategy=strategy)
    sc = dataclasses.replace(sc, controller=dataclasses.replace(sc.controller, horizon=horizon))
    from ..core.control.kernels import load_kernels

    # a compiled kernel loads before the clock starts (im_paper's soft start searches nothing
    # for its first 963 steps)
    compiled = load_kernels()
    decoder = getattr(sc.controller, "decoder", getattr(sc.controller, "search", ""))
    if decoder == "auto":
        decoder = "compiled" if compiled else "python"
    run_inprocess(sc, steps=min(steps, 50))
    t0 = time.perf_counter()
    tr = run_inprocess(sc, steps=steps)
    rate = steps / (time.perf_counter() - t0)
    ns, nodes = tr.col("command", "compute_ns"), tr.col("command", "cal")
    return HorizonRate(
        strategy, scenario, horizon, steps, rate, rate / core,
        float(np.median(ns)) / 1e3, float(np.percentile(ns, 99)) / 1e3,
        float(nodes.mean()), decoder or "-", int((tr.col("command", "suboptimal") == 1.0).sum()),
        float(np.percentile(nodes, 99)),
    )  # fmt: skip


#: the real drive a loss row times (im_paper, db_mptc): its dead time and device drops, and
#: the same drive with its devices' losses and temperatures and the machine's instead of the
#: constant drop (docs/physics.md#losses-and-temperature)
LOSS_DRIVE: dict[str, Any] = {"plant.dead_time": 2e-6, "plant.device_drop": 1.5}
LOSSES_ON: dict[str, Any] = {
    "plant.dead_time": 2e-6,
    "plant.losses.device": "semikron_skm150gb124d",
    "plant.losses.machine": True,
    "plant.losses.iron_hysteresis": 1.0,
    "plant.losses.iron_eddy": 0.01,
}


@dataclass(frozen=True)
class LossRate:
    """Losses and temperatures on against off, in one call: steps/s of the in-process loop of a
    real drive (dead time, device drops: ``real``) and of the same drive with losses and
    temperatures booked (``losses``), each the median of interleaved repeats; ``of_real``: the
    median of each losses run over the real-drive run right before it; ``of_core``: the losses
    runs' median over the call's core loop (the ideal drive, which takes no segment of a real
    inverter); ``booking``: how the ledger booked (``compiled``, numba's kernel, or ``python``,
    the per-period reference: docs/physics.md#losses-and-temperature)."""

    steps: int
    real_steps_per_s: float
    losses_steps_per_s: float
    of_real: float
    of_core: float
    booking: str = "python"

    def as_dict(self) -> dict[str, Any]:
        return dataclasses.asdict(self)


def loss_rate(steps: int, repeats: int, core: float) -> LossRate:
    """:class:`LossRate` on im_paper with db_mptc (see :data:`LOSS_DRIVE`)."""
    path = resolve_scenario_path("im_paper")
    text = path.read_text(encoding="utf-8")
    real, on = (
        load_scenario_text(apply_settings(text, s, path), path).with_strategy("db_mptc")
        for s in (LOSS_DRIVE, LOSSES_ON)
    )
    for sc in (real, on):  # not timed: numba's kernels load once a process (about 0.4 s)
        run_inprocess(sc, steps=200)
    pairs = [(_core_rate(real, steps), _core_rate(on, steps)) for _ in range(repeats)]
    return LossRate(
        steps,
        _median([a for a, _ in pairs]),
        _median([b for _, b in pairs]),
        _median([b / a for a, b in pairs]),
        _median([b for _, b in pairs]) / core,
        "python" if kernel_unavailable() else "compiled",
    )


def _core_rate(sc: Any, steps: int) -> float:
    """Steps/s of the core loop in one run of ``steps``."""
    t0 = time.perf_counter()
    run_inprocess(sc, steps=steps)
    return steps / (time.perf_counter() - t0)


def _median(values: list[float]) -> float:
    return sorted(values)[len(values) // 2]


@dataclass(frozen=True)
class Bench:
    """``bench``: throughput figures of this machine, all from one call (compare them only as
    ratios within a call: the machine's speed drifts between sessions)."""

    steps: int  #: steps of each in-process run
    core_steps_per_s: float  #: the in-process loop without recording, median of the repeats
    core_steps_per_s_runs: list[float]
    #: the in-process loop writing its bag, median of the repeats (each after a core run)
    inprocess_recorded_steps_per_s: float
    #: reading that bag back and evaluating it (what report does), median of the repeats
    report_steps_per_s: float
    #: each recorded run / the core run just before it, and each report / that core run: the
    #: medians (the machine drifts within a call; a pair drifts less)
    inprocess_recorded_of_core: float
    report_x_core: float
    compute_us_per_step: dict[str, float]  #: median control-law time per strategy
    real_time_steps_per_s: float
    graph: list[GraphRate]
    horizons: list[HorizonRate]
    losses: LossRate | None = None

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "core_steps_per_s": self.core_steps_per_s,
            "core_steps_per_s_runs": self.core_steps_per_s_runs,
            "steps": self.steps,
            "compute_us_per_step": self.compute_us_per_step,
            "real_time_steps_per_s": self.real_time_steps_per_s,
            "inprocess_recorded_steps_per_s": self.inprocess_recorded_steps_per_s,
            "report_steps_per_s": self.report_steps_per_s,
            "inprocess_recorded_of_core": self.inprocess_recorded_of_core,
            "report_x_core": self.report_x_core,
            "horizons": [h.as_dict() for h in self.horizons],
            "losses": None if self.losses is None else self.losses.as_dict(),
        }
        for g in self.graph:
            out[g.run.key] = g.steps_per_s
            out[g.run.key.replace("steps_per_s", "startup_s")] = g.startup_s
            out[g.run.key.replace("steps_per_s", "core_near_steps_per_s")] = g.core_near_steps_per_s
        return out


def graph_runs(keys: Sequence[str]) -> tuple[GraphRun, ...]:
    """The graph runs of :data:`GRAPH_RUNS` named by ``keys`` (``ros_example_dtc`` or
    ``ros_example_dtc_steps_per_s``), in their order; ConfigError lists the keys."""
    known = {g.key.removesuffix("_steps_per_s"): g for g in GRAPH_RUNS}
    wanted = [k.removesuffix("_steps_per_s") for k in keys]
    unknown = [k for k in wanted if k not in known]
    if unknown:
        raise ConfigError(f"--graph {unknown[0]}: not a graph run; one of {', '.join(known)}")
    return tuple(g for name, g in known.items() if name in wanted)


def _with_external(
    runs: tuple[GraphRun, ...], command: str, label: str | None
) -> tuple[GraphRun, ...]:
    """``runs`` and, beside them, the default graph with the user's torque controller started
    by ``command`` (checked first, as run --external checks it)."""
    from ..ros.processes import command_line

    command_line(command, option="--external torque_controller=")
    name = external_name(label or "torque_controller").removeprefix(EXTERNAL_PREFIX)
    yours = GraphRun(
        "ros", "paired", "batch", "one_step", f"ros_external_{name}_steps_per_s",
        f"four processes, the torque controller your node `{command}`, recording on",
        command=command,
    )  # fmt: skip
    return (*runs, yours)


def bench(
    *,
    repeats: int = 3,
    steps: int = 20000,
    ros: bool = True,
    quick: bool = False,
    graph: Sequence[str] = (),
    horizons: bool = True,
    horizon_steps: int = 4000,
    external: str | None = None,
    label: str | None = None,
    losses: bool = True,
) -> Bench:
    """Throughput figures (printed by ``predictive-drive bench``; never asserted in tests).
    ``quick``: one repeat of 2,000 steps, horizons over 200 and 0.3 s graph runs of the
    default engines; ``graph``: only these graph runs (see :func:`graph_runs`). ``horizons``:
    time the long-horizon laws (:data:`HORIZON_RUNS`) over ``horizon_steps`` each; ``losses``:
    time losses and temperatures on against off (:class:`LossRate`).
    ``external``: the command of a torque controller of the user's own, timed in the graph
    beside ours (the ``ros`` run, and only it unless ``graph`` says more), its figure keyed
    ``ros_external_LABEL``."""
    chosen = graph_runs(graph) if graph else QUICK_RUNS if quick else GRAPH_RUNS
    if external is not None:
        chosen = _with_external(graph_runs(graph or ["ros"]), external, label)
    if quick:
        repeats, steps, horizon_steps = 1, 2000, 200
    if repeats < 1:
        raise ConfigError(f"--repeats {repeats}: must be at least 1")
    if steps < 2000:
        raise ConfigError(
            f"--steps {steps}: must be at least 2000 (0.1 s of im_paper: the compute times are "
            "taken after the first 0.05 s)"
        )
    sc = load_scenario("im_paper", strategy="db_mptc")
    rates: list[float] = []
    recorded: list[float] = []
    report_rates: list[float] = []
    with tempfile.TemporaryDirectory() as tmp:
        # interleaved, so that the machine's drift touches each figure alike; the medians
        for i in range(repeats):
            rates.append(_core_rate(sc, steps))
            bag = Path(tmp) / f"bench{i}"
            t0 = time.perf_counter()
            n = run_inprocess_to_bag(sc.with_duration(steps * sc.ts), bag)
            recorded.append(n / (time.perf_counter() - t0))
            # what `report` does: read the recording back and evaluate it
            t0 = time.perf_counter()
            evaluate(bag)
            report_rates.append(n / (time.perf_counter() - t0))
    compute = {}
    for name in strategy_names(sc.family):
        tr = run_inprocess(sc.with_strategy(name), steps=steps)
        m = compute_metrics(tr, t_start=0.05)
        compute[name] = m.compute_ns_median / 1e3
    measured: list[GraphRate] = []
    if ros:
        for g in chosen:
            yours: dict[str, str | None] | None = None
            if g.command:
                yours = {"torque_controller": g.command}
            if g.example_dtc:
                command = example_dtc()
                if command is None:
                    measured.append(GraphRate(g, None, math.nan))  # not here: no figure
                    continue
                yours = {"torque_controller": command}
            before = _core_rate(sc, steps)
            r = graph_rate(
                g.engine,
                affinity=g.affinity,
                sched=g.sched,
                speed_loop=g.speed_loop,
                duration=0.3 if quick else g.example_dtc or (0.5 if g.command else 2.0),
                external=yours,
            )
            near = (before + _core_rate(sc, steps)) / 2
            measured.append(GraphRate(g, r["steps_per_s"], r["startup_s"], near))
    rows = []
    if horizons:
        core = _median(rates)
        for strategy, scenario, ns in HORIZON_RUNS:
            for n in ns:
                before = _core_rate(sc, steps)
                h = horizon_rate(strategy, scenario, n, horizon_steps, core)
                near = (before + _core_rate(sc, steps)) / 2
                rows.append(
                    dataclasses.replace(
                        h, core_near_steps_per_s=near, of_core_near=h.steps_per_s / near
                    )
                )
    loss_row = loss_rate(steps, repeats, _median(rates)) if losses else None
    return Bench(
        steps=steps,
        core_steps_per_s=_median(rates),
        core_steps_per_s_runs=rates,
        inprocess_recorded_steps_per_s=_median(recorded),
        report_steps_per_s=_median(report_rates),
        inprocess_recorded_of_core=_median([x / c for x, c in zip(recorded, rates)]),
        report_x_core=_median([x / c for x, c in zip(report_rates, rates)]),
        compute_us_per_step=compute,
        real_time_steps_per_s=1.0 / sc.ts,
        graph=measured,
        horizons=rows,
        losses=loss_row,
    )
