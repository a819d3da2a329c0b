"""A recording read back: the :class:`~predictive_drive.core.trace.Trace` of its per-step topics
(/drive/losses where the run had them),
its ``predictive_drive`` metadata, the parameter changes it recorded, and what state the file is
in (closed, or cut short by a killed writer)."""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable
from dataclasses import dataclass
from functools import cache, partial
from pathlib import Path

import numpy as np
import yaml

from .bag import META_NAME, load_yaml, mcap_file, not_a_recording
from .codec import (
    CODECS,
    MultiArrayCodec,
    ParameterEvent,
    decode_command,
    decode_multiarray,
    decode_parameter_event,
)
from .core.signals import EXTERNAL, EXTERNAL_PREFIX, STATE_INDEX
from .core.trace import Trace, no_losses
from .errors import BagError
from .interface import LOSSES_TOPIC, RECORD_TOPICS, TOPICS
from .mcapio import McapContents, Messages, read_file
from .recording import OwnNode, own_nodes, scenario_of

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

    @property
    def own_nodes(self) -> list[OwnNode]:
        """The nodes of the user's own the run had: how each was started, its parameters."""
        return own_nodes(self.info)


def read_bag(bag: str | Path) -> tuple[Trace, BagInfo]:
    """Decode the per-step topics of a recording into a :class:`Trace` (complete steps only).

    The file is read chunk by chunk (:func:`~.mcapio.read_file`); each per-step topic's messages
    of this version's layout are decoded in one numpy gather, others one by one by field name."""
    path = mcap_file(bag)
    try:
        contents = read_file(path)
    except ValueError:
        raise not_a_recording(path, {}, 0) from None
    except OSError as e:
        raise BagError(f"{path}: cannot read it: {e.strerror}") from None
    meta = contents.metadata
    if META_NAME not in meta:
        raise not_a_recording(path, meta, contents.messages)
    info = meta[META_NAME]

    @cache
    def u_dc() -> float:
        """The DC link of the run (a command of a controller's own may be a voltage)."""
        return float(scenario_of(info, path).plant.u_dc)

    by_name = {TOPICS[key].name: rec for rec, key in RECORD_TOPICS.items()}
    by_name[TOPICS[LOSSES_TOPIC].name] = "losses"
    codecs = {
        **{rec: CODECS[key] for rec, key in RECORD_TOPICS.items()},
        "losses": CODECS[LOSSES_TOPIC],
    }
    tables: dict[str, np.ndarray] = {}
    counts: dict[str, int] = {}
    events: list[tuple[int, ParameterEvent]] = []
    channels = sorted((m for m in contents.channels.values() if len(m)), key=lambda m: m.order[0])
    states: list[Messages] = []
    for m in channels:
        topic = m.channel.topic
        counts[topic] = counts.get(topic, 0) + len(m)
        rec = by_name.get(topic)
        if rec == "state":
            states.append(m)
        if rec is not None:
            decode = partial(decode_command, u_dc=u_dc) if rec == "command" else None
            tables[rec] = _by_step(_values(contents, m, codecs[rec], decode), tables.get(rec))
        elif topic == TOPICS["parameter_events"].name:
            events += [
                (int(m.log_times[i]), decode_parameter_event(contents.payload(m, i)))
                for i in range(len(m))
            ]
    if "losses" not in tables:
        for m in states:  # a recording of the version that sent the losses in the state
            if _legacy_losses(contents, m):
                tables["losses"] = _by_step(
                    _values(contents, m, codecs["losses"]), tables.get("losses")
                )
    # keep the longest prefix of whole steps: states and references 0..n, commands 0..n-1, and
    # the losses 0..n of a run that booked them (a step is whole with its losses)
    empty = np.empty((0, 1))
    state, reference, command = (tables.get(r, empty) for r in ("state", "reference", "command"))
    every = [state, reference, *(("losses" in tables) * [tables.get("losses", empty)])]
    have = [~np.isnan(t[:, 0]) for t in every]
    done = ~np.isnan(command[:, 0])
    whole = min(*(len(h) - 1 for h in have), len(done))
    ok = done[:whole]
    for h in have:
        ok = ok & h[:whole] & h[1 : whole + 1]
    n = int(np.argmin(ok)) if not ok.all() else max(whole, 0)
    if n == 0:
        raise BagError(f"{path}: the recording holds no complete step")
    names = tuple(json.loads(info["strategy_names"]))
    strategy = info.get("strategy", "")
    trace = Trace(
        float(info["ts"]),
        np.ascontiguousarray(state[: n + 1]),
        np.ascontiguousarray(reference[: n + 1]),
        np.ascontiguousarray(command[:n]),
        names,
        strategy if strategy.startswith(EXTERNAL_PREFIX) else EXTERNAL,
        np.ascontiguousarray(tables["losses"][: n + 1]) if "losses" in tables else no_losses(),
    )
    custom = _custom_data(meta.get("rosbag2", {}))
    events.sort(key=lambda e: e[0])
    return trace, BagInfo(path, info, counts, contents.complete, custom, tuple(events))


def _values(
    contents: McapContents,
    m: Messages,
    codec: MultiArrayCodec,
    decode: Callable[[bytes], tuple[float, ...]] | None = None,
) -> np.ndarray:
    """(n, fields) values of a per-step topic's messages: of this layout in one gather, of
    another (a recording of another version, a controller of one's own) one by one with
    ``decode`` (default: by field name)."""
    width = len(codec.fields)
    if (m.lengths == codec.size).all():
        values = codec.exact_rows(m.payloads(contents.data, codec.size))
        if values is not None:
            return values.reshape(len(m), width)
    one = decode or codec.decode
    rows = [one(contents.payload(m, i)) for i in range(len(m))]
    return np.array(rows, dtype=np.float64).reshape(len(m), width)


def _legacy_losses(contents: McapContents, m: Messages) -> bool:
    """The state messages of a recording made when the state carried the plant's losses
    (``p_dc`` … ``t_rotor``, NaN without them): the losses are read from them, by label."""
    if (m.lengths == CODECS["state"].size).all():
        return False  # this version's state: no losses in it
    labels, _ = decode_multiarray(contents.payload(m, 0))
    if "p_dc" not in labels:
        return False
    last = dict(zip(labels, decode_multiarray(contents.payload(m, len(m) - 1))[1]))
    return bool(np.isfinite(last.get("t_sink", np.nan)) or np.isfinite(last.get("p_dc", np.nan)))


def _by_step(values: np.ndarray, into: np.ndarray | None) -> np.ndarray:
    """Rows placed at their step k (the first field); NaN rows where a step is missing; a later
    message of the same step replaces an earlier one (as a recorder would have kept it)."""
    k = values[:, K]
    good = (k >= 0) & (k == np.floor(k))
    values, ks = values[good], k[good].astype(np.int64)
    size = int(ks.max()) + 1 if len(ks) else 0
    if into is not None:
        size = max(size, len(into))
    out = np.full((size, values.shape[1]), np.nan)
    if into is not None:
        out[: len(into)] = into
    out[ks] = values
    return out


def _custom_data(rosbag2: dict[str, str]) -> dict[str, str]:
    """custom_data of the rosbag2 metadata record ({} for a bag that never closed)."""
    try:
        serialized = load_yaml(rosbag2.get("serialized_metadata", "")) or {}
    except yaml.YAMLError:
        return {}
    custom = serialized.get("custom_data") if isinstance(serialized, dict) else None
    return {str(k): str(v) for k, v in custom.items()} if isinstance(custom, dict) else {}
