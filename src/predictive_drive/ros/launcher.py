"""Start the drive graph as child processes, watch it, switch strategies, and end it cleanly.

Each run gets its own ROS domain (a lock file per id keeps parallel runs apart) and discovery on
localhost only. The children run in their own sessions, so a Ctrl-C reaches only this process, which
then ends every child by PID: SIGINT (the logger closes its bag), then SIGTERM, then SIGKILL.
"""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from pathlib import Path
from typing import IO, Any

from ..core.scenario import Scenario
from ..errors import GraphError
from ..interface import LAUNCHER_NODE, NAMESPACE, NODES, TOPICS, node_name
from .placement import CPUS_ENV, SCHED_ENV, SCHED_POLICIES, cpu_plan, ros_env

__all__ = ["isolated_domain", "run_graph", "stop_processes"]

#: start order: the logger first, so it listens before the plant looks for its peers
START_ORDER = ("metrics_logger", "torque_controller", "speed_pi", "plant")
DOMAIN_RANGE = range(1, 101)  # 101..232 left to tests and users
LOCK_DIR = Path(tempfile.gettempdir()) / "predictive_drive_domains"


@contextmanager
def isolated_domain() -> Iterator[int]:
    """A ROS_DOMAIN_ID no other predictive_drive run on this machine holds (flock'ed)."""
    LOCK_DIR.mkdir(exist_ok=True)
    start = os.getpid() % len(DOMAIN_RANGE)
    for i in range(len(DOMAIN_RANGE)):
        d = DOMAIN_RANGE[(start + i) % len(DOMAIN_RANGE)]
        f = (LOCK_DIR / f"{d}.lock").open("w")
        try:
            fcntl.flock(f, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            f.close()
            continue
        try:
            yield d
        finally:
            fcntl.flock(f, fcntl.LOCK_UN)
            f.close()
        return
    raise GraphError("no free ROS domain id: 100 predictive_drive runs at once?")


def stop_processes(procs: dict[str, subprocess.Popen[bytes]], *, grace: float = 5.0) -> None:
    """End every still-running child by PID: SIGINT, then SIGTERM, then SIGKILL, each with a timeout."""
    for sig, wait in ((signal.SIGINT, grace), (signal.SIGTERM, 2.0), (signal.SIGKILL, 5.0)):
        alive = [p for p in procs.values() if p.poll() is None]
        if not alive:
            return
        for p in alive:
            try:
                os.kill(p.pid, sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + wait
        for p in alive:
            try:
                p.wait(timeout=max(0.0, deadline - time.monotonic()))
            except subprocess.TimeoutExpired:
                pass


def _tail(f: IO[bytes], n: int = 12) -> str:
    f.flush()
    f.seek(0)
    lines = f.read().decode(errors="replace").strip().splitlines()
    return "\n".join("    " + line for line in lines[-n:])


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
) -> None:
    """Run ``sc`` through the graph and record it to ``bag``; GraphError names a failed node.
    ``affinity`` places the separate node processes on CPUs (see :func:`cpu_plan`) and ``sched``
    is their threads' scheduling policy (:data:`SCHED_POLICIES`); the composed engine runs in
    this process and is left as it is."""
    if sched not in SCHED_POLICIES:
        raise GraphError(f"--sched: {sched!r} is not one of {', '.join(SCHED_POLICIES)}")
    source = str(Path(sc.source).resolve())
    shared = {"duration": sc.run.duration, "peer_timeout": peer_timeout}
    # node-specific entries beat wildcard ones and later files beat earlier ones, so the command
    # line's overrides go into a second parameter file with one section per node
    overrides = {node_name(n): {"ros__parameters": dict(shared)} for n in NODES}
    overrides[node_name("torque_controller")]["ros__parameters"]["strategy"] = sc.strategy
    overrides[node_name("metrics_logger")]["ros__parameters"].update(
        strategy=sc.strategy, bag=str(bag.resolve()), scenario_file=source
    )
    # the launcher follows /clock for progress and switches: step 0 waits for it too
    watching = bool(switches) or progress is not None
    overrides[node_name("plant")]["ros__parameters"]["await_launcher"] = watching
    with isolated_domain() as domain, tempfile.TemporaryDirectory() as logs:
        import yaml

        override_file = Path(logs) / "overrides.yaml"
        override_file.write_text(yaml.safe_dump(overrides))
        args = ["--ros-args", "--params-file", source, "--params-file", str(override_file)]
        env = ros_env(domain)
        plan = {} if composed else cpu_plan(affinity)
        if not composed:
            env[SCHED_ENV] = sched
        procs: dict[str, subprocess.Popen[bytes]] = {}
        outs: dict[str, IO[bytes]] = {}
        # the launcher's own node: the plant waits for its /clock subscription before step 0
        watcher = _ClockWatcher(domain, sc, switches, progress) if watching else None
        commands = (
            {"composed": ["predictive_drive.ros.composed", *args]}
            if composed
            else {n: [f"predictive_drive.ros.{n}_node", *args] for n in START_ORDER}
        )
        try:
            for name, cmd in commands.items():
                outs[name] = open(Path(logs) / f"{name}.log", "w+b")  # noqa: SIM115
                procs[name] = subprocess.Popen(
                    [sys.executable, "-m", *cmd],
                    env={**env, CPUS_ENV: plan[name]} if name in plan else env,
                    stdout=outs[name],
                    stderr=subprocess.STDOUT,
                    stdin=subprocess.DEVNULL,
                    start_new_session=True,
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
            _watch(procs, outs, watcher)
        finally:
            stop_processes(procs)
            if watcher is not None:
                watcher.close()
            for f in outs.values():
                f.close()


def _watch(
    procs: dict[str, subprocess.Popen[bytes]],
    outs: dict[str, IO[bytes]],
    watcher: _ClockWatcher | None,
) -> None:
    """Wait for the children; follow /clock for progress and timed strategy switches."""
    while True:
        if watcher is not None:
            watcher.spin(0.05)
        else:
            time.sleep(0.05)
        codes = {n: p.poll() for n, p in procs.items()}
        failed = {n: c for n, c in codes.items() if c not in (None, 0)}
        if failed:
            name, code = next(iter(failed.items()))
            how = f"was killed by signal {-code}" if code < 0 else f"exited with status {code}"
            stop_processes(procs)
            raise GraphError(
                f"node {name} (pid {procs[name].pid}) {how}; the run was stopped and the bag "
                f"closed.\n  {name} said:\n{_tail(outs[name])}"
            )
        if all(c == 0 for c in codes.values()):
            if watcher is not None and (errors := watcher.final_errors()):
                raise GraphError("; ".join(errors))
            return


class _ClockWatcher:
    """A small node of the launcher's own: /clock → progress, and parameter-service switches."""

    def __init__(
        self,
        domain: int,
        sc: Scenario,
        switches: Sequence[tuple[float, str]],
        progress: Callable[[int], None] | None,
    ) -> None:
        import rclpy
        from rclpy.context import Context
        from rclpy.parameter_client import AsyncParameterClient

        from .transport import executor

        self.ctx = Context()
        rclpy.init(context=self.ctx, domain_id=domain)
        self.node = rclpy.create_node(LAUNCHER_NODE, namespace=NAMESPACE, context=self.ctx)
        self.ex = executor(self.ctx)
        self.ex.add_node(self.node)
        self.ts = sc.ts
        self.progress = progress
        self.pending = sorted(switches)
        self.switch_errors: list[str] = []
        self._futures: list[tuple[str, Any]] = []
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
        if self.progress is not None:
            self.progress(round(t / self.ts))
        while self.pending and self.pending[0][0] <= t:
            at, name = self.pending.pop(0)
            from rclpy.parameter import Parameter

            fut = self.client.set_parameters([Parameter("strategy", Parameter.Type.STRING, name)])
            self._futures.append((f"switch at {at} s to {name}", fut))

    def spin(self, timeout: float) -> None:
        # /clock only once a timed switch can go out at once: the plant holds step 0 until then
        if self._clock_sub is None and (not self.pending or self.client.services_are_ready()):
            self._follow_clock()
        self.ex.spin_once(timeout_sec=timeout)
        for what, fut in list(self._futures):
            if fut.done():
                self._futures.remove((what, fut))
                res = fut.result()
                for r in getattr(res, "results", []):
                    if not r.successful:
                        self.switch_errors.append(f"{what} rejected: {r.reason}")

    def final_errors(self) -> list[str]:
        """After the run: rejected switches, and switches unanswered or never sent."""
        self.spin(0.0)  # a last answer may be waiting
        return (
            self.switch_errors
            + [
                f"{what}: no answer from {node_name('torque_controller')} before the run ended"
                for what, _ in self._futures
            ]
            + [f"switch at {at} s to {name}: never sent" for at, name in self.pending]
        )

    def close(self) -> None:
        import rclpy

        self.ex.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)
