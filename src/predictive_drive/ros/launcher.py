"""Start the drive graph as child processes, watch it, switch strategies, and end it cleanly.

Each run gets its own ROS domain (a lock file per id keeps parallel runs apart) and discovery on
localhost only. The children run in their own sessions, so a Ctrl-C reaches only this process, which
then ends every child by PID: SIGINT (the logger closes its bag), then SIGTERM, then SIGKILL.
"""

from __future__ import annotations

import re
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

from ..bag import LOGS_DIR, check_new_bag
from ..core.scenario import Scenario
from ..core.timebase import step_index
from ..errors import GraphError
from ..interface import CLOCK_PERIOD, LAUNCHER_NODE, NAMESPACE, NODES, TOPICS, node_name
from ..readback import bag_status
from .placement import CPUS_ENV, SCHED_ENV, SCHED_POLICIES, cpu_plan, ros_env
from .processes import isolated_domain, node_command, parameter_args, start_process, stop_processes

__all__ = ["START_ORDER", "run_graph"]

#: an rclpy log line: ``[ERROR] [<wall time>] [<logger>]: <message>``
_ERROR_LINE = re.compile(r"^\[(?:ERROR|FATAL)\] \[(\d+\.\d+)\] \[[^\]]*\]: (.*)$", re.MULTILINE)
#: start order: the logger first, so it listens before the plant looks for its peers
START_ORDER = ("metrics_logger", "torque_controller", "speed_pi", "plant")


def _tail(path: Path, n: int = 12) -> str:
    lines = path.read_text(errors="replace").strip().splitlines() if path.exists() else []
    return "\n".join("    " + line for line in lines[-n:])


def _first_error(path: Path) -> tuple[float, str] | None:
    """(wall time, message) of the first error a node logged, if it logged one."""
    found = _ERROR_LINE.search(path.read_text(errors="replace")) if path.exists() else None
    return (float(found.group(1)), found.group(2)) if found else None


def run_graph(
    sc: Scenario,
    bag: Path,
    *,
    composed: bool = False,
    switches: Sequence[tuple[float, str]] = (),
    progress: Callable[[int], None] | None = None,
    peer_timeout: float = 10.0,
    affinity: str = "paired",
    sched: str = "batch",
    live_port: int = 0,
) -> None:
    """Run ``sc`` through the graph and record it to ``bag``; with ``live_port``, the logger
    also serves the live view there (:class:`~predictive_drive.live.LiveView`); GraphError names the node that
    failed first and says what state the bag is in. The node logs stay with the bag
    (``<bag>/logs/``). ``affinity`` places the separate node processes on CPUs (see
    :func:`cpu_plan`) and ``sched`` is their threads' scheduling policy
    (:data:`SCHED_POLICIES`); the composed engine runs in one process and is left as it is."""
    if sched not in SCHED_POLICIES:
        raise GraphError(f"--sched: {sched!r} is not one of {', '.join(SCHED_POLICIES)}")
    bag = check_new_bag(bag).resolve()
    source = str(Path(sc.source).resolve())
    shared = {"duration": sc.run.duration, "peer_timeout": peer_timeout}
    overrides: dict[str, dict[str, Any]] = {node_name(n): dict(shared) for n in NODES}
    overrides[node_name("torque_controller")]["strategy"] = sc.strategy
    overrides[node_name("metrics_logger")].update(
        strategy=sc.strategy,
        bag=str(bag),
        scenario_file=source,
        engine="composed" if composed else "ros",
        live_port=live_port,
    )
    # the launcher follows /clock for progress and switches: step 0 waits for it too
    watching = bool(switches) or progress is not None
    overrides[node_name("plant")]["await_launcher"] = watching
    if switches:  # each lands exactly at its step: the plant waits there for the controller
        steps = sorted(step_index(t, sc.ts) for t, _ in switches)
        for n in ("plant", "torque_controller"):
            overrides[node_name(n)]["switch_steps"] = list(steps)
    logs = bag / LOGS_DIR
    logs.mkdir(parents=True, exist_ok=True)
    args = parameter_args(source, overrides, logs)
    with isolated_domain() as domain:
        env = ros_env(domain)
        plan = {} if composed else cpu_plan(affinity)
        if not composed:
            env[SCHED_ENV] = sched
        procs: dict[str, subprocess.Popen[bytes]] = {}
        # the launcher's own node: the plant waits for its /clock subscription before step 0
        watcher = _ClockWatcher(domain, sc, switches, progress) if watching else None
        modules = {"composed": "composed"} if composed else {n: f"{n}_node" for n in START_ORDER}
        try:
            for name, module in modules.items():
                procs[name] = start_process(
                    [*node_command(module), *args],
                    log=logs / f"{name}.log",
                    env={**env, CPUS_ENV: plan[name]} if name in plan else env,
                )
            print(
                f"predictive-drive: graph on ROS_DOMAIN_ID={domain}: "
                + ", ".join(
                    f"{n} pid {p.pid}" + (f" cpu {plan[n]}" if n in plan else "")
                    for n, p in procs.items()
                )
                + ("" if composed else f"; sched {sched}"),
                file=sys.stderr,
                flush=True,
            )
            _watch(procs, logs, watcher, bag)
        finally:
            stop_processes(procs)
            if watcher is not None:
                watcher.close()


def _watch(
    procs: dict[str, subprocess.Popen[bytes]],
    logs: Path,
    watcher: _ClockWatcher | None,
    bag: Path,
) -> None:
    """Wait for the children; follow /clock for progress and timed strategy switches. When one
    fails, stop the others (they finish what is in flight and the logger closes the bag), then
    report the node whose error came first in time, and the bag's state."""
    while True:
        if watcher is not None:
            watcher.spin(0.05)
        else:
            time.sleep(0.05)
        codes = {n: p.poll() for n, p in procs.items()}
        failed = {n for n, c in codes.items() if c not in (None, 0)}
        if failed:
            seen = time.time()
            stop_processes(procs)
            raise GraphError(_failure_report(procs, logs, bag, seen, failed))
        if all(c == 0 for c in codes.values()):
            if watcher is not None and (errors := watcher.final_errors()):
                raise GraphError("; ".join(errors))
            return


def _failure_report(
    procs: dict[str, subprocess.Popen[bytes]],
    logs: Path,
    bag: Path,
    seen: float,
    failed: set[str],
) -> str:
    """Who failed first, how each ended, what it said, and the bag's state. A node failed when it
    had ended (``failed``) or logged an error before the launcher saw the first end (``seen``,
    wall time); the first is the one whose error came first, a node that ended without a word
    counting as of ``seen``."""
    ends = {}
    for name, p in procs.items():
        code = p.returncode
        if code in (None, 0):
            continue
        err = _first_error(logs / f"{name}.log")
        when = err[0] if err else seen
        if name in failed or when < seen:
            ends[name] = (when, code)
    first = min(ends, key=lambda n: ends[n][0])
    code = ends[first][1]
    how = f"was killed by signal {-code}" if code < 0 else f"exited with status {code}"
    others = ", ".join(
        f"{n} {'killed by signal ' + str(-c) if c < 0 else 'status ' + str(c)}"
        for n, p in procs.items()
        if n != first and (c := p.returncode) not in (None, 0)
    )
    lines = [
        f"node {first} (pid {procs[first].pid}) failed first: it {how}; the run was stopped"
        + (f" (then: {others})" if others else ""),
        bag_status(bag).describe() + f"; node logs in {logs}",
        f"  {first} said:",
        _tail(logs / f"{first}.log"),
    ]
    return "\n".join(lines)


class _ClockWatcher:
    """A small node of the launcher's own: /clock → progress, and parameter-service switches.

    Switches go out one at a time, in order, each once /clock is within one tick of its time
    (the plant and the controller hold it to its exact step, see ``switch_steps``); a request
    unanswered after :data:`~.params.RESEND_AFTER` s is sent again (a request made just after
    discovery can be lost), and the next switch waits for the answer to the one before, so a
    late answer can never undo a later switch."""

    def __init__(
        self,
        domain: int,
        sc: Scenario,
        switches: Sequence[tuple[float, str]],
        progress: Callable[[int], None] | None,
    ) -> None:
        from rclpy.parameter_client import AsyncParameterClient

        from .transport import ros_session

        self._session = ros_session(LAUNCHER_NODE, domain=domain, namespace=NAMESPACE)
        self.node, self.ex = self._session.__enter__()
        self.ts = sc.ts
        self.progress = progress
        self.pending = sorted(switches)
        self.switch_errors: list[str] = []
        self._inflight: tuple[str, str, Any, float] | None = None  # what, strategy, future, sent
        self._sim_time = -1.0
        self.client = AsyncParameterClient(self.node, node_name("torque_controller"))
        self._clock_sub: Any = None  # see spin()

    def _follow_clock(self) -> None:
        from rosgraph_msgs.msg import Clock

        from .transport import qos

        self._clock_sub = self.node.create_subscription(
            Clock, TOPICS["clock"].name, self.on_clock, qos(TOPICS["clock"].qos)
        )

    def on_clock(self, msg: Any) -> None:
        t = msg.clock.sec + msg.clock.nanosec * 1e-9
        self._sim_time = t
        if self.progress is not None:
            self.progress(round(t / self.ts))
        self._send()

    def _request(self, what: str, name: str) -> None:
        from rclpy.parameter import Parameter

        fut = self.client.set_parameters([Parameter("strategy", Parameter.Type.STRING, name)])
        self._inflight = (what, name, fut, time.monotonic())

    def _send(self) -> None:
        # the plant waits at the switch's step for it, so the last /clock before that step
        # (one CLOCK_PERIOD before it at most) may be all there is to see
        if (
            self._inflight is None
            and self.pending
            and self.pending[0][0] - CLOCK_PERIOD <= self._sim_time + 1e-12
        ):
            at, name = self.pending.pop(0)
            self._request(f"switch at {at} s to {name}", name)

    def spin(self, timeout: float) -> None:
        from .params import RESEND_AFTER

        # /clock only once a timed switch can go out at once: the plant holds step 0 until then
        if self._clock_sub is None and (not self.pending or self.client.services_are_ready()):
            self._follow_clock()
        self.ex.spin_once(timeout_sec=timeout)
        if self._inflight is not None:
            what, name, fut, sent = self._inflight
            if fut.done():
                self._inflight = None
                for r in getattr(fut.result(), "results", []):
                    if not r.successful:
                        self.switch_errors.append(f"{what} rejected: {r.reason}")
            elif time.monotonic() - sent > RESEND_AFTER:
                self._request(what, name)  # the same value again: setting it twice is harmless
        self._send()

    def final_errors(self) -> list[str]:
        """After the run: rejected switches, and switches unanswered or never sent."""
        self.spin(0.0)  # a last answer may be waiting
        unanswered = [] if self._inflight is None else [self._inflight[0]]
        return (
            self.switch_errors
            + [
                f"{what}: no answer from {node_name('torque_controller')} before the run ended"
                for what in unanswered
            ]
            + [f"switch at {at} s to {name}: never sent" for at, name in self.pending]
        )

    def close(self) -> None:
        self._session.__exit__(None, None, None)
