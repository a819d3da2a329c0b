"""``predictive-drive report``: a recording's metrics, from the recording alone."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..core.analysis import LoadStep, load_steps
from ..core.machines import Machine
from ..core.metrics import Metrics, compute_metrics
from ..core.scenario import Scenario
from ..core.trace import Trace
from ..readback import BagInfo, read_bag
from ..recording import (
    StrategySpan,
    command_span_keys,
    scenario_of,
    spans_from_json,
    strategy_spans,
)

__all__ = [
    "Evaluation",
    "ParameterChange",
    "RecordingDetails",
    "Report",
    "SpanTimes",
    "details_of",
    "evaluate",
    "metrics_of",
    "metrics_window",
    "report",
    "steps_of",
    "strategies_of",
]


@dataclass(frozen=True)
class Evaluation:
    """A recording read back: its trace, its scenario and the metrics over the scenario's window
    (clipped to what the recording holds: ``window_note`` says so when it was)."""

    trace: Trace
    info: BagInfo
    scenario: Scenario
    metrics: Metrics
    window_note: str = ""

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
    slips = sc.machine is Machine.INDUCTION
    return compute_metrics(trace, t_start=start, t_end=end, thd_window=thd, slips=slips)


def _window_note(trace: Trace, sc: Scenario) -> str:
    """What differs from the scenario's windows because the recording ends early ('' if none)."""
    held = trace.steps * trace.ts
    lo = sc.logger
    notes = []
    if held < min(lo.window_end, sc.run.duration):
        start, end = metrics_window(sc, held)
        notes.append(
            f"the recording ends at {held:g} s, inside or before the metrics window "
            f"{lo.window_start:g}-{lo.window_end:g} s: the metrics cover {start:g}-{end:g} s"
        )
    if lo.thd_window and lo.thd_window[1] > held:
        notes.append(
            f"no THD: the THD window {lo.thd_window[0]:g}-{lo.thd_window[1]:g} s ends later"
        )
    return "; ".join(notes)


def evaluate(bag: str | Path) -> Evaluation:
    """Metrics of a recording over its scenario's window, from the recording alone."""
    trace, info = read_bag(bag)
    sc = scenario_of(info.info, info.path)
    return Evaluation(trace, info, sc, metrics_of(trace, sc), _window_note(trace, sc))


@dataclass(frozen=True)
class SpanTimes:
    """A strategy in force over steps ``first``..``last`` (inclusive), times in s."""

    strategy: str
    first: int
    last: int
    t_start: float
    t_end: float  #: the end of the last step's period


@dataclass(frozen=True)
class ParameterChange:
    """An accepted parameter change the recording holds: when (s), which node, what."""

    t: float
    node: str
    changed: dict[str, object]


@dataclass(frozen=True)
class RecordingDetails:
    """What a recording says besides its metrics: the strategies in force and their steps, the
    accepted parameter changes, the run's outcome (its last /diagnostics), and for a PMSM the
    load steps (the measured current angle and amplitude each settled to)."""

    strategies: list[SpanTimes]
    parameter_events: list[ParameterChange]
    outcome: str
    load_steps: list[LoadStep] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "strategies": [dataclasses.asdict(s) for s in self.strategies],
            "parameter_events": [dataclasses.asdict(e) for e in self.parameter_events],
            "outcome": self.outcome,
        }
        if self.load_steps:
            out["load_steps"] = [
                {**dataclasses.asdict(st), "theta_deg": math.degrees(st.theta)}
                for st in self.load_steps
            ]
        return out


def details_of(ev: Evaluation) -> RecordingDetails:
    """The :class:`RecordingDetails` of a recording read back."""
    ts = ev.trace.ts
    return RecordingDetails(
        strategies=[
            SpanTimes(s.strategy, s.first, s.last, s.first * ts, (s.last + 1) * ts)
            for s in strategies_of(ev)
        ],
        parameter_events=[
            ParameterChange(ns * 1e-9, e.node, dict(e.changed)) for ns, e in ev.info.events
        ],
        outcome=ev.info.custom.get("outcome", ""),
        load_steps=steps_of(ev),
    )


@dataclass(frozen=True)
class Report:
    """``report``: a recording's metrics and details, with what it is and in what state."""

    bag: Path
    scenario: str
    family: str
    strategy: str
    engine: str
    steps: int
    planned_steps: int
    complete: bool  #: False: the file was cut short (no index) and read up to its cut
    metrics: Metrics
    details: RecordingDetails
    window_note: str = ""
    figures: list[Path] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        out = {
            "bag": str(self.bag),
            "scenario": self.scenario,
            "family": self.family,
            "strategy": self.strategy,
            "engine": self.engine,
            "steps": self.steps,
            "planned_steps": self.planned_steps,
            "complete": self.complete,
            "metrics": self.metrics.as_dict(),
            **self.details.as_dict(),
            "window_note": self.window_note,
        }
        if self.figures:
            out["figures"] = [str(p) for p in self.figures]
        return out


def report(bag: str | Path, *, figures: str | Path | None = None) -> Report:
    """Metrics of a recording, from the recording alone; for a PMSM, per load step also the
    measured current angle and amplitude it settled to (the MTPA view). ``figures``: a folder to
    draw the paper-style figures into (PNG)."""
    ev = evaluate(bag)
    drawn: list[Path] = []
    if figures is not None:
        from ..reports.figures import Run, run_figures, save

        label = f"{ev.scenario.name} {ev.info.info['strategy']}"
        drawn = save(run_figures(Run(ev.trace, ev.scenario, label)), figures)
    return Report(
        bag=Path(bag),
        scenario=ev.info.info["scenario"],
        family=ev.scenario.family,
        strategy=ev.info.info["strategy"],
        engine=ev.info.info["engine"],
        steps=ev.steps,
        planned_steps=ev.scenario.run.steps,
        complete=ev.info.complete,
        metrics=ev.metrics,
        details=details_of(ev),
        window_note=ev.window_note,
        figures=drawn,
    )


def strategies_of(ev: Evaluation) -> list[StrategySpan]:
    """The strategies in force and their steps: as the bag's metadata lists them, or, for a
    recording that never closed (or predates the list), from its commands."""
    if "strategies" in ev.info.custom:
        return spans_from_json(ev.info.custom["strategies"])
    tr = ev.trace
    return strategy_spans(command_span_keys(tr.command), tr.strategy_names)


def steps_of(ev: Evaluation) -> list[LoadStep]:
    """A PMSM run's load steps (the measured current angle and amplitude each settled to); none
    for an induction machine, whose rotor angle says nothing of its current's."""
    sc = ev.scenario
    if sc.machine != Machine.PMSM:
        return []
    return load_steps(ev.trace, load_times=sc.plant.load_times, load_values=sc.plant.load_values)
