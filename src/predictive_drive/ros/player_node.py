"""The player: a recording published back onto ROS topics, paced by its log time, as
``ros2 bag play`` does (``predictive-drive replay BAG``).

Each topic goes out with the QoS it was recorded with (the channel's ``offered_qos_profiles``),
its messages as recorded (serialized bytes, never decoded), in log-time order, none dropped: when
publishing cannot keep the pace (the 20 kHz topics at rate 1 outrun rclpy on a small machine), the
player publishes as fast as it can, says that it falls behind and by how much, and reports its
achieved rate and final lag. ``rate`` and ``paused`` are live parameters of ``/drive/player``.
"""

from __future__ import annotations

import dataclasses
import sys
import time
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, ParameterDescriptor, SetParametersResult
from rclpy.duration import Duration
from rclpy.exceptions import InvalidTopicNameException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import QoSProfile

from ..bag import RecordedTopic, first_log_time, iter_messages, recorded_topics
from ..codec import encode_clock
from ..errors import ConfigError
from ..interface import NAMESPACE, PLAYER_NODE, TOPICS, Qos
from .transport import msg_class, qos, spin_once

__all__ = ["PlayOptions", "PlayResult", "PlayerNode", "play"]

NS = 1_000_000_000
#: how often (wall s) the player serves its parameter services while it publishes flat out
SERVICE_PERIOD = 0.05
#: s of recorded time behind the pace from which the player says it falls behind
BEHIND = 0.1
#: s the player waits, at the end, for reliable readers to acknowledge what it published
ACK_TIMEOUT = 10.0
#: the discovery settle before the first message (without ``--wait-for``): at least the first s
#: — Fast DDS matched a subscriber already running within about 0.12 s of a new publisher's
#: creation, or at its next periodic announcement, 2.1-2.6 s (10 tries on localhost beside three
#: busy loops) and 3.06 s once in a CI run (at 3 s the subscriber then missed the first 61
#: states) — and until the played topics' matched subscribers held still for the second s, at
#: most the third
SETTLE = (4.0, 0.5, 8.0)


@dataclass(frozen=True)
class PlayOptions:
    """What ``ros2 bag play`` offers, by the same names: rate (> 0), start offset and playback
    duration (s of recorded time), loop, topics to play or exclude, remaps (old → new name),
    /clock from the replayed time at ``clock_hz`` (the recorded /clock then left out), start
    paused."""

    rate: float = 1.0
    start_offset: float = 0.0
    playback_duration: float | None = None
    loop: bool = False
    topics: tuple[str, ...] = ()
    exclude_topics: tuple[str, ...] = ()
    remap: dict[str, str] = field(default_factory=dict)
    clock_hz: float | None = None
    start_paused: bool = False
    #: before the first message, wait until every played topic has this many matched
    #: subscribers (None: the discovery settle, :data:`SETTLE`)
    wait_for: int | None = None

    def __post_init__(self) -> None:
        if not self.rate > 0:
            raise ConfigError(f"--rate must be > 0, got {self.rate}")
        if self.wait_for is not None and self.wait_for < 1:
            raise ConfigError(f"--wait-for must be at least 1 subscriber, got {self.wait_for}")
        if self.start_offset < 0:
            raise ConfigError(f"--start-offset must be >= 0 s, got {self.start_offset}")
        if self.playback_duration is not None and not self.playback_duration > 0:
            raise ConfigError(f"--playback-duration must be > 0 s, got {self.playback_duration}")
        if self.clock_hz is not None and not self.clock_hz > 0:
            raise ConfigError(f"--clock must be > 0 Hz, got {self.clock_hz}")


@dataclass
class PlayResult:
    """``replay``: what was published of ``bag`` (per topic as it went out, remaps applied), the
    achieved rate (recorded s per wall s), how far behind the recording's pace the last message
    and the latest one went (s of recorded time; 0 when on time), the wall time and the passes
    (``--loop``); ``interrupted``: Ctrl-C ended it (what went out until then)."""

    bag: Path
    published: dict[str, int]
    achieved_rate: float
    lag_s: float
    max_lag_s: float
    wall_s: float
    passes: int
    interrupted: bool = False

    def as_dict(self) -> dict[str, Any]:
        return {**dataclasses.asdict(self), "bag": str(self.bag)}


def qos_of(recorded: list[dict[str, Any]]) -> QoSProfile:
    """rclpy QoS from a rosbag2 offered QoS profile (the first one offered)."""
    return qos(Qos.from_rosbag2(recorded[0] if recorded else {}))


class PlayerNode(Node):
    """``/drive/player``: one publisher per played topic; ``rate`` and ``paused`` settable."""

    def __init__(self, topics: dict[str, RecordedTopic], options: PlayOptions, **kw: Any) -> None:
        super().__init__(PLAYER_NODE, namespace=NAMESPACE, **kw)
        self.options = options
        rate_desc = ParameterDescriptor(
            description="playback rate: recorded seconds per wall second; > 0",
            floating_point_range=[FloatingPointRange(from_value=0.0, to_value=1e6, step=0.0)],
        )
        self.rate = float(self.declare_parameter("rate", options.rate, rate_desc).value)
        self.paused = bool(
            self.declare_parameter(
                "paused",
                options.start_paused,
                ParameterDescriptor(description="playback paused (true) or running"),
            ).value
        )
        self.pubs = {}
        for name, t in topics.items():
            target = options.remap.get(name, name)
            try:
                self.pubs[name] = self.create_publisher(msg_class(t.type), target, qos_of(t.qos))
            except InvalidTopicNameException as e:
                raise ConfigError(
                    f"--remap {name}:={target}: {target!r} is not a valid ROS topic name "
                    f"({str(e).splitlines()[0]})"
                ) from None
        self.clock_pub = None
        if options.clock_hz is not None:
            clock = TOPICS["clock"]
            self.clock_pub = self.create_publisher(msg_class(clock.type), clock.name, 10)
        self.add_on_set_parameters_callback(self._validate)
        self.add_post_set_parameters_callback(self._apply)
        self.changed = False

    def destroy_node(self) -> None:  # rclpy leaves it unannotated (see node_base.DriveNode)
        super().destroy_node()  # type: ignore[no-untyped-call]

    def _validate(self, params: list[Parameter]) -> SetParametersResult:
        for p in params:
            if p.name == "rate" and not (isinstance(p.value, float) and p.value > 0):
                return SetParametersResult(successful=False, reason="rate must be a number > 0")
            if p.name == "paused" and not isinstance(p.value, bool):
                return SetParametersResult(successful=False, reason="paused is true or false")
        return SetParametersResult(successful=True)

    def _apply(self, params: list[Parameter]) -> None:
        for p in params:
            if p.name == "rate":
                self.rate = float(p.value)
                self.changed = True
            elif p.name == "paused":
                self.paused = bool(p.value)
                self.changed = True


class _PlayClock:
    """Recorded time (s after the start) as it advances with wall time at the player's rate,
    stopping while paused; re-anchored whenever rate or pause change."""

    def __init__(self, rate: float, paused: bool) -> None:
        self.rate, self.paused = rate, paused
        self._at, self._wall = 0.0, time.perf_counter()
        self.running_wall = 0.0  #: wall s spent not paused

    def now(self) -> float:
        if self.paused:
            return self._at
        return self._at + (time.perf_counter() - self._wall) * self.rate

    def set(self, rate: float, paused: bool) -> None:
        now, wall = self.now(), time.perf_counter()
        if not self.paused:
            self.running_wall += wall - self._wall
        self._at, self._wall, self.rate, self.paused = now, wall, rate, paused

    def running(self) -> float:
        return self.running_wall + (0.0 if self.paused else time.perf_counter() - self._wall)


def play(bag: str | Path, options: PlayOptions, *, context: Any = None) -> PlayResult:
    """Publish ``bag`` onto ROS with ``options`` (rclpy initialised in ``context`` by the
    caller); returns what went out. Stops at the end (or, looping, on KeyboardInterrupt)."""
    from .transport import executor

    available = recorded_topics(bag)
    chosen = list(options.topics) or list(available)
    unknown = [t for t in [*chosen, *options.exclude_topics, *options.remap] if t not in available]
    if unknown:
        raise ConfigError(
            f"{bag}: no topic {unknown[0]!r} in the recording; it has {', '.join(available)}"
        )
    play_topics = [t for t in chosen if t not in options.exclude_topics]
    if options.clock_hz is not None:
        # replaced by the player's own
        play_topics = [t for t in play_topics if t != TOPICS["clock"].name]
    node = PlayerNode({t: available[t] for t in play_topics}, options, context=context)
    ex = executor(context)
    ex.add_node(node)
    published = {node.pubs[t].topic_name: 0 for t in play_topics}
    lag = max_lag = 0.0
    passes = 0
    clock = _PlayClock(node.rate, node.paused)
    next_service = next_clock = time.perf_counter()
    clock_period = 1.0 / options.clock_hz if options.clock_hz is not None else 0.0
    said_behind = 0.0
    first = first_log_time(bag)
    interrupted = False
    done_ns = span_ns = 0  #: recorded time played: the passes before this one, and all of it
    try:
        _matched(node, ex, options.wait_for)
        clock = _PlayClock(node.rate, node.paused)  # the pace starts with the first message
        next_service = next_clock = time.perf_counter()
        while True:
            passes += 1
            msgs = _window(bag, play_topics, options, first)
            start_ns: int | None = None
            for topic, t_ns, data in msgs:
                if start_ns is None:
                    start_ns = t_ns
                due = (done_ns + t_ns - start_ns) / NS  # recorded time played, over the passes
                while True:  # wait for the message's time (serving parameters, /clock)
                    wall = time.perf_counter()
                    if node.changed:
                        node.changed = False
                        clock.set(node.rate, node.paused)
                    if clock.paused or clock.now() < due or wall >= next_service:
                        # paused: wait for a parameter set (it wakes the spin) a service
                        # period at a time; a zero timeout kept a core ~35 % busy
                        wait = SERVICE_PERIOD if clock.paused else (due - clock.now()) / clock.rate
                        spin_once(ex, min(max(wait, 0.0), SERVICE_PERIOD))
                        next_service = time.perf_counter() + SERVICE_PERIOD
                    if node.clock_pub is not None and wall >= next_clock and not clock.paused:
                        # the replayed time within this pass: the pace's while on time, the
                        # next message's when behind (never ahead of what has gone out)
                        now = start_ns / NS + min(clock.now(), due) - done_ns / NS
                        node.clock_pub.publish(encode_clock(now))
                        next_clock = wall + clock_period
                    if not clock.paused and clock.now() >= due:
                        break
                node.pubs[topic].publish(data)
                published[node.pubs[topic].topic_name] += 1
                span_ns = done_ns + t_ns - start_ns
                lag = max(0.0, clock.now() - due)
                max_lag = max(max_lag, lag)
                if lag > BEHIND and time.perf_counter() - said_behind > 2.0:
                    said_behind = time.perf_counter()
                    print(
                        f"predictive-drive: replay falls behind: {lag:.2f} s of recorded time "
                        f"behind the pace at rate {clock.rate:g} (it publishes as fast as it "
                        f"can and drops nothing)",
                        file=sys.stderr,
                        flush=True,
                    )
            done_ns = span_ns
            if not options.loop or start_ns is None:
                break
        running = clock.running()  # publishing ends here (not the wait for acknowledgements)
    except KeyboardInterrupt:
        interrupted = True
        running = clock.running()
    finally:
        # let reliable readers have everything before we go (briefly, when told to stop)
        ack_wait = Duration(seconds=1.0 if interrupted else ACK_TIMEOUT)
        for pub in node.pubs.values():
            pub.wait_for_all_acked(ack_wait)
        ex.shutdown(timeout_sec=1.0)
        node.destroy_node()
    return PlayResult(
        bag=Path(bag),
        published=published,
        achieved_rate=span_ns / NS / running if running > 0 else float("nan"),
        lag_s=lag,
        max_lag_s=max_lag,
        wall_s=running,
        passes=passes,
        interrupted=interrupted,
    )


def _matched(node: PlayerNode, ex: Any, wait_for: int | None) -> None:
    """Before the first message: the subscribers of the played topics matched. A volatile
    message sent before a subscriber matched is lost to it, and discovering one that runs
    takes up to a few seconds (one started 3 s before a replay at rate 0.05 missed the first 233
    states of 6,001). With ``wait_for``, until every played topic has that many
    (said on stderr; Ctrl-C gives up); else the discovery settle (:data:`SETTLE`)."""
    pubs = list(node.pubs.values())

    def counts() -> list[int]:
        return [p.get_subscription_count() for p in pubs]

    start = time.perf_counter()
    if wait_for is not None:
        said: int | None = None  # the count last said: said again as it changes
        while (matched := min(counts(), default=wait_for)) < wait_for:
            if matched != said and time.perf_counter() - start > 1.0:
                said = matched
                print(
                    f"predictive-drive: replay waits for {wait_for} subscriber(s) of each played "
                    f"topic (now {matched}; Ctrl-C gives up)",
                    file=sys.stderr,
                    flush=True,
                )
            spin_once(ex, SERVICE_PERIOD)
        return
    least, still, most = SETTLE
    seen, since = counts(), start
    while (now := time.perf_counter()) - start < most:
        if now - start >= least and now - since >= still:
            return
        spin_once(ex, SERVICE_PERIOD)
        if (c := counts()) != seen:
            seen, since = c, time.perf_counter()


def _window(
    bag: str | Path, topics: list[str], options: PlayOptions, first: int | None
) -> Iterator[tuple[str, int, bytes]]:
    """The recording's messages of ``topics`` within the start offset and playback duration
    (``first``: the recording's first log time, ns)."""
    if first is None:
        return
    start = first + round(options.start_offset * NS)
    end = None
    if options.playback_duration is not None:
        end = start + round(options.playback_duration * NS)
    yield from iter_messages(bag, topics=topics, start_ns=start, end_ns=end)
