"""``predictive-drive report``: a recording's metrics, from the recording alone."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..core.analysis import LoadStep, load_steps
from ..core.losses import Overheat, overheats
from ..core.machines import Machine
from ..core.metrics import Metrics, compute_metrics
from ..core.scenario import Scenario
from ..core.trace import Trace
from ..errors import ConfigError
from ..outputs import check_output_dir
from ..readback import BagInfo, read_bag
from ..recording import (
    OwnNode,
    StrategySpan,
    command_span_keys,
    run_label,
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
    "with_windows",
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
    window, when the trace reaches its end and the window holds a whole electrical cycle)."""
    return _evaluated(trace, sc)[0]


def _evaluated(trace: Trace, sc: Scenario) -> tuple[Metrics, str]:
    """:func:`metrics_of`, and what differs from the scenario's windows because the recording
    ends early or the THD window holds no whole cycle ('' if nothing)."""
    held = trace.steps * trace.ts
    lo = sc.logger
    start, end = metrics_window(sc, held)
    notes = []
    if held < min(lo.window_end, sc.run.duration):
        notes.append(
            f"the recording ends at {held:g} s, inside or before the metrics window "
            f"{lo.window_start:g}-{lo.window_end:g} s: the metrics cover {start:g}-{end:g} s"
        )
    thd = lo.thd_window
    if thd and thd[1] > held:  # a run (or a cut recording) that ends before the THD window
        notes.append(f"no THD: the THD window {thd[0]:g}-{thd[1]:g} s ends later")
        thd = ()
    slips = sc.machine is Machine.INDUCTION
    try:
        m = compute_metrics(trace, t_start=start, t_end=end, thd_window=thd, slips=slips)
    except ConfigError as e:  # the THD window's: the run turned too slowly in it
        notes.append(f"no THD: {e} (`report --thd-window A,B` evaluates another)")
        m = compute_metrics(trace, t_start=start, t_end=end, slips=slips)
    return m, "; ".join(notes)


def with_windows(
    sc: Scenario,
    *,
    window: tuple[float, float] | None = None,
    thd_window: tuple[float, float] | None = None,
) -> Scenario:
    """The scenario evaluated over another metrics ``window`` and/or THD window (s, [start,
    end)), as ``report --window A,B --thd-window A,B`` asks; ConfigError names the option."""
    for option, given in (("--window", window), ("--thd-window", thd_window)):
        if given is None:
            continue
        a, b = given
        if not (0 <= a < b):
            raise ConfigError(f"{option} {a:g},{b:g}: need 0 <= A < B (s)")
        if b > sc.run.duration:
            raise ConfigError(f"{option} {a:g},{b:g}: ends beyond the run ({sc.run.duration:g} s)")
    lo = sc.logger
    if window is not None:
        lo = dataclasses.replace(lo, window_start=window[0], window_end=window[1])
    if thd_window is not None:
        lo = dataclasses.replace(lo, thd_window=tuple(thd_window))
    return dataclasses.replace(sc, logger=lo)


def evaluate(
    bag: str | Path,
    *,
    window: tuple[float, float] | None = None,
    thd_window: tuple[float, float] | None = None,
) -> Evaluation:
    """Metrics of a recording over its scenario's window (or ``window``, and the THD over
    ``thd_window``: see :func:`with_windows`), from the recording alone."""
    trace, info = read_bag(bag)
    sc = with_windows(scenario_of(info.info, info.path), window=window, thd_window=thd_window)
    return Evaluation(trace, info, sc, *_evaluated(trace, sc))


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
    #: the nodes of the user's own: how each was started, the parameters its section gave it
    own_nodes: list[OwnNode] = field(default_factory=list)
    #: a replay into a controller (``replay --into``): the recording whose states it was fed
    #: ('' for a run). Its plant's figures are that recording's; its commands are the node's
    replay_of: str = ""
    #: the inverter's devices (their part name; '' without losses) and each device whose
    #: junction went above its rated temperature (docs/physics.md#losses-and-temperature)
    device: str = ""
    rated_tj: tuple[float, float] = (math.nan, math.nan)  #: transistor's, diode's, °C
    overheats: list[Overheat] = field(default_factory=list)
    #: the steps a long horizon's search decided, and those of them whose node budget ran out
    #: (the best sequence found so far applied: docs/physics.md#a-budget-per-step)
    searched_steps: int = 0
    suboptimal_steps: int = 0

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "strategies": [dataclasses.asdict(s) for s in self.strategies],
            "parameter_events": [dataclasses.asdict(e) for e in self.parameter_events],
            "outcome": self.outcome,
            "own_nodes": [dataclasses.asdict(n) for n in self.own_nodes],
            "replay_of": self.replay_of,
            "searched_steps": self.searched_steps,
            "suboptimal_steps": self.suboptimal_steps,
        }
        if self.device:
            out["device"] = self.device
            out["rated_tj"] = list(self.rated_tj)
            out["overheats"] = [dataclasses.asdict(o) for o in self.overheats]
        if self.load_steps:
            out["load_steps"] = [
                {**dataclasses.asdict(st), "theta_deg": math.degrees(st.theta)}
                for st in self.load_steps
            ]
        return out


def details_of(ev: Evaluation) -> RecordingDetails:
    """The :class:`RecordingDetails` of a recording read back."""
    ts = ev.trace.ts
    suboptimal = ev.trace.col("command", "suboptimal")
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
        own_nodes=ev.info.own_nodes,
        replay_of=ev.info.info.get("replay_of", ""),
        device="" if (d := ev.scenario.device) is None else d.name,
        rated_tj=(math.nan, math.nan) if d is None else (d.switch.t_j_max, d.diode.t_j_max),
        overheats=overheats(ev.trace, d),
        searched_steps=int(np.isfinite(suboptimal).sum()),
        suboptimal_steps=int((suboptimal == 1.0).sum()),
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


def report(
    bag: str | Path,
    *,
    figures: str | Path | None = None,
    window: tuple[float, float] | None = None,
    thd_window: tuple[float, float] | None = None,
) -> Report:
    """Metrics of a recording, from the recording alone; for a PMSM, per load step also the
    measured current angle and amplitude it settled to (the MTPA view). ``figures``: a folder to
    draw the paper-style figures into (PNG); ``window``, ``thd_window``: evaluate over these
    instead of the recorded scenario's (s, [start, end))."""
    check_output_dir(figures, option="report --figures")
    ev = evaluate(bag, window=window, thd_window=thd_window)
    drawn: list[Path] = []
    if figures is not None:
        from ..reports.figures import Run, run_figures, save

        label = run_label(ev.info.info)
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
    return strategy_spans(command_span_keys(tr.command), tr.strategy_names, external=tr.external)


def steps_of(ev: Evaluation) -> list[LoadStep]:
    """A PMSM run's load steps (the measured current angle and amplitude each settled to); none
    for an induction machine, whose rotor angle says nothing of its current's."""
    sc = ev.scenario
    if sc.machine != Machine.PMSM:
        return []
    return load_steps(ev.trace, load_times=sc.plant.load_times, load_values=sc.plant.load_values)
