"""What every node shares: QoS conversion, parameters declared from the scenario dataclasses, the
executor, the jazzy shutdown pattern and the peer watchdog."""

from __future__ import annotations

import dataclasses
import os
import signal
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import rclpy
from rcl_interfaces.msg import ParameterDescriptor
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

from ..config import MACHINE_SECTIONS, NAMESPACE, _build, load_scenario
from ..core.control import Machine
from ..core.scenario import RunParams, Scenario
from ..errors import ConfigError, GraphError
from ..interface import TOPICS, Qos
from .graph import CPUS_ENV, LAUNCHER_ENV, SCHED_ENV, SCHED_POLICIES

__all__ = [
    "DriveNode",
    "LocalBus",
    "executor",
    "closing",
    "qos",
    "spin_main",
    "spin_node",
]

#: s a closing process may take (bag summary, node and context teardown) before SIGALRM ends it
CLOSE_TIMEOUT = 30

#: wall-clock bounds (s) every node declares besides the scenario
RUNTIME_PARAMS = {
    "peer_timeout": (10.0, "s of wall time a lock-step peer may stay silent before the run fails"),
    "startup_timeout": (60.0, "s of wall time to wait for all peers to match before step 0"),
}

_DESCRIPTIONS = {
    "ts": "control period, s",
    "duration": "simulated run length, s",
    "scenario": "scenario name (config/<name>.yaml)",
    "machine": "machine type: induction | pmsm",
    "strategy": "control law; switchable at run time (takes effect at the next step)",
}


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


class LocalBus:
    """Delivery between the nodes of one process without DDS — what rclcpp's intra-process
    communication does for composed nodes; rclpy has none.

    A subscription made through the bus is a local callback; a publisher's message is queued for
    every local subscriber of its topic (FIFO, the order DDS would deliver a lock-step graph's
    messages in) and still goes out over DDS whenever an outside subscriber is matched (a tool, the
    launcher's /clock watch). :func:`spin_nodes` runs the queue between executor spins.
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


class DriveNode(Node):
    """Base of the four nodes: declares the shared and own-section parameters from the scenario
    dataclasses (read-only except ``strategy``) and validates them with the scenario loader."""

    section: str = ""

    def __init__(self, name: str, *, bus: LocalBus | None = None, **kwargs: Any) -> None:
        self.bus = bus
        kwargs.setdefault("namespace", NAMESPACE)
        super().__init__(name, **kwargs)
        if not self.has_parameter("use_sim_time"):
            self.declare_parameter("use_sim_time", True)
        self.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, True)])
        for key, (default, desc) in RUNTIME_PARAMS.items():
            self.declare_parameter(key, default, ParameterDescriptor(description=desc))
        self.failure: str | None = None
        self._finished = False
        self.notify: Callable[[], None] = lambda: None

    @property
    def finished(self) -> bool:
        return self._finished

    @finished.setter
    def finished(self, value: bool) -> None:
        self._finished = value
        self.notify()

    def check(self) -> None:
        """Called by the spin loop at least every 0.1 s (watchdogs)."""

    # -- parameters -------------------------------------------------------------------------
    def _declare_section(self, cls: type, nested: dict[str, type], prefix: str = "") -> dict:
        data: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            name = f"{prefix}{f.name}"
            if f.name in nested:
                data[f.name] = self._declare_section(nested[f.name], {}, f"{name}.")
                continue
            desc = ParameterDescriptor(
                description=_DESCRIPTIONS.get(f.name, (cls.__doc__ or "").strip().split("\n")[0]),
                read_only=f.name != "strategy",
                dynamic_typing=True,
            )
            default = None if f.default is dataclasses.MISSING else f.default
            value = self.declare_parameter(name, default, desc).value
            if value is None:
                continue
            data[f.name] = list(value) if isinstance(value, (list, tuple)) else value
        return data

    def load_params(self) -> tuple[RunParams, Any]:
        """(shared run parameters, this node's section dataclass), validated like a scenario file."""
        where = f"{self.get_fully_qualified_name()} parameters"
        run = _build(RunParams, self._declare_section(RunParams, {}), {}, f"{where} (/**)")
        if not self.section:
            return run, None
        cls, nested = MACHINE_SECTIONS[Machine(run.machine)][self.section]
        own = _build(cls, self._declare_section(cls, nested), nested, where)
        return run, own

    def scenario(self) -> Scenario:
        """The whole scenario file named by the ``scenario`` parameter (for the logger's bag)."""
        return load_scenario(self.get_parameter("scenario").value)

    @property
    def peer_timeout(self) -> float:
        return float(self.get_parameter("peer_timeout").value)

    @property
    def startup_timeout(self) -> float:
        return float(self.get_parameter("startup_timeout").value)

    # -- lock-step helpers --------------------------------------------------------------------
    def publisher(self, key: str) -> Any:
        t = TOPICS[key]
        pub = self.create_publisher(_msg_class(t.type), t.name, qos(t.qos))
        return pub if self.bus is None else Outlet(pub, self.bus)

    def subscription(self, key: str, callback: Callable[[bytes], None]) -> Any:
        """Raw (serialized) subscription; through the process's :class:`LocalBus` if it has one."""
        t = TOPICS[key]
        if self.bus is not None:
            self.bus.subscribe(t.name, callback)
            return None
        return self.create_subscription(_msg_class(t.type), t.name, callback, qos(t.qos), raw=True)

    def wait_matched(self, pub: Any, count: int, what: str) -> None:
        """Block (briefly, in a callback is fine: matching runs in DDS threads) until ``pub`` has
        ``count`` matched subscriptions, or fail after startup_timeout."""
        deadline = time.monotonic() + self.startup_timeout
        while pub.get_subscription_count() < count:
            if time.monotonic() > deadline:
                raise GraphError(
                    f"{self.get_fully_qualified_name()}: {pub.topic_name} has "
                    f"{pub.get_subscription_count()} of {count} subscribers ({what}) after "
                    f"{self.startup_timeout} s"
                )
            time.sleep(0.005)

    def fail(self, message: str) -> None:
        self.failure = message
        self.get_logger().error(message)
        self.notify()


def _msg_class(type_name: str) -> Any:
    import importlib

    pkg, _, name = type_name.split("/")
    return getattr(importlib.import_module(f"{pkg}.msg"), name)


def spin_node(
    make: Callable[[], DriveNode],
    *,
    args: list[str] | None = None,
) -> int:
    """Jazzy main pattern around one node; returns the process exit code."""
    return spin_main(lambda _bus: [make()], args=args)


def spin_main(
    make: Callable[[LocalBus | None], list[DriveNode]],
    *,
    args: list[str] | None = None,
    bus: LocalBus | None = None,
) -> int:
    """Jazzy main pattern: init, ``make(bus)`` the nodes, spin them, close them however the run
    ends (the logger closes its bag), shut down. Returns the process exit code."""
    rclpy.init(args=args)
    nodes: list[DriveNode] = []
    code = 0
    try:
        nodes = make(bus)
        code = spin_nodes(nodes, bus)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = 130
    except (ConfigError, GraphError) as e:
        print(f"{e}", file=sys.stderr)
        code = 2
    finally:
        with closing():
            for n in nodes:
                if n.failure:
                    print(n.failure, file=sys.stderr)
                close = getattr(n, "close", None)
                if close is not None:
                    close()
                n.destroy_node()
            rclpy.try_shutdown()
    return code


@contextmanager
def closing() -> Iterator[None]:
    """The process is closing: a second SIGINT/SIGTERM (or one still pending after rclpy's own
    handler shut the context down) must not raise KeyboardInterrupt in the middle of closing the
    bag. The launcher still escalates to SIGKILL if closing hangs; without a launcher (or with
    one that died) SIGALRM ends a close that takes longer than CLOSE_TIMEOUT."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    signal.alarm(CLOSE_TIMEOUT)
    try:
        yield
    finally:
        signal.alarm(0)


#: local deliveries between executor polls (~70 steps of the drive graph)
_BATCH = 500


def spin_nodes(nodes: list[DriveNode], bus: LocalBus | None = None) -> int:
    """Spin until every node has finished or one fails; 0 on success, 1 on a node failure.

    The executor runs in C++ until a node signals (finished / failed) or 0.1 s pass; then the
    watchdogs run. Every spin has a finite timeout (see :func:`executor`). With a ``bus``, its
    queued messages are delivered in batches, the executor (parameter services, outside traffic)
    polled between them.
    """
    from rclpy.task import Future

    ex = executor()
    done = Future()

    def notify() -> None:
        if not done.done() and (any(n.failure for n in nodes) or all(n.finished for n in nodes)):
            done.set_result(True)

    for n in nodes:
        n.notify = notify
        ex.add_node(n)
    launcher = int(os.environ.get(LAUNCHER_ENV, "0"))
    try:
        while rclpy.ok():
            if bus is not None and bus.run(_BATCH):
                ex.spin_until_future_complete(done, timeout_sec=0.0)
            else:
                ex.spin_until_future_complete(done, timeout_sec=0.1)
            for n in nodes:
                n.check()
            if launcher and os.getppid() != launcher and not nodes[0].failure:
                nodes[0].fail(f"the launcher (pid {launcher}) is gone; ending the run")
            notify()
            if any(n.failure for n in nodes):
                return 1
            if all(n.finished for n in nodes):
                return 0
    finally:
        ex.shutdown(timeout_sec=1.0)
    return 130


def run_main(node_cls: type, args: list[str] | None = None) -> int:
    if args is None:
        args = sys.argv
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    apply_placement()
    return spin_node(node_cls, args=args)


def apply_placement() -> None:
    """Apply the placement its launcher chose to this process: the CPUs (:data:`CPUS_ENV`) and the
    scheduling policy (:data:`SCHED_ENV`) of every thread it has now (imports may have started
    some) and, since this runs before rclpy and DDS start theirs, of every later one (threads
    inherit both)."""
    cpus = os.environ.get(CPUS_ENV, "").strip()
    sched = os.environ.get(SCHED_ENV, "").strip()
    if cpus:
        try:
            chosen = {int(c) for c in cpus.split(",")}
            _each_thread(lambda tid: os.sched_setaffinity(tid, chosen))
        except (ValueError, OSError) as e:
            raise SystemExit(
                f"{CPUS_ENV}={cpus!r}: cannot keep to these CPUs ({e}); expected "
                f"comma-separated ids of {sorted(os.sched_getaffinity(0))}"
            ) from None
    if sched:
        if sched not in SCHED_POLICIES:
            raise SystemExit(
                f"{SCHED_ENV}={sched!r}: unknown scheduling policy; expected one of "
                f"{', '.join(SCHED_POLICIES)}"
            )
        policy = SCHED_POLICIES[sched]
        try:
            _each_thread(lambda tid: os.sched_setscheduler(tid, policy, os.sched_param(0)))
        except OSError as e:
            raise SystemExit(f"{SCHED_ENV}={sched!r}: cannot use this policy ({e})") from None


def _each_thread(apply: Callable[[int], None]) -> None:
    for tid in os.listdir("/proc/self/task"):
        try:
            apply(int(tid))
        except ProcessLookupError:
            pass  # a thread that ended meanwhile
