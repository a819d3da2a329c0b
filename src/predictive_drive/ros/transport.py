"""How the nodes talk: QoS profiles from the interface's plain data, the executor, raw
(serialized) publishers and subscriptions, and the in-process bus of the composed engine."""

from __future__ import annotations

import importlib
import os
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from .. import interrupts
from ..interface import TOPICS, Qos
from .placement import ros_log_dir

__all__ = [
    "LocalBus",
    "Outlet",
    "executor",
    "msg_class",
    "qos",
    "raw_publisher",
    "raw_subscription",
    "ros_context",
    "ros_session",
    "spin_once",
]


def qos(q: Qos) -> QoSProfile:
    return QoSProfile(
        reliability=ReliabilityPolicy.RELIABLE
        if q.reliability == "reliable"
        else ReliabilityPolicy.BEST_EFFORT,
        durability=DurabilityPolicy.TRANSIENT_LOCAL
        if q.durability == "transient_local"
        else DurabilityPolicy.VOLATILE,
        history=HistoryPolicy.KEEP_ALL if q.history == "keep_all" else HistoryPolicy.KEEP_LAST,
        depth=max(q.depth, 1),
    )


def executor(context: Any = None) -> Any:
    """EventsExecutor (about 3x faster per hop than the default here). Always spin it with a finite
    timeout: in these wheels spin()/spin_once() without one never runs callbacks."""
    from rclpy.experimental.events_executor import EventsExecutor

    return EventsExecutor(context=context)


def spin_once(ex: Any, timeout: float) -> None:
    """One turn of a tool's executor in the command line's process (the launcher's watch, the
    player, the stepper): a Ctrl-C that comes meanwhile is raised when the spin returns, never
    inside a callback, where rclpy's executor logs it as a FATAL callback exception with its
    traceback and the callback is cut (see :mod:`~predictive_drive.interrupts`)."""
    with interrupts.held():
        ex.spin_once(timeout_sec=timeout)


@contextmanager
def ros_context(domain: int, *, log_dir: Path | None = None) -> Iterator[Any]:
    """An rclpy context of its own on ROS domain ``domain``, shut down however the block ends
    (a tool's process: the launcher's watch, the player, the stepper, ``param``); rcl's log
    files go to ``log_dir`` or a temp folder (see :func:`~.placement.ros_log_dir`)."""
    import rclpy
    from rclpy.context import Context
    from rclpy.utilities import try_shutdown

    # rcl reads it when this process first initialises logging: set for that moment only, so
    # the node processes this process starts later still log with their runs
    before = os.environ.get("ROS_LOG_DIR")
    ros_log_dir(os.environ, log_dir)
    ctx = Context()
    try:
        rclpy.init(context=ctx, domain_id=domain)
    finally:
        if before is None:
            os.environ.pop("ROS_LOG_DIR", None)
        else:
            os.environ["ROS_LOG_DIR"] = before
    try:
        yield ctx
    finally:
        try_shutdown(context=ctx)


@contextmanager
def ros_session(
    name: str, *, domain: int, namespace: str | None = None, log_dir: Path | None = None
) -> Iterator[tuple[Any, Any]]:
    """``(node, executor)``: a node ``name`` (in ``namespace``) on a context of its own, added
    to an executor of its own; node, executor and context end with the block."""
    import rclpy

    with ros_context(domain, log_dir=log_dir) as ctx:
        node = rclpy.create_node(name, namespace=namespace, context=ctx)
        ex = executor(ctx)
        ex.add_node(node)
        try:
            yield node, ex
        finally:
            ex.shutdown(timeout_sec=1.0)
            node.destroy_node()


def msg_class(type_name: str) -> Any:
    """The rclpy message class of ``pkg/msg/Type``."""
    pkg, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def raw_publisher(node: Any, key: str) -> Any:
    """A publisher of topic ``key`` of the topic table, with its type and QoS; it publishes the
    serialized bytes of :mod:`predictive_drive.codec`."""
    t = TOPICS[key]
    return node.create_publisher(msg_class(t.type), t.name, qos(t.qos))


def raw_subscription(node: Any, key: str, callback: Callable[[bytes], None]) -> Any:
    """A subscription of topic ``key`` of the topic table that hands ``callback`` the message's
    serialized bytes."""
    t = TOPICS[key]
    return node.create_subscription(msg_class(t.type), t.name, callback, qos(t.qos), raw=True)


class LocalBus:
    """Delivery between the nodes of one process without DDS — what rclcpp's intra-process
    communication does for composed nodes; rclpy has none.

    A subscription made through the bus is a local callback; a publisher's message is queued for
    every local subscriber of its topic (FIFO, the order DDS would deliver a lock-step graph's
    messages in) and still goes out over DDS whenever an outside subscriber is matched (a tool, the
    launcher's /clock watch). The spin loop runs the queue between executor spins.
    """

    def __init__(self) -> None:
        self.subscribers: dict[str, list[Callable[[bytes], None]]] = {}
        self.queue: deque[tuple[Callable[[bytes], None], bytes]] = deque()

    def subscribe(self, topic: str, callback: Callable[[bytes], None]) -> None:
        self.subscribers.setdefault(topic, []).append(callback)

    def count(self, topic: str) -> int:
        return len(self.subscribers.get(topic, ()))

    def run(self, budget: int) -> int:
        """Deliver up to ``budget`` queued messages; returns how many were delivered."""
        queue = self.queue
        n = 0
        while queue and n < budget:
            callback, data = queue.popleft()
            callback(data)
            n += 1
        return n


class Outlet:
    """A publisher that also serves the local subscribers of its topic (see :class:`LocalBus`).

    ``recheck``: how many messages go out between two looks at the topic's outside (DDS)
    subscribers (asking rmw costs more than the rest of a publish): 1 for a topic the graph's
    own tools must never miss a message of (/clock: the launcher's switches follow it); for a
    per-step topic, an outside subscriber that comes in the middle of a run (a tool, a second
    recorder) may miss the messages of up to ``recheck`` steps before its first."""

    def __init__(self, pub: Any, bus: LocalBus, recheck: int = 1) -> None:
        self.pub = pub
        self.topic_name = pub.topic_name
        self._local = bus.subscribers.setdefault(pub.topic_name, [])
        self._queue = bus.queue
        self._recheck = recheck
        self._until_look = 0
        self._outside = 0

    def publish(self, data: bytes) -> None:
        for callback in self._local:
            self._queue.append((callback, data))
        self._until_look -= 1
        if self._until_look <= 0:
            self._outside = self.pub.get_subscription_count()
            self._until_look = self._recheck
        if self._outside:  # only outside subscribers are DDS ones
            self.pub.publish(data)

    def get_subscription_count(self) -> int:
        return len(self._local) + int(self.pub.get_subscription_count())

    def wait_for_all_acked(self, timeout: Any) -> bool:
        return bool(self.pub.wait_for_all_acked(timeout))
