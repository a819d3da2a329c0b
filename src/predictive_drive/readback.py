"""A recording read back: the :class:`~predictive_drive.core.trace.Trace` of its per-step topics,
its ``predictive_drive`` metadata, the parameter changes it recorded, and what state the file is
in (closed, or cut short by a killed writer)."""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path

import yaml

from .bag import META_NAME, mcap_file, not_a_recording, read_records
from .codec import CODECS, ParameterEvent, decode_parameter_event
from .core.signals import STATE_INDEX
from .core.trace import RECORDS, Trace, TraceBuilder
from .errors import BagError
from .interface import RECORD_TOPICS, TOPICS

__all__ = ["BagInfo", "BagStatus", "bag_status", "read_bag"]

K = STATE_INDEX.k  #: the step index: the first field of every per-step record


@dataclass(frozen=True)
class BagStatus:
    """What a launcher can say of a bag after its run: readable at all, closed (indexed, with a
    footer), and the whole steps it holds."""

    path: Path
    readable: bool
    closed: bool
    steps: int

    def describe(self) -> str:
        if not self.readable:
            return f"the bag {self.path} holds no readable step"
        if self.closed:
            return f"the bag {self.path} was closed with {self.steps} steps"
        return (
            f"the bag {self.path} was not closed (no index): it reads up to its last complete "
            f"chunk, {self.steps} steps; `predictive-drive repair {self.path}` rebuilds its index"
        )


def bag_status(bag: str | Path) -> BagStatus:
    """Read a bag back to say what state it is in (never raises for a bad bag)."""
    try:
        trace, info = read_bag(bag)
    except (BagError, OSError):
        return BagStatus(Path(bag), False, False, 0)
    return BagStatus(Path(bag), True, info.complete, trace.steps)


@dataclass
class BagInfo:
    path: Path
    info: dict[str, str]
    counts: dict[str, int]
    complete: bool  #: False if the file had to be read as a truncated stream
    #: rosbag2's custom_data, written when the bag closed (``strategies``: the spans each
    #: strategy was in force, JSON; ``outcome``: the run's final diagnostics); {} if it did not
    custom: dict[str, str] = dataclasses.field(default_factory=dict)
    #: the accepted parameter changes recorded on /parameter_events, with their log times (ns)
    events: tuple[tuple[int, ParameterEvent], ...] = ()


def read_bag(bag: str | Path) -> tuple[Trace, BagInfo]:
    """Decode the per-step topics of a recording into a :class:`Trace` (complete steps only)."""
    path = mcap_file(bag)
    msgs, meta, complete = read_records(path)
    if META_NAME not in meta:
        raise not_a_recording(path, meta, len(msgs))
    info = meta[META_NAME]
    by_name = {TOPICS[key].name: rec for rec, key in RECORD_TOPICS.items()}
    rows: dict[str, dict[int, tuple[float, ...]]] = {rec: {} for rec in RECORDS}
    counts: dict[str, int] = {}
    events: list[tuple[int, ParameterEvent]] = []
    for channel, message in msgs:
        counts[channel.topic] = counts.get(channel.topic, 0) + 1
        rec = by_name.get(channel.topic)
        if rec is None:
            if channel.topic == TOPICS["parameter_events"].name:
                events.append((message.log_time, decode_parameter_event(message.data)))
            continue
        values = CODECS[RECORD_TOPICS[rec]].decode(message.data)
        rows[rec][int(values[K])] = values
    ts = float(info["ts"])
    builder = TraceBuilder(ts, tuple(json.loads(info["strategy_names"])))
    # keep the longest prefix of whole steps: states and references 0..n, commands 0..n-1
    n = 0
    while (
        n in rows["command"]
        and n + 1 in rows["state"]
        and n + 1 in rows["reference"]
        and n in rows["state"]
        and n in rows["reference"]
    ):
        n += 1
    if n == 0:
        raise BagError(f"{path}: the recording holds no complete step")
    for k in range(n + 1):
        builder.add("state", rows["state"][k])
        builder.add("reference", rows["reference"][k])
    for k in range(n):
        builder.add("command", rows["command"][k])
    custom = _custom_data(meta.get("rosbag2", {}))
    events.sort(key=lambda e: e[0])
    return builder.build(), BagInfo(path, info, counts, complete, custom, tuple(events))


def _custom_data(rosbag2: dict[str, str]) -> dict[str, str]:
    """custom_data of the rosbag2 metadata record ({} for a bag that never closed)."""
    try:
        serialized = yaml.safe_load(rosbag2.get("serialized_metadata", "")) or {}
    except yaml.YAMLError:
        return {}
    custom = serialized.get("custom_data") if isinstance(serialized, dict) else None
    return {str(k): str(v) for k, v in custom.items()} if isinstance(custom, dict) else {}
