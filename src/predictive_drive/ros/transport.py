"""How the nodes talk: QoS profiles from the interface's plain data, the executor, raw
(serialized) publishers and subscriptions, and the in-process bus of the composed engine."""

from __future__ import annotations

import importlib
from collections import deque
from collections.abc import Callable
from typing import Any

from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..interface import Qos

__all__ = ["LocalBus", "Outlet", "executor", "msg_class", "qos"]


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
    from rclpy.experimental import EventsExecutor

    return EventsExecutor(context=context)


def msg_class(type_name: str) -> Any:
    """The rclpy message class of ``pkg/msg/Type``."""
    pkg, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


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
    """A publisher that also serves the local subscribers of its topic (see :class:`LocalBus`)."""

    def __init__(self, pub: Any, bus: LocalBus) -> None:
        self.pub = pub
        self.topic_name = pub.topic_name
        self._local = bus.subscribers.setdefault(pub.topic_name, [])
        self._queue = bus.queue

    def publish(self, data: bytes) -> None:
        for callback in self._local:
            self._queue.append((callback, data))
        if self.pub.get_subscription_count():  # only outside subscribers are DDS ones
            self.pub.publish(data)

    def get_subscription_count(self) -> int:
        return len(self._local) + self.pub.get_subscription_count()

    def wait_for_all_acked(self, timeout: Any) -> bool:
        return bool(self.pub.wait_for_all_acked(timeout))
