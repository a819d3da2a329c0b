"""What a run records, shared by the in-process engine and the metrics_logger node.

Per step: state, reference and command; every :data:`~.interface.CLOCK_PERIOD` of simulated time
the plant's ``/clock`` and ``/drive/joint_states``; every 0.1 s of simulated time (10 Hz)
``/diagnostics`` and ``/drive/metrics`` with the period's running metrics, and the run's outcome at
its end. The plant node publishes the tool messages built by :func:`tool_messages`, so both engines
record the same bytes.
"""

from __future__ import annotations

import dataclasses
import itertools
import json
import math
import os
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .bag import BagWriter
from .codec import (
    CODECS,
    ERROR,
    LEVEL_NAMES,
    OK,
    WARN,
    diagnostics_value,
    encode_clock,
    encode_diagnostics,
    encode_joint_state,
    encode_parameter_event,
    stamp_ns,
    tool_stamp_ns,
)
from .config import load_scenario_text
from .core.control import strategy_names
from .core.metrics import LiveMetrics
from .core.scenario import Scenario
from .core.signals import COMMAND_INDEX, STATE_INDEX
from .core.timebase import every_steps
from .interface import CLOCK_PERIOD, RECORD_TOPICS, TOOL_TOPICS, TOPICS, node_name

__all__ = [
    "DIAGNOSTICS_NAME",
    "RunRecorder",
    "StrategySpan",
    "bag_info",
    "default_bag_dir",
    "diagnostics_message",
    "scenario_of",
    "spans_from_json",
    "strategy_spans",
    "tool_every",
    "tool_messages",
]

DIAGNOSTICS_NAME = "predictive_drive: drive"
K = STATE_INDEX.k  #: the step: the first field of every per-step record
T = STATE_INDEX.t  #: simulated time: the second field of every per-step record


def bag_info(sc: Scenario, engine: str) -> dict[str, Any]:
    """What a bag stores about its run (the ``predictive_drive`` metadata record)."""
    return {
        "scenario": sc.name,
        "scenario_yaml": sc.text,
        "scenario_source": sc.source,
        "family": sc.family,
        "strategy": sc.strategy,
        "duration": repr(sc.run.duration),
        "ts": repr(sc.ts),
        "engine": engine,
        "strategy_names": list(strategy_names(sc.family)),
    }


def scenario_of(info: dict[str, str], where: Path) -> Scenario:
    """The scenario a recording was made with, from its ``predictive_drive`` metadata record."""
    sc = load_scenario_text(info["scenario_yaml"], f"{where} (stored scenario)", legacy=True)
    return sc.with_strategy(info["strategy"]).with_duration(float(info["duration"]))


def default_bag_dir(sc: Scenario, root: str | Path = "bags") -> Path:
    """``bags/<scenario>_<strategy>_<date-time>_<pid>``."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    return Path(root) / f"{sc.name}_{sc.strategy}_{stamp}_{os.getpid()}"


def tool_every(ts: float) -> int:
    """/clock and /drive/joint_states go out every this many steps (CLOCK_PERIOD of sim time)."""
    return every_steps(CLOCK_PERIOD, ts)


def tool_messages(state: tuple[float, ...], every: int) -> list[tuple[str, int, bytes]]:
    """/clock and /drive/joint_states for state k when k is a multiple of ``every``."""
    S = STATE_INDEX
    k = int(state[S.k])
    if k % every:
        return []
    t = state[S.t]
    ns = stamp_ns(t)
    joint = encode_joint_state(t, state[S.theta_m], state[S.omega_m], state[S.torque])
    return [("clock", ns, encode_clock(t)), ("joint_states", ns, joint)]


#: diagnostics values that are counts, written as integers
_COUNTS = ("k", "steps", "steps_planned")


def diagnostics_message(
    snap: dict[str, float], level: int, message: str, strategy_names: tuple[str, ...]
) -> tuple[int, bytes]:
    """The /diagnostics message of a snapshot: counts as integers, figures as exact floats,
    the strategy by name."""
    name = strategy_name(strategy_names, snap["strategy"]) if "strategy" in snap else ""
    values = [
        (key, str(int(v)) if key in _COUNTS else diagnostics_value(v))
        for key, v in snap.items()
        if key not in ("t", "strategy")
    ]
    values.append(("strategy", name))
    t = snap["t"]
    return stamp_ns(t), encode_diagnostics(t, [(level, DIAGNOSTICS_NAME, message, values)])


@dataclass(frozen=True)
class StrategySpan:
    """A strategy in force over steps ``first``..``last`` (inclusive) of a run."""

    strategy: str
    first: int
    last: int


def spans_to_json(spans: list[StrategySpan]) -> str:
    return json.dumps([dataclasses.asdict(s) for s in spans])


def spans_from_json(text: str) -> list[StrategySpan]:
    return [StrategySpan(**d) for d in json.loads(text)]


def strategy_spans(
    strategy: Iterable[float], names: tuple[str, ...], k0: int = 0
) -> list[StrategySpan]:
    """The spans of a run's per-step strategy index (the command's ``strategy`` field)."""
    spans, k = [], k0
    for index, steps in itertools.groupby(strategy):
        n = sum(1 for _ in steps)
        spans.append(StrategySpan(strategy_name(names, index), k, k + n - 1))
        k += n
    return spans


def strategy_name(names: tuple[str, ...], index: float) -> str:
    return names[int(index)] if 0 <= index < len(names) else "?"


#: the topics a node's recorder receives each in order but not in order with one another: the
#: per-step records and the plant's tool topics
_STREAMS = ("state", "reference", "command", *TOOL_TOPICS)


class RunRecorder:
    """Writes a run into a :class:`BagWriter` in log-time order and keeps the running metrics.

    The graph delivers each topic in order but gives no order across topics (command k arrives
    after state k+1): every message is held until each topic the recorder waits on has passed
    its time, so the file reads in log-time order (what rosbag2's writer and MCAP readers expect).
    The in-process engine hands its records over in time order, so they are written at once.
    ``publish(topic_key, data)`` (optional) also sends what it produces (/diagnostics,
    /drive/metrics: the node's publishers); the in-process engine records only. ``steps``: the
    run's planned steps, for the progress in /diagnostics and the final outcome.
    """

    def __init__(
        self,
        writer: BagWriter,
        *,
        ts: float,
        steps: int,
        torque_limit: float,
        strategy_names: tuple[str, ...],
        record_tools: bool,
        publish: Callable[[str, bytes], None] | None = None,
        live: Callable[[str, int, bytes], None] | None = None,
    ) -> None:
        """``record_tools``: the in-process engine, where the recorder also writes what the
        plant and the controller node would publish: /clock, /drive/joint_states, and a
        parameter event when the strategy changes. ``live(topic_key, t_ns, data)``: a second
        sink that sees every message as it comes (the live view)."""
        self.writer = writer
        self.live = LiveMetrics(ts=ts, torque_limit=torque_limit)
        self.strategy_names = strategy_names
        self.ts = ts
        self.steps = steps
        self._every = tool_every(ts)
        self._tools = self._events = record_tools
        self._publish = publish
        self._live = live
        self.last_t = 0.0
        #: the last log time seen on each topic the recorder waits on (each comes in order);
        #: none in-process, whose records come in time order
        self._seen = {} if record_tools else dict.fromkeys(_STREAMS, -1)
        self._released = -1
        self._warned = ""
        self._finished = False
        self._spans: list[StrategySpan] = []  #: the last one's end is ``_through``
        self._index = math.nan  #: the strategy index of the last span
        self._through = -1

    def record(self, record: str, row: tuple[float, ...]) -> None:
        """In-process path: encode, write, and the plant's tool messages with each state."""
        key = RECORD_TOPICS[record]
        ns = stamp_ns(row[T])
        self._hold(key, ns, CODECS[key].encode(row))
        if self._tools and record == "state":
            for tkey, tns, data in tool_messages(row, self._every):
                self._hold(tkey, tns, data)
        self._feed(record, row, ns)

    def record_raw(self, record: str, data: bytes) -> tuple[float, ...]:
        """Node path: write the bytes as received, decode for the running metrics."""
        key = RECORD_TOPICS[record]
        row = CODECS[key].decode(data)
        ns = stamp_ns(row[T])
        self._hold(key, ns, data)
        self._feed(record, row, ns)
        return row

    def record_tool(self, key: str, data: bytes) -> None:
        """Node path: /clock or /drive/joint_states as the plant published it."""
        ns = tool_stamp_ns(data)
        self._hold(key, ns, data)
        self._advance(key, ns)

    def record_event(self, data: bytes) -> None:
        """An accepted parameter change (rcl_interfaces/ParameterEvent), logged at the time it
        arrives on the simulated clock (the last step seen), as rosbag2 logs receive time."""
        self._hold("parameter_events", max(stamp_ns(self.last_t), self._floor()), data)

    def _floor(self) -> int:
        """The earliest log time a message made now may have: what is written or released."""
        return max(self._released, self.writer.last_ns)

    def _hold(self, key: str, ns: int, data: bytes) -> None:
        if self._seen:
            self.writer.hold(key, ns, data)
        else:
            self.writer.write(key, ns, data)
        if self._live is not None:
            self._live(key, ns, data)

    def _feed(self, record: str, row: tuple[float, ...], ns: int) -> None:
        if row[T] > self.last_t:
            self.last_t = row[T]
        if record == "command":
            self._span(int(row[K]), row[COMMAND_INDEX.strategy])
        self._diagnose(self.live.add(record, row))
        self._advance(record, ns)

    def _advance(self, topic: str, ns: int) -> None:
        if not self._seen:
            return
        self._seen[topic] = ns
        through = min(self._seen.values())
        if through > self._released:
            self._released = through
            self.writer.release(through)

    def _span(self, k: int, index: float) -> None:
        """Command k ran strategy ``index``: the span goes on, or a new one starts (in-process
        with the parameter event the controller node would publish)."""
        if index == self._index and k == self._through + 1:
            self._through = k
            return
        self._seal()
        self._index, self._through = index, k
        name = strategy_name(self.strategy_names, index)
        self._spans.append(StrategySpan(name, k, k))
        if k > 0 and self._events:
            t = k * self.ts
            data = encode_parameter_event(t, node_name("torque_controller"), [("strategy", name)])
            self._hold("parameter_events", stamp_ns(t), data)

    def _seal(self) -> None:
        if self._spans and self._spans[-1].last != self._through:
            self._spans[-1] = dataclasses.replace(self._spans[-1], last=self._through)

    @property
    def spans(self) -> list[StrategySpan]:
        """The strategies in force so far and their steps."""
        self._seal()
        return list(self._spans)

    def finish(self, error: str = "") -> None:
        """The last, partial diagnostics period, then the run's outcome: OK (or WARN, naming
        what was wrong) when every planned step is recorded, ERROR with ``error`` or the steps
        missing otherwise; the strategies in force go into the bag's metadata. Once."""
        if self._finished or self.writer.failed:  # a bag that failed takes nothing more
            return
        self._finished = True
        self._diagnose(self.live.flush())
        total = self.live.total() or {"k": -1.0, "t": self.last_t, "steps": 0.0}
        done = int(total["steps"])
        total = {**total, "steps_planned": float(self.steps)}
        figures = (
            f"; over the run T_e RMSE {total['t_rmse']:.4g} N·m, f_ave {total['f_ave_hz']:.5g} Hz"
            if "t_rmse" in total
            else ""
        )
        if error or done < self.steps:
            level, message = ERROR, f"{error or 'stopped'}: {done} of {self.steps} steps{figures}"
        elif self._warned:
            level, message = WARN, f"complete: {done} steps{figures}; {self._warned}"
        else:
            level, message = OK, f"complete: {done} steps{figures}"
        ns, data = diagnostics_message(total, level, message, self.strategy_names)
        self._hold("diagnostics", max(ns, self._floor()), data)
        if self._publish is not None:
            self._publish("diagnostics", data)
        self.writer.custom_data["strategies"] = spans_to_json(self.spans)
        self.writer.custom_data["outcome"] = f"{LEVEL_NAMES[level]}: {message}"

    def _diagnose(self, snap: dict[str, float] | None) -> None:
        if snap is None:
            return
        level, wrong = self.live.level(snap)
        if wrong and not self._warned:
            self._warned = f"from {snap['t']:.6g} s: {wrong}"
        message = wrong or f"running: {int(snap['steps'])} of {self.steps} steps"
        ns, data = diagnostics_message(snap, level, message, self.strategy_names)
        metrics = CODECS["metrics"].encode(
            tuple(float(level) if f == "level" else snap[f] for f in TOPICS["metrics"].fields)
        )
        ns = max(ns, self._floor())  # the last, partial period comes after the final state
        self._hold("diagnostics", ns, data)
        self._hold("metrics", ns, metrics)
        if self._publish is not None:
            self._publish("diagnostics", data)
            self._publish("metrics", metrics)

    def error(self, message: str) -> bytes:
        """Record (and return) an ERROR diagnostics status, e.g. when a peer went silent."""
        t = self.last_t
        data = encode_diagnostics(t, [(ERROR, DIAGNOSTICS_NAME, message, [])])
        self._hold("diagnostics", max(stamp_ns(t), self._floor()), data)
        return data
