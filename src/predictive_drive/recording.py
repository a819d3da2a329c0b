"""What a run records, shared by the in-process engine and the metrics_logger node.

Per step: state, reference and command; every :data:`~.interface.CLOCK_PERIOD` of simulated time the
plant's ``/clock`` and ``/drive/joint_states``; about once per simulated second ``/diagnostics`` with
running metrics. The plant node publishes the tool messages built by :func:`tool_messages`, so both
engines record the same bytes.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

from .bag import BagWriter
from .config import load_scenario_text
from .core.control import strategy_names
from .core.metrics import LiveMetrics
from .core.scenario import Scenario
from .core.signals import STATE_INDEX
from .core.timebase import every_steps
from .interface import (
    CLOCK_PERIOD,
    CODECS,
    ERROR,
    RECORD_TOPICS,
    encode_clock,
    encode_diagnostics,
    encode_joint_state,
    fmt,
    stamp_ns,
)

__all__ = [
    "DIAGNOSTICS_NAME",
    "RunRecorder",
    "bag_info",
    "default_bag_dir",
    "diagnostics_message",
    "scenario_of",
    "tool_every",
    "tool_messages",
]

DIAGNOSTICS_NAME = "predictive_drive: drive"
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


def diagnostics_message(
    snap: dict[str, float], level: int, message: str, strategy_names: tuple[str, ...]
) -> tuple[int, bytes]:
    s = int(snap.get("strategy", -1))
    name = strategy_names[s] if 0 <= s < len(strategy_names) else ""
    values = [(key, fmt(v)) for key, v in snap.items() if key not in ("t", "strategy")]
    values.append(("strategy", name))
    t = snap["t"]
    return stamp_ns(t), encode_diagnostics(t, [(level, DIAGNOSTICS_NAME, message, values)])


class RunRecorder:
    """Writes a run into a :class:`BagWriter` and keeps the running metrics.

    ``publish(topic_key, data)`` (optional) also sends the diagnostics it produces (the node's
    publisher); the in-process engine records only.
    """

    def __init__(
        self,
        writer: BagWriter,
        *,
        ts: float,
        torque_limit: float,
        strategy_names: tuple[str, ...],
        record_tools: bool,
        publish: Callable[[str, bytes], None] | None = None,
    ) -> None:
        self.writer = writer
        self.live = LiveMetrics(ts=ts, torque_limit=torque_limit)
        self.strategy_names = strategy_names
        self._every = tool_every(ts)
        self._tools = record_tools
        self._publish = publish
        self.last_t = 0.0

    def record(self, record: str, row: tuple[float, ...]) -> None:
        """In-process path: encode, write, and the plant's tool messages with each state."""
        key = RECORD_TOPICS[record]
        self.writer.write(key, stamp_ns(row[T]), CODECS[key].encode(row))
        if self._tools and record == "state":
            for tkey, ns, data in tool_messages(row, self._every):
                self.writer.write(tkey, ns, data)
        self._feed(record, row)

    def record_raw(self, record: str, data: bytes) -> tuple[float, ...]:
        """Node path: write the bytes as received, decode for the running metrics."""
        key = RECORD_TOPICS[record]
        row = CODECS[key].decode(data)
        self.writer.write(key, stamp_ns(row[T]), data)
        self._feed(record, row)
        return row

    def _feed(self, record: str, row: tuple[float, ...]) -> None:
        self.last_t = max(self.last_t, row[T])
        self._diagnose(self.live.add(record, row))

    def finish(self) -> None:
        """The last, partial diagnostics period (so even a short run reports its figures)."""
        self._diagnose(self.live.flush())

    def _diagnose(self, snap: dict[str, float] | None) -> None:
        if snap is not None:
            level, message = self.live.level(snap)
            ns, data = diagnostics_message(snap, level, message, self.strategy_names)
            self.writer.write("diagnostics", ns, data)
            if self._publish is not None:
                self._publish("diagnostics", data)

    def error(self, message: str) -> bytes:
        """Record (and return) an ERROR diagnostics status, e.g. when a peer went silent."""
        t = self.last_t
        data = encode_diagnostics(t, [(ERROR, DIAGNOSTICS_NAME, message, [])])
        self.writer.write("diagnostics", stamp_ns(t), data)
        return data
