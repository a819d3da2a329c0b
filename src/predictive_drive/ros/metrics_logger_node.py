"""The metrics logger node (``ros2 run predictive_drive metrics_logger_node --ros-args
--params-file config/<scenario>.yaml``): records every topic of the run to a bag, publishes
running metrics on /diagnostics, closes the bag cleanly however the run ends."""

from __future__ import annotations

import functools
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..bag import LOGS_DIR, BagWriter
from ..codec import CODECS, decode_parameter_event
from ..config import load_scenario
from ..core.control import strategy_names
from ..core.fields import choice, quantity
from ..errors import BagError, ConfigError
from ..interface import LOSSES_TOPIC, NODES, RECORD_TOPICS, RECORDED_EVERY, TOPICS, node_name
from ..live import LiveView
from ..recording import RunRecorder, bag_info, default_bag_dir, tool_every
from .node_base import FINISH_TIMEOUT, WatchedNode, run_main
from .placement import launcher_pid, stop_reason

__all__ = ["TAKE_BATCH", "MetricsLoggerNode", "main"]

#: messages the logger takes before it writes them (about 500 steps of the drive, half the plant's
#: RECORDING_WINDOW: the recorder's work runs on arrays, and a batch's numpy calls cost about as
#: much as its messages at 384); a watchdog turn (0.1 s at most) writes what is waiting
TAKE_BATCH = 1536


@dataclass(frozen=True)
class RecordingParams:
    """Where and what the logger records, besides its scenario section."""

    bag: str = choice(
        "bag directory to write (default bags/<scenario>_<strategy>_<time>)", default=""
    )
    strategy: str = choice(
        "the controller's starting strategy, for the bag's metadata (default: the scenario's)",
        default="",
    )
    scenario_file: str = choice(
        "scenario file to store in the bag (default config/<scenario>.yaml)", default=""
    )
    engine: str = choice(
        "what runs the graph, for the bag's metadata", ("ros", "composed"), default="ros"
    )
    live_port: int = quantity(
        "port of the live view (Foxglove WebSocket, on 127.0.0.1; 0: none)",
        ge=0,
        le=65535,
        integer=True,
        default=0,
    )
    external: str = choice(
        "the nodes of the user's own, for the bag's metadata: JSON, node name to the command "
        "line the launcher started it with (null: started by hand); their sections are theirs",
        default="",
    )
    label: str = choice(
        "the run's label (run --label) when a speed loop of the user's own runs with our torque "
        "controller, for the bag's metadata ('': none)",
        default="",
    )


class MetricsLoggerNode(WatchedNode):
    """Records raw bytes (no decode on the hot path but the running metrics')."""

    patience = 1.0  #: see WatchedNode.patience

    section = "metrics_logger"

    def __init__(self, **kw: Any) -> None:
        super().__init__("metrics_logger", **kw)
        run, self.params = self.load_params()
        extra = RecordingParams(**self.declare_fields(RecordingParams))
        commands = _commands(extra.external, self._where())
        sc = load_scenario(
            extra.scenario_file or run.scenario,
            strategy=extra.strategy or None,
            duration=run.duration,
            own=list(commands),
        )
        self.n = run.steps
        out = Path(extra.bag) if extra.bag else default_bag_dir(sc)
        self.live = self._live_view(extra.live_port, run.ts, sc) if extra.live_port else None
        try:
            # run by the project's launcher, which holds the directory's claim for the run
            claimed = launcher_pid() != 0
            info = bag_info(sc, extra.engine, commands, label=extra.label or None)
            #: the plant books its losses: /drive/losses is recorded, a step whole with them
            self.losses = sc.plant.losses.on
            self.writer = BagWriter(out, info=info, claimed=claimed, losses=self.losses)
        except BaseException:
            if self.live is not None:
                self.live.close()
            raise
        self.pubs = {key: self.publisher(key) for key in ("diagnostics", "metrics")}
        self.pub_recorded = self.publisher("recorded")
        self._said = -1  #: the last step /drive/recorded announced
        #: stopping: /drive/recorded is no longer announced, so the plant holds within
        #: RECORDING_WINDOW steps and everything it published reaches this node (back-pressure)
        self._draining = False
        self._ts = run.ts
        self._last_message = time.monotonic()
        self.rec = RunRecorder(
            self.writer,
            ts=run.ts,
            steps=run.steps,
            torque_limit=sc.torque_limit,
            strategy_names=strategy_names(sc.family),
            record_tools=False,
            publish=self._publish_tool,
            live=None if self.live is None else self.live.offer,
            external=sc.own_name,
            losses=self.losses,
        )
        ticks = self.n // tool_every(run.ts) + 1
        #: messages taken, by topic; written (and counted in the bag) in batches
        self._counts = {"state": 0, "reference": 0, "command": 0, "clock": 0, "joint_states": 0}
        self._taken: list[tuple[str, bytes]] = []  #: (topic key, data)
        self._need = {
            "state": self.n + 1,
            "reference": self.n + 1,
            "command": self.n,
            "clock": ticks,
            "joint_states": ticks,
        }
        if self.losses:
            self._counts[LOSSES_TOPIC], self._need[LOSSES_TOPIC] = 0, self.n + 1
        self._left = sum(self._need.values())  #: messages still to come
        #: at the last batch written: the messages still to come, and the records taken
        self._noted = (self._left, 0)
        # tool topics first: the plant starts once it sees this node's /drive/state subscription
        self.subs = [
            self.subscription(key, functools.partial(self.on_tool, key))
            for key in ("clock", "joint_states")
        ] + [
            # the losses before the state: the plant starts once it sees the state's
            self.subscription(key, functools.partial(self.on_record, key))
            for key in ((LOSSES_TOPIC,) if self.losses else ()) + ("state", "reference", "command")
        ]
        # rclpy publishes parameter events over DDS, never through a LocalBus
        self._drive_nodes = {node_name(n) for n in NODES}
        self._controller = node_name("torque_controller")
        self.events = self.subscription("parameter_events", self.on_parameter_event, dds=True)
        self.get_logger().info(f"recording to {out}")
        self._closed = False

    def _live_view(self, port: int, ts: float, sc: Any) -> LiveView:
        """The live view, its strategy set through the controller's parameter service."""
        from rclpy.parameter import Parameter
        from rclpy.parameter_client import AsyncParameterClient

        controller = AsyncParameterClient(self, node_name("torque_controller"))

        def set_strategy(name: str) -> None:
            fut = controller.set_parameters([Parameter("strategy", value=name)])
            fut.add_done_callback(lambda f: self._strategy_answer(name, f))

        view = LiveView(
            port=port,
            ts=ts,
            strategy=sc.strategy,
            strategy_names=strategy_names(sc.family),
            set_strategy=set_strategy,
        )
        self.get_logger().info(
            f"live view on {view.url} (Foxglove / Lichtblick: open a Foxglove WebSocket "
            f"connection to it)"
        )
        return view

    def _strategy_answer(self, name: str, fut: Any) -> None:
        result = fut.result().results[0] if fut.result() else None
        if self.live is not None and result is not None and not result.successful:
            self.live.rejected(f"strategy {name}: {result.reason}")

    def _publish_tool(self, key: str, data: bytes) -> None:
        if self.context.ok():  # not while shutting down: the recording matters more
            self.pubs[key].publish(data)

    def stalled_message(self) -> str:
        missing = [r for r, c in self._counts.items() if c < self._need[r]]
        return (
            f"recording stalled: waiting for {', '.join(TOPICS[m].name for m in missing)} "
            f"(state {self._counts['state']}/{self._need['state']})"
        )

    def on_record(self, key: str, data: bytes) -> None:
        """A per-step record: a state, reference or command, or the plant's losses."""
        if not self._started:  # start-up lasts until command 0 is applied: until state 1 comes
            self.progressed(started=key == "state" and CODECS["state"].decode(data)[0] > 0)
        self._take(key, data)

    def _take(self, key: str, data: bytes) -> None:
        """A message to record: taken now, written with the ones before it once
        :data:`TAKE_BATCH` have come (the recorder's work then runs on arrays), or at the next
        watchdog turn, or when the last one has come. The watchdog hears of the progress when
        they are written (see :meth:`_write_taken`)."""
        self._counts[key] += 1
        self._taken.append((key, data))
        self._left -= 1
        if len(self._taken) >= TAKE_BATCH or (self._left <= 0 and self._counts == self._need):
            self._write_taken()

    def _write_taken(self) -> None:
        """Write what was taken, in the order it came; announce on /drive/recorded how far the
        recording goes; close the bag when every message has come."""
        taken, self._taken = self._taken, []
        self._note_progress()
        left_out = dict(self.rec.left_out)
        try:
            self.rec.take(taken)
            self.rec.flush()
        except BagError as e:
            self._cannot_write(e)
            return
        if self.rec.left_out != left_out:
            self._left_out(left_out)
        through = self.last_step
        if not self._draining and (through >= self._said + RECORDED_EVERY or through >= self.n - 1):
            self._said = through
            # the plant runs ahead of this by at most RECORDING_WINDOW steps (back-pressure)
            progress = (float(through), through * self._ts, float(self.writer.message_count))
            self.pub_recorded.publish(CODECS["recorded"].encode(progress))
        self._maybe_done()

    def _left_out(self, before: dict[str, int]) -> None:
        """Messages the recorder left out (see :meth:`RunRecorder._screen`): not counted among
        those the run needs; the first one said in the log."""
        for key, n in self.rec.left_out.items():
            self._counts[key] -= n - before.get(key, 0)
            self._left += n - before.get(key, 0)
        if not before:
            self.get_logger().warning(
                f"left out of the bag: {self.rec.left_out_first} (the plant refuses it; every "
                f"valid step is kept)"
            )

    def _note_progress(self) -> None:
        """Messages came since the last batch: the last one came now (for :meth:`finish`); the
        watchdog's progress (see progressed) if records came among them. Once a batch, not
        once a message: a watchdog turn comes every 0.1 s."""
        records = sum(self._counts[key] for key in (*RECORD_TOPICS.values(), LOSSES_TOPIC)
                      if key in self._counts)  # fmt: skip
        if self._left != self._noted[0]:
            self._last_message = time.monotonic()
            if records != self._noted[1]:
                self.progressed(started=self._started)
            self._noted = (self._left, records)

    def check(self) -> None:
        if self._taken:
            self._write_taken()
        super().check()

    def finish(self, spin: Callable[[float], None], deadline: float) -> None:
        """Take what is still in flight before the bag closes: until every step has come, or
        nothing has for a second. /drive/recorded is not announced any more, so the plant stops
        within RECORDING_WINDOW steps of the last announcement: every state it published comes
        (the peers keep their publishers until it is acknowledged). Bounded by FINISH_TIMEOUT
        whatever stopped the run: the recording is what a stop must not cut short."""
        self._draining = True
        self._write_taken()
        start = time.monotonic()
        until = max(deadline, start + FINISH_TIMEOUT)
        while (
            self._counts != self._need
            and time.monotonic() < until
            and time.monotonic() - max(start, self._last_message) < 1.0
        ):
            spin(0.05)
            self._write_taken()

    @property
    def last_step(self) -> int:
        return min(self.rec.last_k.values())

    def _maybe_done(self) -> None:
        if self._counts == self._need and not self._taken:
            self.close()
            self.finished = True

    def on_tool(self, key: str, data: bytes) -> None:
        self._take(key, data)

    def on_parameter_event(self, data: bytes) -> None:
        """Parameter changes the drive's nodes accept while the drive runs (from its first state
        on: not the declarations and overrides of start-up, which this node may or may not see
        depending on who starts first)."""
        event = decode_parameter_event(data)
        if self.live is not None and event.node == self._controller:
            for name, value in event.changed:
                if name == "strategy":
                    self.live.strategy_changed(str(value))
        if self._counts["state"] == 0 or self._closed:
            return
        if event.node in self._drive_nodes and event.changed:
            # in its place among the messages taken (its log time is the last step's before it)
            self._taken.append(("parameter_events", data))

    def _cannot_write(self, e: BagError) -> None:
        if not self.failure:
            self.fail(f"{self.get_fully_qualified_name()}: {e}")

    def fail(self, message: str) -> None:
        super().fail(message)
        try:
            self._publish_tool("diagnostics", self.rec.error(message))
        except BagError:
            pass  # the bag is what failed: the message goes to the log only

    def close(self) -> None:
        if self._closed:
            return
        if self._taken and not self.writer.failed:
            self._write_taken()  # closes the bag itself when that was the last message
            if self._closed:
                return
        self._closed = True
        if self.live is not None:
            self.live.close()
        try:
            # a run that did not complete ends with why, as this node or its launcher saw it
            why = ""
            if self._counts != self._need:
                why = self.failure or stop_reason(self.writer.directory / LOGS_DIR)
            try:
                self.rec.finish(why)
            finally:
                self.writer.close()
        except BagError as e:
            self.get_logger().error(f"the bag was not closed: {e}")
            return
        self.get_logger().info(
            f"bag closed: {self.writer.directory} ({self.writer.message_count} messages)"
        )


def _commands(text: str, where: str) -> dict[str, str | None]:
    """The ``external`` parameter: node → command line (None: started by hand)."""
    try:
        commands = json.loads(text or "{}")
    except json.JSONDecodeError as e:
        raise ConfigError(f"{where}: external: not JSON ({e})") from None
    if not isinstance(commands, dict) or not all(
        isinstance(c, str) or c is None for c in commands.values()
    ):
        raise ConfigError(f"{where}: external: expected {{node: command or null}}, got {text!r}")
    return commands


def main(args: list[str] | None = None) -> int:
    return run_main(MetricsLoggerNode, args)


if __name__ == "__main__":
    sys.exit(main())
