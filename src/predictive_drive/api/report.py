"""``predictive-drive report``: a recording's metrics, from the recording alone."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..core.analysis import load_steps
from ..core.machines import Machine
from ..core.metrics import Metrics, compute_metrics
from ..core.scenario import Scenario
from ..core.trace import Trace
from ..readback import BagInfo, read_bag
from ..recording import StrategySpan, scenario_of, spans_from_json, strategy_spans

__all__ = [
    "Evaluation",
    "evaluate",
    "metrics_window",
    "report",
    "steps_of",
    "strategies_of",
    "details_of",
]


@dataclass(frozen=True)
class Evaluation:
    """A recording read back: its trace, its scenario and the metrics over the scenario's window."""

    trace: Trace
    info: BagInfo
    scenario: Scenario
    metrics: Metrics

    @property
    def steps(self) -> int:
        return self.trace.steps


def metrics_window(sc: Scenario, recorded_s: float | None = None) -> tuple[float, float]:
    """The scenario's metrics window, clipped to the run and to the ``recorded_s`` seconds a
    recording holds: a run (or a recording cut short) that ends before the window's start is
    evaluated whole."""
    lo = sc.logger
    end = min(lo.window_end, sc.run.duration)
    if recorded_s is not None:
        end = min(end, recorded_s)
    start = lo.window_start if lo.window_start < end else 0.0
    return start, end


def metrics_of(trace: Trace, sc: Scenario) -> Metrics:
    """A run's metrics over its scenario's window, clipped to what the trace holds (and the THD
    window, when the trace reaches its end)."""
    start, end = metrics_window(sc, trace.steps * trace.ts)
    thd = sc.logger.thd_window
    if thd and thd[1] > trace.steps * trace.ts:
        thd = ()  # a run (or a cut recording) that ends before the THD window: no THD
    return compute_metrics(trace, t_start=start, t_end=end, thd_window=thd)


def evaluate(bag: str | Path) -> Evaluation:
    """Metrics of a recording over its scenario's window, from the recording alone."""
    trace, info = read_bag(bag)
    sc = scenario_of(info.info, info.path)
    return Evaluation(trace, info, sc, metrics_of(trace, sc))


def report(bag: str | Path, *, figures: str | Path | None = None) -> dict[str, Any]:
    """Metrics of a recording, from the recording alone; for a PMSM, per load step also the
    measured current angle and amplitude it settled to (the MTPA view, SPEC §3.4). ``figures``:
    a folder to draw the paper-style figures into (PNG)."""
    ev = evaluate(bag)
    out: dict[str, Any] = {
        "bag": str(Path(bag)),
        "scenario": ev.info.info["scenario"],
        "family": ev.scenario.family,
        "strategy": ev.info.info["strategy"],
        "engine": ev.info.info["engine"],
        "steps": ev.steps,
        "planned_steps": ev.scenario.run.steps,
        "complete": ev.info.complete,
        "metrics": ev.metrics.as_dict(),
        **details_of(ev),
    }
    if figures is not None:
        from ..reports.figures import Run, run_figures, save

        label = f"{ev.scenario.name} {ev.info.info['strategy']}"
        drawn = save(run_figures(Run(ev.trace, ev.scenario, label)), figures)
        out["figures"] = [str(p) for p in drawn]
    return out


def details_of(ev: Evaluation) -> dict[str, Any]:
    """What a recording says besides its metrics: the strategies in force and their steps, the
    accepted parameter changes, the run's outcome, and (a PMSM) the load steps."""
    ts = ev.trace.ts
    out: dict[str, Any] = {
        "strategies": [
            {**dataclasses.asdict(s), "t_start": s.first * ts, "t_end": (s.last + 1) * ts}
            for s in strategies_of(ev)
        ],
        "parameter_events": [
            {"t": ns * 1e-9, "node": e.node, "changed": dict(e.changed)} for ns, e in ev.info.events
        ],
        "outcome": ev.info.custom.get("outcome", ""),
    }
    if steps := steps_of(ev):
        out["load_steps"] = steps
    return out


def strategies_of(ev: Evaluation) -> list[StrategySpan]:
    """The strategies in force and their steps: as the bag's metadata lists them, or, for a
    recording that never closed (or predates the list), from its commands."""
    if "strategies" in ev.info.custom:
        return spans_from_json(ev.info.custom["strategies"])
    tr = ev.trace
    return strategy_spans(tr.col("command", "strategy"), tr.strategy_names)


def steps_of(ev: Evaluation) -> list[dict[str, Any]]:
    """A PMSM run's load steps (the measured current angle and amplitude each settled to); none
    for an induction machine, whose rotor angle says nothing of its current's."""
    sc = ev.scenario
    if sc.machine != Machine.PMSM:
        return []
    steps = load_steps(ev.trace, load_times=sc.plant.load_times, load_values=sc.plant.load_values)
    return [{**dataclasses.asdict(st), "theta_deg": math.degrees(st.theta)} for st in steps]
