"""What a run records, shared by the in-process engine and the metrics_logger node.

Per step: state, reference and command, and the plant's losses where it books them; every
:data:`~.interface.CLOCK_PERIOD` of simulated time
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
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from .bag import BagWriter, Held
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
    labelled,
    stamp_ns,
    tool_stamp_ns,
)
from .config import load_scenario_text, section_parameters
from .core.commands import COMMAND_CONTRACT
from .core.control import strategy_names
from .core.metrics import LiveMetrics
from .core.scenario import Scenario
from .core.signals import (
    COMMAND_INDEX,
    EXTERNAL,
    STATE_INDEX,
    span_key,
    span_name,
    span_parts,
    strategy_name,
)
from .core.timebase import every_steps
from .errors import BagError
from .interface import (
    CLOCK_PERIOD,
    LOSSES_TOPIC,
    RECORD_TOPICS,
    RECORDING_WINDOW,
    TOOL_TOPICS,
    TOPICS,
    node_name,
)
from .mcapio import MessageGroup

__all__ = [
    "DIAGNOSTICS_NAME",
    "OwnNode",
    "RunRecorder",
    "StrategySpan",
    "bag_info",
    "default_bag_dir",
    "diagnostics_message",
    "own_nodes",
    "run_label",
    "scenario_of",
    "spans_from_json",
    "command_span_keys",
    "strategy_spans",
    "tool_every",
    "tool_messages",
]

DIAGNOSTICS_NAME = "predictive_drive: drive"
K = STATE_INDEX.k  #: the step: the first field of every per-step record
T = STATE_INDEX.t  #: simulated time: the second field of every per-step record


@dataclass(frozen=True)
class OwnNode:
    """A node of the user's own in a run: its name, the command line the launcher started it
    with (None: started by hand), and the parameters its section of the scenario gave it."""

    name: str
    command: str | None
    parameters: dict[str, Any]

    @property
    def started(self) -> str:
        return "started by hand" if self.command is None else f"started as `{self.command}`"


def bag_info(
    sc: Scenario,
    engine: str,
    commands: Mapping[str, str | None] | None = None,
    *,
    label: str | None = None,
) -> dict[str, Any]:
    """What a bag stores about its run (the ``predictive_drive`` metadata record). ``commands``:
    the nodes of the user's own and the command lines they were started with (None: by hand),
    stored with the parameters their sections give them (``external``, JSON: read back by
    :func:`own_nodes`). ``label``: the run's label where it is not in the strategy's name (a
    speed loop of one's own with our torque controller; see :func:`run_label`)."""
    own = {
        name: {"command": command, "parameters": section_parameters(sc.text, name)}
        for name, command in (commands or {}).items()
    }
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
        # the inverter's devices (plant.losses.device): their file, as the run read it
        **({"device_json": sc.device.text} if sc.device is not None else {}),
        **({"external": json.dumps(own)} if own else {}),
        **({"label": label} if label else {}),
        **({"draw": sc.draw} if sc.draw else {}),  # a drawn drive (sweep --draw, robustness)
    }


def run_label(info: Mapping[str, str]) -> str:
    """How tables and figures name a recorded run: its scenario and strategy (``external:NAME``
    for a torque controller of one's own), and the run's label where a speed loop of one's own
    carried it (``im_short mptc [speed_pi:NAME]``)."""
    text = f"{info['scenario']} {info['strategy']}"
    return text + (f" [speed_pi:{info['label']}]" if info.get("label") else "")


def own_nodes(info: Mapping[str, str]) -> list[OwnNode]:
    """The nodes of the user's own a recording names (see :func:`bag_info`), in start order."""
    return [
        OwnNode(name, d.get("command"), dict(d.get("parameters", {})))
        for name, d in json.loads(info.get("external", "{}")).items()
    ]


def scenario_of(info: Mapping[str, str], where: Path) -> Scenario:
    """The scenario a recording was made with, from its ``predictive_drive`` metadata record
    (the sections of the user's own nodes theirs, as when it ran)."""
    own = [n.name for n in own_nodes(info)]
    where_ = f"{where} (stored scenario)"
    first = info["strategy"] if "torque_controller" not in own else None
    sc = load_scenario_text(
        info["scenario_yaml"], where_, legacy=True, own=own, strategy=first,
        device_text=info.get("device_json"),
    )  # fmt: skip
    return sc.with_strategy(info["strategy"]).with_duration(float(info["duration"]))


def default_bag_dir(sc: Scenario, root: str | Path = "bags") -> Path:
    """``bags/<scenario>_<strategy>_<date-time>_<pid>``; a ':' (``external:NAME``) as '-': a
    folder name with one breaks zip, SMB and Windows."""
    stamp = time.strftime("%Y%m%d-%H%M%S")
    return Path(root) / f"{sc.name}_{sc.strategy.replace(':', '-')}_{stamp}_{os.getpid()}"


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
    snap: dict[str, float],
    level: int,
    message: str,
    strategy_names: tuple[str, ...],
    external: str = EXTERNAL,
) -> tuple[int, bytes]:
    """The /diagnostics message of a snapshot: counts as integers, figures as exact floats,
    the strategy by name."""
    name = strategy_name(strategy_names, snap["strategy"], external) if "strategy" in snap else ""
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
    keys: Iterable[float], names: tuple[str, ...], k0: int = 0, external: str = EXTERNAL
) -> list[StrategySpan]:
    """The spans of a run's per-step span keys (:func:`command_span_keys`: the command's
    ``strategy`` and ``horizon``; NaN: a controller of one's own, named ``external``)."""
    spans, k = [], k0
    for name, steps in itertools.groupby(keys, key=lambda i: span_name(names, i, external)):
        n = sum(1 for _ in steps)
        spans.append(StrategySpan(name, k, k + n - 1))
        k += n
    return spans


def command_span_keys(commands: np.ndarray) -> np.ndarray:
    """The span key (:func:`~.core.signals.span_key`) of each row of commands."""
    return np.asarray(
        span_key(commands[:, COMMAND_INDEX.strategy], commands[:, COMMAND_INDEX.horizon])
    )


def _row_key(row: Any) -> float:
    """The span key of one command row."""
    return float(span_key(float(row[COMMAND_INDEX.strategy]), float(row[COMMAND_INDEX.horizon])))


#: the span key before the first span: no command's (theirs are >= 0, or NaN)
_NO_SPAN = -1.0


def _decode_or_nan(codec: Any, data: bytes) -> tuple[float, ...]:
    """A record's values by field name, or all NaN where the message is no labelled array of
    a step and a time (see :meth:`RunRecorder._screen`)."""
    try:
        values: tuple[float, ...] = codec.decode(data)
        return values
    except BagError:
        return (math.nan,) * len(codec.fields)


def _changed(names: tuple[str, ...], before: float, key: float) -> list[tuple[str, Any]]:
    """The parameter change that took a run from span key ``before`` to ``key``: the
    strategy's name, or the horizon alone when the strategy stayed."""
    (s0, h0), (s1, h1) = span_parts(before), span_parts(key)
    if s0 == s1 and h0 != h1:
        return [("horizon", int(h1))]
    return [("strategy", strategy_name(names, s1))]


def _same_strategy(a: float, b: float) -> bool:
    """Two commands' strategy indices name the same strategy (NaN: the user's own, both)."""
    return a == b or (math.isnan(a) and math.isnan(b))


#: the topics a node's recorder receives each in order but not in order with one another: the
#: per-step records and the plant's tool topics
_STREAMS = ("state", "reference", "command", *TOOL_TOPICS)
#: a step's records in the order a node's recorder receives them (indices into state, reference,
#: command): reference k was made from state k-1, command k from state k
_ARRIVAL = (1, 0, 2)
#: steps after which a record still waiting for its step's others is let go (a node's recorder)
_UNPAIRED_HORIZON = 10 * RECORDING_WINDOW
#: record name by topic key (the plant's losses a record of their own where a run has them)
_RECORD_OF = {key: record for record, key in RECORD_TOPICS.items()} | {LOSSES_TOPIC: "losses"}


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
        external: str = EXTERNAL,
        losses: bool = False,
    ) -> None:
        """``record_tools``: the in-process engine, where the recorder also writes what the
        plant and the controller node would publish: /clock, /drive/joint_states, and a
        parameter event when the strategy changes. ``live(topic_key, t_ns, data)``: a second
        sink that sees every message as it comes (the live view). ``external``: the name of a
        controller of one's own (its commands carry no strategy index). ``losses``: the plant
        books its losses: /drive/losses comes every step (a step is whole with them)."""
        self.writer = writer
        self.external = external
        self.live = LiveMetrics(ts=ts, torque_limit=torque_limit)
        self.strategy_names = strategy_names
        self.ts = ts
        self.steps = steps
        self._every = tool_every(ts)
        self._tools = self._events = record_tools
        self._publish = publish
        self._live = live
        self.last_t = 0.0
        self._losses = losses
        #: the per-step records, by name → topic key (the losses where the run has them)
        self._records = {**RECORD_TOPICS, **({"losses": LOSSES_TOPIC} if losses else {})}
        streams = (*_STREAMS, *((LOSSES_TOPIC,) if losses else ()))
        #: the last log time seen on each topic the recorder waits on (each comes in order);
        #: none in-process, whose records come in time order
        self._seen = {} if record_tools else dict.fromkeys(streams, -1)
        self._through_ns = -1  #: see _released
        #: node path: records taken whose step's others have not come yet, in order, and where
        #: each came in the batch that brought it (-1: a batch before)
        self._unpaired = {
            r: (np.empty((0, len(CODECS[key].fields))), np.empty(0, dtype=np.int64))
            for r, key in self._records.items()
        }
        #: node path: the last step taken of each record
        self.last_k = dict.fromkeys(self._records, -1)
        #: in-process: the last state written
        self._state_written = -1
        #: node path: the step of each record's last message taken (see _screen)
        self._last_taken = dict.fromkeys(self._records, -1.0)
        #: node path: messages left out of the bag, by topic key, and what the first one was
        self.left_out: dict[str, int] = {}
        self.left_out_first = ""
        self._warned = ""
        self._finished = False
        self._spans: list[StrategySpan] = []  #: the last one's end is ``_through``
        self._index = _NO_SPAN  #: the strategy index of the last span
        self._through = -1
        keys = [RECORD_TOPICS[r] for r in ("state", "reference", "command")]
        self._sizes = tuple(CODECS[key].size for key in keys)
        self._widths = tuple(len(CODECS[key].fields) for key in keys)
        #: a step's records written as one group: in a node, the messages as received, in the
        #: order they come in (reference k comes before state k: the speed PI made it from state
        #: k-1), the plant's tool messages and losses after the state (see flush); in-process
        #: without a live view, state, losses, tool messages, reference, command, the packed
        #: rows after each record's constant prefix (see record_rows); with a live view,
        #: message by message
        self._group: MessageGroup | None = None
        if not record_tools:
            self._group = writer.group(
                [(keys[p], b"", self._sizes[p]) for p in _ARRIVAL], extras_after=1
            )
        elif live is None:
            inprocess = (keys[0], LOSSES_TOPIC, *keys[1:]) if losses else keys
            self._group = writer.group(
                [(key, CODECS[key].prefix, 8 * len(CODECS[key].fields)) for key in inprocess],
                extras_after=1 if losses else 0,
            )
        self._tool_channels = {key: writer.channel(key) for key in TOOL_TOPICS}
        self._tool_channel_ids = np.array(list(self._tool_channels.values()))
        self._arrival_channels = [writer.channel(keys[p]) for p in _ARRIVAL]
        #: node path: the channel of each topic a node takes
        self._channel_of = {key: writer.channel(key) for key in (*streams, "parameter_events")}
        self._streams = [(key, self._channel_of[key]) for key in streams]
        self._record_channel_ids = np.array([writer.channel(k) for k in self._records.values()])
        #: node path: what may come between a step's state and its command, written with the
        #: step's block (see flush): the plant's tool messages, and its losses
        self._between_ids = np.array(
            [*self._tool_channel_ids, *((writer.channel(LOSSES_TOPIC),) if losses else ())]
        )
        self._prefix_state = CODECS[RECORD_TOPICS["state"]].prefix
        self._prefix_reference = CODECS[RECORD_TOPICS["reference"]].prefix
        self._prefix_command = CODECS[RECORD_TOPICS["command"]].prefix
        self._prefix_losses = CODECS[LOSSES_TOPIC].prefix
        self._losses_size = 8 * len(CODECS[LOSSES_TOPIC].fields)

    def record_rows(
        self, states: bytes, references: bytes, commands: bytes, losses: bytes = b""
    ) -> None:
        """In-process path (a :data:`~.core.runner.Sink`): the rows of consecutive steps, packed
        as the trace packs them; each step's state (with the plant's losses and tool
        messages), reference and command are written in that order, as the graph's recorder
        writes them, and the run's final state and reference (no command) close it. The steps
        of one strategy go out as one block, their running metrics summed at once; a step that
        starts a span, and every step when a live view watches too, message by message."""
        s, r, c = (
            np.frombuffer(rows, dtype="<f8").reshape(-1, width)
            for rows, width in zip((states, references, commands), self._widths)
        )
        steps = min(len(s), len(r))  # a run cut short may end between a step's records
        if self._losses:
            steps = min(steps, len(losses) // self._losses_size)
        commanded = min(steps, len(c))
        # each record's rows, in the order a step writes them (the group's parts)
        views = [memoryview(rows) for rows in (states, references, commands)]
        sizes = [8 * width for width in self._widths]
        if self._losses:
            views.insert(1, memoryview(losses))
            sizes.insert(1, self._losses_size)
        strategy = command_span_keys(c)
        i = 0
        while i < commanded:
            if self._group is None or not _same_strategy(float(strategy[i]), self._index):
                self._write_step(
                    s[i], r[i], c[i], *(v[i * n : (i + 1) * n] for v, n in zip(views, sizes))
                )
                i += 1
                continue
            # the steps of this span, up to the end of a diagnostics period
            rest = strategy[i:commanded]
            same = np.isnan(rest) if math.isnan(self._index) else rest == self._index
            j = i + (int(np.argmin(same)) if not same.all() else len(rest))
            j = min(j, i + self.live.every - self.live.steps % self.live.every)
            self._write_plain_steps(
                s[i:j], r[i:j], c[i:j], *(v[i * n : j * n] for v, n in zip(views, sizes))
            )
            i = j
        if steps > commanded:  # the final state and reference (and losses)
            i = commanded
            last: list[Any] = [v[i * n : (i + 1) * n] for v, n in zip(views, sizes)]
            last[-1] = b""  # no command
            self._write_step(s[i], r[i], None, *last)

    def _write_plain_steps(
        self, s: np.ndarray, r: np.ndarray, c: np.ndarray, *payloads: Any
    ) -> None:
        """Consecutive steps of one span: their records in one block (with the losses and the
        tool messages after the states they come with), the running metrics of them all at
        once. ``payloads``: each record's rows, in the group's order."""
        ns = [np.rint(x[:, T] * 1e9).astype(np.int64) for x in (s, r, c)]
        if self._losses:
            ns.insert(1, ns[0])  # a step's losses at its state's time
        every = self._every
        extras = []
        for j in np.flatnonzero(s[:, K] % every == 0).tolist():
            tools = tool_messages(s[j].tolist(), every)
            extras.append((j, [(self._tool_channels[key], t, data) for key, t, data in tools]))
        try:
            self._group.add_steps(ns, payloads, extras)  # type: ignore[union-attr]
        except OSError as e:
            raise self.writer.write_failed(e) from None
        t = float(max(s[-1, T], r[-1, T], c[-1, T]))
        if t > self.last_t:
            self.last_t = t
        self._through = int(c[-1, K])  # the span goes on
        self._state_written = int(s[-1, K])
        snap = self.live.add_steps(s, r, c)
        if snap is not None:
            self._diagnose(snap)

    def _write_step(self, s: np.ndarray, r: np.ndarray, c: np.ndarray | None, *rows: Any) -> None:
        """One step, messages and running metrics (a new span, the last step, a live view);
        ``rows``: the step's records packed, in the group's order (state, losses where the run
        has them, reference, command)."""
        sb, *rest = rows
        lb = rest.pop(0) if self._losses else None
        rb, cb = rest
        state, ref = tuple(s.tolist()), tuple(r.tolist())
        self._state_written = int(state[K])
        write = self._hold
        write("state", stamp_ns(state[T]), self._prefix_state + bytes(sb))
        if lb is not None:
            write(LOSSES_TOPIC, stamp_ns(state[T]), self._prefix_losses + bytes(lb))
        if self._tools and not int(state[K]) % self._every:
            for tkey, tns, data in tool_messages(state, self._every):
                write(tkey, tns, data)
        write("reference", stamp_ns(ref[T]), self._prefix_reference + bytes(rb))
        t = max(state[T], ref[T])
        if c is None:
            if t > self.last_t:
                self.last_t = t
            return
        cmd = tuple(c.tolist())
        write("command", stamp_ns(cmd[T]), self._prefix_command + bytes(cb))
        t = max(t, cmd[T])
        if t > self.last_t:
            self.last_t = t
        k = int(cmd[K])
        index = _row_key(cmd)
        if _same_strategy(index, self._index) and k == self._through + 1:
            self._through = k
        else:
            self._span(k, index)
        snap = self.live.add_step(state, ref, cmd)
        if snap is not None:
            self._diagnose(snap)

    def take(self, taken: list[tuple[str, bytes]]) -> None:
        """Node path: messages as the node took them, in the order they came, by topic key: the
        per-step records (written as received, decoded for the running metrics), the plant's
        tool messages, and accepted parameter changes (see :meth:`record_event`). Each is held
        for its place in log-time order (written by :meth:`flush`). A 20 kHz drive's ~60,000
        messages a simulated second pass here: the records of a batch are decoded and their
        steps' running metrics summed at once (:meth:`_take_batch`); with a live view, which
        sees every message as it comes, message by message (the same bag)."""
        taken, rows = self._screen(taken)
        if self._live is None:
            self._take_batch(taken, rows)
        else:
            self._take_each(taken)

    def _screen(
        self, taken: list[tuple[str, bytes]]
    ) -> tuple[list[tuple[str, bytes]], dict[str, np.ndarray]]:
        """The messages of a batch the bag takes, and each record's rows among them. A per-step
        record is taken when it decodes as a labelled array (by field name; NaN for what it
        lacks) and carries a whole step later than the last one taken of its topic, at a finite
        time: what a node of the graph publishes, each topic in step order. Anything else (a
        command of the wrong size, with no layout, for a step taken already: a controller of
        one's own at fault) is left out and counted in :attr:`left_out`; the plant refuses it
        and names it, and every valid step is kept (the pairing by step relies on the order)."""
        rows: dict[str, np.ndarray] = {}
        bad: set[int] = set()
        for record, key in self._records.items():
            where = [i for i, (k, _) in enumerate(taken) if k == key]
            if not where:
                continue
            codec = CODECS[key]
            payloads = [taken[i][1] for i in where]
            try:
                values = codec.decode_rows(payloads)
            except BagError:  # one of them is not of a labelled layout: each on its own
                values = np.array([_decode_or_nan(codec, data) for data in payloads])
            last = self._last_taken[record]
            ks = values[:, K]
            steps = np.floor(ks) == ks  # NaN: no step
            rising = ks[0] > last and (len(ks) == 1 or bool((np.diff(ks) > 0).all()))
            if rising and steps.all() and np.isfinite(values[:, T]).all():  # as the graph sends
                self._last_taken[record] = float(ks[-1])
            else:
                keep = []
                for j, row in enumerate(values):
                    if row[K] > last and row[K] == math.floor(row[K]) and math.isfinite(row[T]):
                        keep.append(j)
                        last = float(row[K])
                    else:
                        bad.add(where[j])
                        self._left_out(key, row, last, taken[where[j]][1])
                values = values[keep]
                self._last_taken[record] = last
            rows[record] = values
        if bad:
            taken = [m for i, m in enumerate(taken) if i not in bad]
        return taken, rows

    def _left_out(self, key: str, row: np.ndarray, last: float, data: bytes) -> None:
        """A message the bag does not take (see :meth:`_screen`): counted, the first said."""
        self.left_out[key] = self.left_out.get(key, 0) + 1
        if self.left_out_first:
            return
        topic = TOPICS[key].name
        if math.isnan(row[K]):
            try:
                labelled(data)
                why = "it carries no step k and time t"
            except BagError as e:
                why = str(e)
        elif not row[K] > last:
            why = f"it is for step {row[K]:g}, after step {last:g} was taken"
        elif row[K] != math.floor(row[K]):
            why = f"its step k = {row[K]!r} is no whole number"
        else:
            why = f"its time t = {row[T]!r} is not finite"
        self.left_out_first = f"a {topic} message: {why}"

    def _take_each(self, taken: list[tuple[str, bytes]]) -> None:
        """:meth:`take`, message by message."""
        hold = self.writer.hold
        offer = self._live
        live = self.live.add
        seen = self._seen
        last_k = self.last_k
        for key, data in taken:
            record = _RECORD_OF.get(key)
            if record is not None and record in self._records:
                row = _decode_or_nan(CODECS[key], data)  # screened: it decodes
                t = row[T]
                ns = round(t * 1e9)  # stamp_ns
                hold(key, ns, data)
                if offer is not None:
                    offer(key, ns, data)
                if t > self.last_t:
                    self.last_t = t
                if record == "command":
                    self._span(int(row[K]), _row_key(row))
                snap = live(record, row) if record != "losses" else None
                if snap is not None:
                    self._diagnose(snap)
                seen[key] = ns  # each topic comes in order: see _released
                last_k[record] = int(row[K])
            elif key == "parameter_events":
                self.record_event(data)
            else:
                ns = tool_stamp_ns(data)
                hold(key, ns, data)
                if offer is not None:
                    offer(key, ns, data)
                seen[key] = ns

    def _take_batch(self, taken: list[tuple[str, bytes]], decoded: dict[str, np.ndarray]) -> None:
        """:meth:`take` of a batch: each topic's records decoded at once (one numpy call when
        all have this version's layout), paired with the records of their step by k, the
        completed steps' running metrics summed at once; the messages held as blocks, a
        parameter change at the last step's time before it and a period's diagnostics right
        after the message that completed the period — where :meth:`_take_each` holds them."""
        n = len(taken)
        if n == 0:
            return
        keys, datas = zip(*taken)
        channels = np.fromiter(map(self._channel_of.__getitem__, keys), dtype=np.int64, count=n)
        ns = np.zeros(n, dtype=np.int64)  #: each message's log time (a parameter change: later)
        t_at = np.full(n, -math.inf)  #: each record's time
        for record, key in self._records.items():
            where = np.flatnonzero(channels == self._channel_of[key])
            if not len(where):
                continue
            rows = decoded[record]
            ns[where] = np.rint(rows[:, T] * 1e9)  # stamp_ns
            t_at[where] = rows[:, T]
            self.last_k[record] = int(rows[-1, K])
            if record == "command":
                self._spans_of(rows)
            self._unpaired[record] = (
                np.concatenate([self._unpaired[record][0], rows]),
                np.concatenate([np.full(len(self._unpaired[record][1]), -1), where]),
            )
        # where the batch is cut: after a message that completed a diagnostics period (its
        # snapshot), at a parameter change (None)
        cuts: list[tuple[int, dict[str, float] | None]] = []
        for i in np.flatnonzero(~np.isin(channels, self._record_channel_ids)).tolist():
            if keys[i] == "parameter_events":
                cuts.append((i, None))
            else:  # a tool message
                ns[i] = tool_stamp_ns(datas[i])
        cuts += self._pair_steps()
        cuts.sort(key=lambda cut: cut[0])  # stable: a position's snapshots in their order
        held = seen = 0  #: what is held, and seen (see _released), of the batch so far
        for i, snap in cuts:
            if snap is None:  # record_event, at the last step's time before it
                self._hold_part(held, i, ns, channels, datas)
                self._see(seen, i, ns, channels)
                last_t = max(self.last_t, float(t_at[:i].max(initial=-math.inf)))
                self.writer.hold("parameter_events", max(stamp_ns(last_t), self._floor()), datas[i])
                held = seen = i + 1
            else:  # held and seen: through the message before it
                self._hold_part(held, i + 1, ns, channels, datas)
                self._see(seen, i, ns, channels)
                self._diagnose(snap)
                held, seen = i + 1, i
        self._hold_part(held, n, ns, channels, datas)
        self._see(seen, n, ns, channels)
        self.last_t = max(self.last_t, float(t_at.max()))

    def _hold_part(
        self, start: int, end: int, ns: np.ndarray, channels: np.ndarray, datas: tuple[bytes, ...]
    ) -> None:
        """Messages [start, end) of a batch, held as a block."""
        if end > start:
            self.writer.hold_block(Held(ns[start:end], channels[start:end], list(datas[start:end])))

    def _see(self, start: int, end: int, ns: np.ndarray, channels: np.ndarray) -> None:
        """The last log time of each topic among messages [start, end) of a batch (see
        _released)."""
        part = channels[start:end]
        for key, channel in self._streams:
            hits = np.flatnonzero(part == channel)
            if len(hits):
                self._seen[key] = int(ns[start + hits[-1]])

    def _pair_steps(self) -> list[tuple[int, dict[str, float]]]:
        """The steps whose state, reference and command (and losses, where the run has them)
        have all come (paired by k, in the order of k): their running metrics, a diagnostics
        period at a time. Returns each period's snapshot with where its last step was
        completed in the batch (-1: before it). A record whose step's others have not come
        within _UNPAIRED_HORIZON steps (one went missing) is let go."""
        records = [self._unpaired[x] for x in self._records]  # state, reference, command, ...
        if not all(len(rows) for rows, _ in records):
            return []
        ks = [rows[:, K] for rows, _ in records]
        # each topic's steps in a row from the same step on (as the graph delivers them): the
        # first ones of each are the steps complete
        in_row = all(k[0] == ks[0][0] for k in ks) and all(
            len(k) == 1 or bool((np.diff(k) == 1).all()) for k in ks
        )
        if in_row:
            common = ks[0][: min(len(k) for k in ks)]
            picks = [np.arange(len(common))] * len(ks)
        else:
            common = ks[0]
            for k in ks[1:]:
                common = np.intersect1d(common, k)
            picks = [np.searchsorted(k, common) for k in ks]
        snaps: list[tuple[int, dict[str, float]]] = []
        if len(common):
            paired = [rows[p] for (rows, _), p in zip(records[:3], picks)]
            at = np.maximum.reduce([came[p] for (_, came), p in zip(records, picks)])
            i, m = 0, len(common)
            while i < m:
                j = min(m, i + self.live.every - self.live.steps % self.live.every)
                snap = self.live.add_steps(*(x[i:j] for x in paired))
                if snap is not None:
                    snaps.append((int(at[j - 1]), snap))
                i = j
        for x, (rows, came) in list(self._unpaired.items()):
            if in_row:
                keep = rows[:, K] > common[-1]
            else:
                keep = ~np.isin(rows[:, K], common)
            if len(common):  # a record this far behind the steps paired will find no partner
                keep &= rows[:, K] > common[-1] - _UNPAIRED_HORIZON
            self._unpaired[x] = (rows[keep], came[keep])
        snaps.sort(key=lambda p: p[0])
        while snaps and snaps[0][0] < 0:  # completed by records of the batches before
            self._diagnose(snaps.pop(0)[1])
        return snaps

    def _spans_of(self, commands: np.ndarray) -> None:
        """The strategy spans of consecutive commands (:meth:`_span` of each, at once when
        they go on the span in force)."""
        index = command_span_keys(commands)
        same = np.isnan(index) if math.isnan(self._index) else index == self._index
        k = commands[:, K]
        if same.all() and k[0] == self._through + 1 and np.all(np.diff(k) == 1):
            self._through = int(k[-1])
            return
        for k_i, index_i in zip(k.tolist(), index.tolist()):
            self._span(int(k_i), index_i)

    def record_event(self, data: bytes) -> None:
        """An accepted parameter change (rcl_interfaces/ParameterEvent), logged at the time it
        arrives on the simulated clock (the last step seen), as rosbag2 logs receive time."""
        self._hold("parameter_events", max(stamp_ns(self.last_t), self._floor()), data)

    @property
    def _released(self) -> int:
        """Node path: the log time every topic the recorder waits on has passed (each topic
        comes in order, so nothing earlier is still to come); -1 in-process."""
        if self._seen:
            self._through_ns = max(self._through_ns, min(self._seen.values()))
        return self._through_ns

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

    def flush(self) -> None:
        """Node path: write what every topic has passed (the node calls this after each batch of
        messages it takes; what comes later cannot be earlier): the steps whose reference,
        state, tool messages and command follow one another as one block, the rest one by one."""
        ready = self.writer.ready(self._released)
        times, channels, data = ready
        n = len(times)
        if n == 0:
            return
        sizes = np.fromiter(map(len, data), dtype=np.int64, count=n)
        ref, state, command = (
            (channels == self._arrival_channels[p]) & (sizes == self._sizes[q])
            for p, q in enumerate(_ARRIVAL)
        )
        tool = np.isin(channels, self._between_ids)
        # the first message at or after each place that is not a tool message (n: none)
        after = np.minimum.accumulate(np.where(tool, n, np.arange(n))[::-1])[::-1]
        after = np.append(after, [n, n])
        # a step: a reference, its state, tool messages, then its command
        cmd = after[2:n]  # where each candidate's command would be
        step = ref[: n - 2] & state[1 : n - 1] & (cmd < n)
        step[step] &= command[cmd[step]]
        starts = np.flatnonzero(step)
        ends = cmd[starts]  #: each step's command
        inside = np.zeros(n + 1, dtype=np.int64)
        inside[starts] += 1
        inside[ends + 1] -= 1
        alone = np.flatnonzero(np.cumsum(inside[:n]) == 0)  #: written one by one
        try:
            done = 0
            for i, before in zip(alone.tolist(), np.searchsorted(starts, alone).tolist()):
                self._write_block(ready, starts[done:before], ends[done:before])
                done = before
                self.writer.write_on(int(channels[i]), int(times[i]), data[i])
            self._write_block(ready, starts[done:], ends[done:])
        except OSError as e:
            raise self.writer.write_failed(e) from None

    def _write_block(self, ready: Held, starts: np.ndarray, ends: np.ndarray) -> None:
        """Node path: steps of ``ready`` (its messages from each start to the command at its
        end) as one block."""
        if not len(starts):
            return
        times, channels, data = ready
        parts = (starts, starts + 1, ends)  # reference, state, command: _ARRIVAL
        extras = [
            (j, [(int(channels[m]), int(times[m]), data[m]) for m in range(s + 2, e)])
            for j, (s, e) in enumerate(zip(starts.tolist(), ends.tolist()))
            if e > s + 2
        ]
        self._group.add_steps(  # type: ignore[union-attr]
            [times[at] for at in parts],
            [b"".join([data[i] for i in at.tolist()]) for at in parts],
            extras,
        )

    def _span(self, k: int, index: float) -> None:
        """Command k ran the strategy (and horizon) of span key ``index``: the span goes on, or
        a new one starts (in-process with the parameter event the controller node would
        publish: the strategy's, or the horizon's when only the horizon changed)."""
        if _same_strategy(index, self._index) and k == self._through + 1:
            self._through = k
            return
        self._seal()
        before = self._index
        self._index, self._through = index, k
        name = span_name(self.strategy_names, index, self.external)
        self._spans.append(StrategySpan(name, k, k))
        if k > 0 and self._events:
            t = k * self.ts
            changed = _changed(self.strategy_names, before, index)
            data = encode_parameter_event(t, node_name("torque_controller"), changed)
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
        # the steps as `report` counts them: whole, their next state and reference in too (a
        # command the plant refused, the last one of a stopped run, had its three records but
        # never acted)
        after = min(
            max(self.last_k[r], self._state_written) for r in self._records if r != "command"
        )
        done = min(int(total["steps"]), max(after, 0))
        total["steps"] = float(done)
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
        ns, data = diagnostics_message(total, level, message, self.strategy_names, self.external)
        self._hold("diagnostics", max(ns, self._floor()), data)
        if self._publish is not None:
            self._publish("diagnostics", data)
        spans = [
            dataclasses.replace(sp, last=min(sp.last, done - 1))
            for sp in self.spans
            if sp.first < done
        ]  # a strategy span of a step never applied is none
        self.writer.custom_data["strategies"] = spans_to_json(spans)
        self.writer.custom_data["outcome"] = f"{LEVEL_NAMES[level]}: {message}"

    def _diagnose(self, snap: dict[str, float] | None) -> None:
        if snap is None:
            return
        level, wrong = self.live.level(snap)
        if wrong and not self._warned:
            self._warned = f"from {snap['t']:.6g} s: {wrong}"
        message = wrong or f"running: {int(snap['steps'])} of {self.steps} steps"
        ns, data = diagnostics_message(snap, level, message, self.strategy_names, self.external)
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
