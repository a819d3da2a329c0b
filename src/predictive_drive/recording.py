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

import numpy as np

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
from .core.commands import COMMAND_CONTRACT
from .core.control import strategy_names
from .core.metrics import LiveMetrics
from .core.scenario import Scenario
from .core.signals import COMMAND_INDEX, STATE_INDEX, strategy_name
from .core.timebase import every_steps
from .interface import CLOCK_PERIOD, RECORD_TOPICS, TOOL_TOPICS, TOPICS, node_name
from .mcapio import MessageGroup

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
        # a controller of the user's own: the command contract it was held to
        **({"command_contract": str(COMMAND_CONTRACT)} if sc.external else {}),
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
    joint = encode_joint_state(t, state[S.theta_m], state[S.omega_m_true], state[S.torque])
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
    for name, steps in itertools.groupby(strategy, key=lambda i: strategy_name(names, i)):
        n = sum(1 for _ in steps)
        spans.append(StrategySpan(name, k, k + n - 1))
        k += n
    return spans


#: the strategy index before the first span: no command's (theirs are >= 0, or NaN)
_NO_SPAN = -1.0


def _same_strategy(a: float, b: float) -> bool:
    """Two commands' strategy indices name the same strategy (NaN: the user's own, both)."""
    return a == b or (math.isnan(a) and math.isnan(b))


#: the topics a node's recorder receives each in order but not in order with one another: the
#: per-step records and the plant's tool topics
_STREAMS = ("state", "reference", "command", *TOOL_TOPICS)
#: an in-process step as :meth:`RunRecorder.record_step` takes it: state, reference, command
#: (None after the last step), and the three packed
Step = tuple[Any, ...]
#: in-process steps written together (:meth:`RunRecorder.record_step`): 6 ms of a 20 kHz run
STEP_BATCH = 128


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
        self._index = _NO_SPAN  #: the strategy index of the last span
        self._through = -1
        self._batch: list[Step] = []  #: steps taken, not yet written
        keys = [RECORD_TOPICS[r] for r in ("state", "reference", "command")]
        self._sizes = tuple(CODECS[key].size for key in keys)
        #: a step's state, reference and command written as one group: in a node, the messages
        #: as received (see flush); in-process without a live view, the packed rows after each
        #: record's constant prefix (see record_step); with a live view, message by message
        self._group: MessageGroup | None = None
        if not record_tools:
            self._group = writer.group([(key, b"", size) for key, size in zip(keys, self._sizes)])
        elif live is None:
            self._group = writer.group(
                [(key, CODECS[key].prefix, 8 * len(CODECS[key].fields)) for key in keys]
            )
        self._prefix_state = CODECS[RECORD_TOPICS["state"]].prefix
        self._prefix_reference = CODECS[RECORD_TOPICS["reference"]].prefix
        self._prefix_command = CODECS[RECORD_TOPICS["command"]].prefix

    def record_step(
        self,
        state: tuple[float, ...],
        ref: tuple[float, ...],
        cmd: tuple[float, ...] | None,
        state_b: bytes,
        ref_b: bytes,
        cmd_b: bytes,
    ) -> None:  # a core.runner.Sink
        """In-process path (a :data:`~.core.runner.Sink`): step k's state (with the plant's tool
        messages), reference and command (None after the last step), encoded and written in
        that order, as the graph's recorder writes them; ``*_b``: the rows packed (a message's
        payload after its constant prefix). Steps are taken :data:`STEP_BATCH` at a time (the
        work then runs in a tight loop, about twice as fast as spread between the steps of the
        simulation); :meth:`finish` takes the rest."""
        batch = self._batch
        batch.append((state, ref, cmd, state_b, ref_b, cmd_b))
        if len(batch) >= STEP_BATCH or cmd is None:
            self._write_steps()

    def _write_steps(self) -> None:
        batch, self._batch = self._batch, []
        if self._group is None:
            for step in batch:
                self._write_step(step)
            return
        i, n = 0, len(batch)
        while i < n:
            if not self._plain(batch[i], self._through + 1):
                self._write_step(batch[i])  # a new span or the last step
                i += 1
                continue
            # the plain steps that follow, up to the end of a diagnostics period
            j = i + 1
            room = self.live.every - self.live.steps % self.live.every
            while j < n and j - i < room and self._plain(batch[j], int(batch[j - 1][2][K]) + 1):
                j += 1
            self._write_plain_steps(batch[i:j])
            i = j

    def _plain(self, step: Step, k_next: int) -> bool:
        """A step that only goes on: a command, the strategy in force (step ``k_next`` of its
        span), not the first of a span."""
        cmd = step[2]
        return (
            cmd is not None
            and _same_strategy(cmd[COMMAND_INDEX.strategy], self._index)
            and int(cmd[K]) == k_next
        )

    def _write_plain_steps(self, steps: list[Step]) -> None:
        """Consecutive steps of one span: each step's three records in one pack (with the tool
        messages between state and reference where they come), the running metrics of them all
        at once."""
        s, r, c = (
            np.frombuffer(b"".join(step[n] for step in steps), dtype="<f8").reshape(len(steps), -1)
            for n in (3, 4, 5)
        )
        ns = [np.rint(x[:, T] * 1e9).astype(np.int64).tolist() for x in (s, r, c)]
        add3 = self._group.add3  # type: ignore[union-attr]
        every = self._every
        try:
            for k, ts, tr, tc, step in zip(s[:, K].tolist(), *ns, steps):
                if k % every:
                    add3(ts, tr, tc, *step[3:])
                else:
                    self._write_messages(step, ts, tr, tc)
        except OSError as e:
            raise self.writer.write_failed(e) from None
        t = float(max(s[-1, T], r[-1, T], c[-1, T]))
        if t > self.last_t:
            self.last_t = t
        self._through = int(c[-1, K])  # the span goes on (see _plain)
        snap = self.live.add_steps(s, r, c)
        if snap is not None:
            self._diagnose(snap)

    def _write_messages(self, step: Step, ts: int, tr: int, tc: int) -> None:
        """A step's messages one by one: state, the plant's tool messages where they come,
        reference, command (none after the last step)."""
        write = self._hold
        write("state", ts, self._prefix_state + step[3])
        if self._tools and not int(step[0][K]) % self._every:
            for tkey, tns, data in tool_messages(step[0], self._every):
                write(tkey, tns, data)
        write("reference", tr, self._prefix_reference + step[4])
        if step[2] is not None:
            write("command", tc, self._prefix_command + step[5])

    def _write_step(self, step: Step) -> None:
        """One step, messages and running metrics (a new span, the last step, a live view)."""
        state, ref, cmd = step[:3]
        tc = stamp_ns(cmd[T]) if cmd is not None else 0
        self._write_messages(step, stamp_ns(state[T]), stamp_ns(ref[T]), tc)
        t = max(state[T], ref[T])
        if cmd is None:
            if t > self.last_t:
                self.last_t = t
            return
        t = max(t, cmd[T])
        if t > self.last_t:
            self.last_t = t
        k = int(cmd[K])
        index = cmd[COMMAND_INDEX.strategy]
        if _same_strategy(index, self._index) and k == self._through + 1:
            self._through = k
        else:
            self._span(k, index)
        snap = self.live.add_step(state, ref, cmd)
        if snap is not None:
            self._diagnose(snap)

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
            self._released = through  # written at the next flush()

    def flush(self) -> None:
        """Node path: write what every topic has passed (the node calls this after each batch of
        messages it takes; what comes later cannot be earlier), a step's state, reference and
        command in one pack where they follow one another."""
        ready = self.writer.ready(self._released)
        write = self.writer.write
        add3 = self._group.add3  # type: ignore[union-attr]
        sizes = self._sizes
        i, n = 0, len(ready)
        try:
            while i < n:
                t, _, key, data = ready[i]
                if key == "state" and i + 2 < n:
                    r, c = ready[i + 1], ready[i + 2]
                    if (
                        r[2] == "reference"
                        and c[2] == "command"
                        and (len(data), len(r[3]), len(c[3])) == sizes
                    ):
                        add3(t, r[0], c[0], data, r[3], c[3])
                        i += 3
                        continue
                write(key, t, data)
                i += 1
        except OSError as e:
            raise self.writer.write_failed(e) from None

    def _span(self, k: int, index: float) -> None:
        """Command k ran strategy ``index``: the span goes on, or a new one starts (in-process
        with the parameter event the controller node would publish)."""
        if _same_strategy(index, self._index) and k == self._through + 1:
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
        self._write_steps()
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
