"""What every drive node shares: parameters declared from the scenario dataclasses (their meaning,
unit and range from the field metadata), the peer watchdog, the executor loop and the jazzy
shutdown pattern."""

from __future__ import annotations

import dataclasses
import math
import os
import signal
import sys
import time
import typing
from collections.abc import Callable, Collection, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from typing import Any

import rclpy
from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.duration import Duration
from rclpy.executors import ExternalShutdownException
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.signals import SignalHandlerOptions
from rclpy.utilities import ok, try_shutdown

from ..config import build_section, section_class
from ..core.fields import Quantity, check_fields, quantity, spec_of
from ..core.scenario import RunParams
from ..errors import ConfigError, GraphError
from ..interface import LOSSES_TOPIC, NAMESPACE, RECORD_TOPICS, TOPICS
from .placement import apply_placement, launcher_pid
from .transport import LocalBus, Outlet, executor, raw_publisher, raw_subscription

__all__ = [
    "DriveNode",
    "NodeTimeouts",
    "WatchedNode",
    "closing",
    "describe",
    "run_main",
    "spin_main",
    "spin_nodes",
]

#: composed: a per-step topic looks for outside (DDS) subscribers every this many messages
#: (:class:`~.transport.Outlet`): a tool subscribing mid-run misses at most 3 ms of a 20 kHz run
OUTSIDE_RECHECK = 64
#: s a closing process may take (messages in flight, bag summary, teardown) before SIGALRM ends it
CLOSE_TIMEOUT = 60
#: s the nodes may spend, once the run ends, on messages still in flight: publishers wait for
#: their readers' acknowledgements, the logger takes what still arrives
FINISH_TIMEOUT = 20.0


class StopFlag:
    """Set by SIGINT / SIGTERM: the node ends its run and closes (rclpy's own handlers are not
    installed: they would shut the context down before the logger has taken what is in flight).

    A plain attribute, no lock: a signal handler runs between two bytecodes of the main thread,
    so a second signal can run it again inside the first call. ``threading.Event.set`` takes a
    lock there, and the nested call waited forever for the lock its outer call held (a torque
    controller sat in a futex after a double Ctrl-C). The spin loop looks at the flag at least
    every 0.1 s, so nothing needs waking."""

    __slots__ = ("signum",)

    def __init__(self) -> None:
        #: the signal that set it (0: none). SIGINT asks a node to finish what is in flight
        #: (its publishers wait for every acknowledgement); SIGTERM asks it to finish quickly: a
        #: peer is gone, so acknowledgements it owes will never come (the logger still takes
        #: what is in flight). The first signal decides.
        self.signum = 0

    def set(self, signum: int = signal.SIGINT) -> None:
        if not self.signum:
            self.signum = signum

    def is_set(self) -> bool:
        return self.signum != 0

    def clear(self) -> None:
        self.signum = 0


STOP = StopFlag()
#: s a node stopped by SIGTERM waits for acknowledgements before it goes
QUICK_FINISH = 1.0
#: the line a node run by the project's launcher writes to its log when a signal stopped it
#: mid-run (the launcher reads it to say who stopped the run and at which step)
STOPPED_LINE = "stopped by {signal} at step {step}"

_INT64 = (-(2**63), 2**63 - 1)


@dataclass(frozen=True)
class NodeTimeouts:
    """Wall-clock bounds every drive node declares besides its scenario section."""

    peer_timeout: float = quantity(
        "wall time a lock-step peer may stay silent before the run fails", "s", gt=0, default=10.0
    )
    startup_timeout: float = quantity(
        "wall time to wait for every peer to match before step 0", "s", gt=0, default=60.0
    )

    def __post_init__(self) -> None:
        check_fields(self)


def describe(q: Quantity | None, hint: Any, *, read_only: bool) -> ParameterDescriptor:
    """The ROS descriptor of a parameter field: its meaning, unit and range in the description,
    and a ``FloatingPointRange`` / ``IntegerRange`` for a bounded scalar number."""
    d = ParameterDescriptor(
        description=q.text() if q is not None else "", read_only=read_only, dynamic_typing=True
    )
    if q is None or q.choices or q.nan_default or (q.low is None and q.high is None):
        return d
    if hint is int:
        low = _INT64[0] if q.low is None else math.ceil(q.low)
        high = _INT64[1] if q.high is None else math.floor(q.high)
        d.integer_range = [IntegerRange(from_value=low, to_value=high, step=0)]
    elif hint is float:
        low_f = -math.inf if q.low is None else q.low
        high_f = math.inf if q.high is None else q.high
        d.floating_point_range = [FloatingPointRange(from_value=low_f, to_value=high_f, step=0.0)]
    return d


class DriveNode(Node):
    """Base of the drive nodes: declares the shared (``/**``) and own-section parameters from the
    scenario dataclasses (read-only except those named in ``writable``) and validates them as the
    scenario loader does."""

    section: str = ""
    writable: Collection[str] = ()

    def __init__(self, name: str, *, bus: LocalBus | None = None, **kwargs: Any) -> None:
        self.bus = bus
        kwargs.setdefault("namespace", NAMESPACE)
        super().__init__(name, **kwargs)
        # rclpy declares use_sim_time (default false) itself; refuse only a false one was given
        given = self._parameter_overrides.get("use_sim_time")
        if not self.has_parameter("use_sim_time"):
            self.declare_parameter("use_sim_time", True)
        elif given is not None and given.value is False:
            raise ConfigError(
                f"{self.get_fully_qualified_name()}: use_sim_time is false; the drive runs on "
                f"simulated time only (the plant's /clock): leave it true"
            )
        self.set_parameters([Parameter("use_sim_time", Parameter.Type.BOOL, True)])
        self.add_on_set_parameters_callback(self._keep_sim_time)
        self.timeouts: NodeTimeouts = build_section(
            NodeTimeouts, self.declare_fields(NodeTimeouts), {}, self._where()
        )
        self.failure: str | None = None
        self._finished = False
        self.notify: Callable[[], None] = lambda: None

    # rclpy leaves these two unannotated (and mypy's untyped_calls_exclude does not reach a
    # method called on a subclass): annotated here, once, for every drive node
    def get_logger(self) -> RcutilsLogger:
        logger: RcutilsLogger = super().get_logger()  # type: ignore[no-untyped-call]
        return logger

    def destroy_node(self) -> None:
        super().destroy_node()  # type: ignore[no-untyped-call]

    def _keep_sim_time(self, params: list[Parameter]) -> Any:
        from rcl_interfaces.msg import SetParametersResult

        for p in params:
            if p.name == "use_sim_time" and p.value is not True:
                return SetParametersResult(
                    successful=False,
                    reason="use_sim_time must stay true: the drive runs on simulated time only",
                )
        return SetParametersResult(successful=True)

    @property
    def finished(self) -> bool:
        return self._finished

    @finished.setter
    def finished(self, value: bool) -> None:
        self._finished = value
        self.notify()

    def check(self) -> None:
        """Called by the spin loop at least every 0.1 s (watchdogs)."""

    def finish(self, spin: Callable[[float], None], deadline: float) -> None:
        """The run is over (done, failed or stopped): see the messages still in flight through,
        until ``deadline`` (time.monotonic()). ``spin(t)`` runs the executor for up to t s."""

    @property
    def last_step(self) -> int:
        """The last step this node has handled (-1 before the first)."""
        return -1

    def resumed(self) -> None:
        """This process did not run for a while (stopped by a signal, starved): the time its
        watchdogs measured is not its peers' silence."""

    # -- parameters -------------------------------------------------------------------------
    def _where(self) -> str:
        return f"{self.get_fully_qualified_name()} parameters"

    def declare_fields(
        self, cls: type, nested: dict[str, type] | None = None, prefix: str = ""
    ) -> dict[str, Any]:
        """Declare a parameter per field of ``cls`` (nested dataclasses as ``key.field``) and
        return the values given, as a section mapping for :func:`build_section`."""
        nested = nested or {}
        hints = typing.get_type_hints(cls)
        data: dict[str, Any] = {}
        for f in dataclasses.fields(cls):
            name = f"{prefix}{f.name}"
            if f.name in nested:
                data[f.name] = self.declare_fields(nested[f.name], None, f"{name}.")
                continue
            desc = describe(spec_of(f), hints[f.name], read_only=name not in self.writable)
            default = None if f.default is dataclasses.MISSING else f.default
            value = self.declare_parameter(name, default, desc).value
            if value is None:
                continue
            data[f.name] = list(value) if isinstance(value, (list, tuple)) else value
        return data

    def section_class(self, run: RunParams) -> tuple[type, dict[str, type]]:
        """The dataclass of this node's scenario section (and its nested ones)."""
        return section_class(self.section, run.machine)

    def load_params(self) -> tuple[RunParams, Any]:
        """(shared run parameters, this node's section dataclass), validated like a scenario file."""
        where = self._where()
        run = build_section(RunParams, self.declare_fields(RunParams), {}, f"{where} (/**)")
        if not self.section:
            return run, None
        cls, nested = self.section_class(run)
        return run, build_section(cls, self.declare_fields(cls, nested), nested, where)

    def declare_switch_steps(self, what: str) -> list[int]:
        """The read-only ``switch_steps`` parameter: the steps of the launcher's scheduled
        strategy switches (``--switch``), sorted; ``what`` says what this node does at them."""
        value = self.declare_parameter(
            "switch_steps",
            None,
            ParameterDescriptor(
                description=f"steps of the launcher's scheduled strategy switches: {what}",
                read_only=True,
                dynamic_typing=True,
            ),
        ).value
        return sorted(int(k) for k in value or [])

    @property
    def peer_timeout(self) -> float:
        return self.timeouts.peer_timeout

    @property
    def startup_timeout(self) -> float:
        return self.timeouts.startup_timeout

    # -- lock-step helpers --------------------------------------------------------------------
    def publisher(self, key: str) -> Any:
        pub = raw_publisher(self, key)
        if self.bus is None:
            return pub
        per_step = key in RECORD_TOPICS or key == LOSSES_TOPIC
        return Outlet(pub, self.bus, recheck=OUTSIDE_RECHECK if per_step else 1)

    def subscription(
        self, key: str, callback: Callable[[bytes], None], *, dds: bool = False
    ) -> Any:
        """Raw (serialized) subscription; through the process's :class:`LocalBus` if it has one,
        unless ``dds`` (a topic rclpy itself publishes, such as /parameter_events)."""
        if self.bus is not None and not dds:
            self.bus.subscribe(TOPICS[key].name, callback)
            return None
        return raw_subscription(self, key, callback)

    def wait_matched(self, pub: Any, count: int, what: str) -> None:
        """Block (briefly, in a callback is fine: matching runs in DDS threads) until ``pub`` has
        ``count`` matched subscriptions, or fail after startup_timeout; a stop (SIGINT, SIGTERM:
        :data:`STOP`) ends the wait at once, the node then closing as it would anywhere."""
        deadline = time.monotonic() + self.startup_timeout
        while pub.get_subscription_count() < count and not STOP.is_set():
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


class WatchedNode(DriveNode):
    """A lock-step node that fails when the message it waits for does not come in time
    (``startup_timeout`` before its first message, ``peer_timeout`` after). Its lock-step
    publishers (``self.lockstep``) are kept until their readers have acknowledged every message
    when the run ends, so a recorder that was behind still gets them."""

    #: s this node waits beyond the peer timeout before it fails. When the loop stalls, every
    #: node waits; the one waiting on the silent peer directly must speak first and name it, so
    #: the nodes further along the loop from a controller wait longer: the plant (waits on the
    #: torque controller) 0.25 s, the speed PI (on the plant) 0.5 s, the recorder (on all) 1 s
    patience: float = 0.0
    #: s this node waits beyond the start-up timeout before it fails, until the graph has
    #: started: the plant judges start-up (it names the peers it still waits for, or the silent
    #: controller of command 0), so the others, which wait on it, give it this long besides —
    #: enough for the skew of the processes' starts
    start_patience: float = 10.0

    def __init__(self, name: str, **kw: Any) -> None:
        super().__init__(name, **kw)
        self._last_progress = time.monotonic()
        self._started = False
        self.lockstep: list[Any] = []

    def finish(self, spin: Callable[[float], None], deadline: float) -> None:
        for pub in self.lockstep:
            left = deadline - time.monotonic()
            if left > 0:
                pub.wait_for_all_acked(Duration(seconds=left))

    def progressed(self, started: bool = True) -> None:
        """A message this node waited for came. ``started=False``: one of step 0 — the graph is
        still starting until command 0 has been applied (a controller may take the start-up
        timeout for it, still discovering its peers), so the next wait is start-up too."""
        self._last_progress = time.monotonic()
        if started:
            self._started = True

    def resumed(self) -> None:
        self._last_progress = time.monotonic()

    def check(self) -> None:
        if self.finished or self.failure:
            return
        limit = self.peer_timeout if self._started else self.startup_timeout
        patience = self.patience if self._started else self.start_patience
        if time.monotonic() - self._last_progress > limit + patience:
            self.fail(
                f"{self.get_fully_qualified_name()}: {self.stalled_message()} within {limit} s"
            )

    def stalled_message(self) -> str:
        """What this node has been waiting for (names the silent peer and the topic)."""
        raise NotImplementedError


def spin_main(
    make: Callable[[LocalBus | None], list[DriveNode]],
    *,
    args: list[str] | None = None,
    bus: LocalBus | None = None,
) -> int:
    """Jazzy main pattern: init, ``make(bus)`` the nodes, spin them, close them however the run
    ends (the logger closes its bag), shut down. Returns the process exit code.

    SIGINT and SIGTERM set :data:`STOP` (rclpy's handlers are not installed): the loop ends, the
    nodes finish what is in flight (:meth:`DriveNode.finish`), close and go."""
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)

    def stop(signum: int, _frame: object) -> None:
        STOP.set(signum)  # nothing else: see StopFlag

    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, stop)
    nodes: list[DriveNode] = []
    code = 0
    ex = executor()
    try:
        nodes = make(bus)
        code = spin_nodes(nodes, ex, bus)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = 0
    except (ConfigError, GraphError) as e:
        print(f"{e}", file=sys.stderr)
        code = 2
    finally:
        with closing():
            urgent = STOP.signum == signal.SIGTERM
            deadline = time.monotonic() + (QUICK_FINISH if urgent else FINISH_TIMEOUT)
            for n in sorted(nodes, key=lambda n: not isinstance(n, WatchedNode)):
                n.finish(lambda t: _spin(ex, bus, t), deadline)
            stopped_mid_run = STOP.is_set() and not all(n.finished for n in nodes)
            if stopped_mid_run and launcher_pid():
                name = signal.Signals(STOP.signum).name
                step = max((n.last_step for n in nodes), default=-1)
                print(STOPPED_LINE.format(signal=name, step=step), file=sys.stderr, flush=True)
            for n in nodes:
                if n.failure:
                    print(n.failure, file=sys.stderr)
                close = getattr(n, "close", None)
                if close is not None:
                    close()
                n.destroy_node()
            ex.shutdown(timeout_sec=1.0)
            try_shutdown()
    return code


@contextmanager
def closing() -> Iterator[None]:
    """The process is closing: a further SIGINT/SIGTERM must not interrupt the closing of the
    bag. The launcher still escalates to SIGKILL if closing hangs; without a launcher (or with
    one that died) SIGALRM ends a close that takes longer than CLOSE_TIMEOUT. The alarm stays
    set after the block, through the process's exit (a node process only exits after it): a
    teardown of rclpy or Fast DDS that hangs at the interpreter's exit is ended too (one node,
    its launcher gone after a third Ctrl-C, sat 7 minutes in a futex there)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_IGN)
    signal.alarm(CLOSE_TIMEOUT)
    yield


#: local deliveries between executor polls (~280 steps of the drive graph; a poll costs about a
#: millisecond: at 500 the composed graph spent a tenth of its time polling)
_BATCH = 2000
#: s without a turn of the spin loop (which comes every 0.1 s at most) that mean this process
#: was stopped or starved, not that its peers were silent
RESUME_GAP = 2.0


def _spin(ex: Any, bus: LocalBus | None, timeout: float) -> None:
    """One round of the loop: local deliveries (composed), then the executor."""
    if bus is not None and bus.run(_BATCH):
        ex.spin_once(timeout_sec=0.0)
    else:
        ex.spin_once(timeout_sec=timeout)


def spin_nodes(nodes: list[DriveNode], ex: Any, bus: LocalBus | None = None) -> int:
    """Spin until every node has finished or one fails, or :data:`STOP` is set; 1 on a node
    failure, else 0 (a stop by SIGINT or SIGTERM ends a node cleanly, as ``ros2 launch`` expects
    of its nodes).

    The executor runs in C++ until a node signals (finished / failed) or 0.1 s pass; then the
    watchdogs run. Every spin has a finite timeout (see :func:`executor`). With a ``bus``, its
    queued messages are delivered in batches, the executor (parameter services, outside traffic)
    polled between them.
    """
    from rclpy.task import Future

    done = Future()

    def notify() -> None:
        if not done.done() and (any(n.failure for n in nodes) or all(n.finished for n in nodes)):
            done.set_result(True)

    for n in nodes:
        n.notify = notify
        ex.add_node(n)
    launcher = launcher_pid()
    last = time.monotonic()
    while ok() and not STOP.is_set():
        if bus is not None and bus.run(_BATCH):
            ex.spin_until_future_complete(done, timeout_sec=0.0)
        else:
            ex.spin_until_future_complete(done, timeout_sec=0.1)
        now = time.monotonic()
        if now - last > RESUME_GAP:  # this loop did not run: the process itself was held
            for n in nodes:
                n.resumed()
        last = now
        for n in nodes:
            n.check()
        if launcher and os.getppid() != launcher and not nodes[0].failure:
            nodes[0].fail(f"the launcher (pid {launcher}) is gone; ending the run")
        notify()
        if any(n.failure for n in nodes):
            return 1
        if all(n.finished for n in nodes):
            return 0
    return 0  # stopped (SIGINT / SIGTERM): a clean end, as a ROS node's


def run_main(node_cls: Callable[[], DriveNode], args: list[str] | None = None) -> int:
    """``main`` of a node process: the launcher's placement, then :func:`spin_main`."""
    if args is None:
        args = sys.argv
    os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
    apply_placement()
    return spin_main(lambda _bus: [node_cls()], args=args)
