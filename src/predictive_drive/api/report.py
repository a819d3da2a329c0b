"""``predictive-drive report``: a recording's metrics, from the recording alone."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..bag import BagInfo, read_bag
from ..core.metrics import Metrics, compute_metrics
from ..core.scenario import Scenario
from ..core.trace import Trace
from ..recording import scenario_of

__all__ = ["Evaluation", "evaluate", "metrics_window", "report"]


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


def metrics_window(sc: Scenario) -> tuple[float, float]:
    """The scenario's metrics window, clipped to the run (a run shorter than the window's start is
    evaluated whole)."""
    lo = sc.logger
    end = min(lo.window_end, sc.run.duration)
    start = lo.window_start if lo.window_start < end else 0.0
    return start, end


def evaluate(bag: str | Path) -> Evaluation:
    """Metrics of a recording over its scenario's window, from the recording alone."""
    trace, info = read_bag(bag)
    sc = scenario_of(info.info, info.path)
    start, end = metrics_window(sc)
    thd = sc.logger.thd_window
    if thd and thd[1] > trace.steps * trace.ts:
        thd = ()  # a run (or a cut recording) that ends before the THD window: no THD
    metrics = compute_metrics(trace, t_start=start, t_end=end, thd_window=thd)
    return Evaluation(trace, info, sc, metrics)


def report(bag: str | Path) -> dict[str, Any]:
    """Metrics of a recording, from the recording alone."""
    ev = evaluate(bag)
    return {
        "bag": str(Path(bag)),
        "scenario": ev.info.info["scenario"],
        "strategy": ev.info.info["strategy"],
        "engine": ev.info.info["engine"],
        "steps": ev.steps,
        "complete": ev.info.complete,
        "metrics": ev.metrics.as_dict(),
    }
