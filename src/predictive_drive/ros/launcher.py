"""Start the drive graph as child processes, watch it, switch strategies, and end it cleanly.

Each run gets its own ROS domain (a lock file per id keeps parallel runs apart) and discovery on
localhost only. The children run in their own sessions, so a Ctrl-C reaches only this process, which
then ends every child by PID: SIGINT (the logger closes its bag), then SIGTERM, then SIGKILL.
"""

from __future__ import annotations

import json
import re
import shlex
import subprocess
import sys
import time
from collections import deque
from collections.abc import Callable, Collection, Mapping, Sequence
from pathlib import Path
from typing import Any

from ..bag import LOGS_DIR, check_new_bag
from ..core.control.base import parse_switch
from ..core.scenario import Scenario
from ..core.timebase import step_index
from ..errors import GraphError, Interrupted
from ..interface import CLOCK_PERIOD, LAUNCHER_NODE, NAMESPACE, NODES, TOPICS, node_name
from ..readback import BagStatus, bag_status
from .placement import (
    CPUS_ENV,
    SCHED_ENV,
    SCHED_POLICIES,
    cpu_plan,
    ros_env,
    write_stop_reason,
)
from .processes import (
    AGAIN,
    SharedMemory,
    command_line,
    cpu_state,
    end_own_nodes,
    ended_how,
    ending_with_this_process,
    is_stopped,
    isolated_domain,
    node_command,
    parameter_args,
    start_process,
    stop_processes,
)

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
    external: Mapping[str, str | None] | None = None,
    startup_timeout: float = 60.0,
    label: str | None = None,
) -> None:
    """Run ``sc`` through the graph and record it to ``bag``; with ``live_port``, the logger
    also serves the live view there (:class:`~predictive_drive.live.LiveView`); GraphError names the node that
    failed first and says what state the bag is in. The node logs stay with the bag
    (``<bag>/logs/``). ``affinity`` places the separate node processes on CPUs (see
    :func:`cpu_plan`) and ``sched`` is their threads' scheduling policy
    (:data:`SCHED_POLICIES`); the composed engine runs in one process and is left as it is.
    ``external``: nodes of the user's own in place of ours (docs/ros.md#writing-your-own-controller),
    by name: a command line the launcher starts (with ``--ros-args``, the node's name, namespace
    and parameter files appended) and owns like its own nodes, or None for a node the user starts
    by hand (the launcher says how, and the graph waits ``startup_timeout`` s for it as for any
    node)."""
    external = dict(external or {})
    if sched not in SCHED_POLICIES:
        raise GraphError(f"--sched: {sched!r} is not one of {', '.join(SCHED_POLICIES)}")
    bag = check_new_bag(bag, claimed=True).resolve()  # the caller claimed it
    source = str(Path(sc.source).resolve())
    shared = {
        "duration": sc.run.duration,
        "peer_timeout": peer_timeout,
        "startup_timeout": startup_timeout,
    }
    overrides: dict[str, dict[str, Any]] = {node_name(n): dict(shared) for n in NODES}
    if "torque_controller" not in external:
        overrides[node_name("torque_controller")]["strategy"] = sc.strategy
    else:  # the contract's parameter (ours declares it with this default)
        overrides[node_name("torque_controller")]["command_readers"] = 2
    overrides[node_name("metrics_logger")].update(
        strategy=sc.strategy,
        bag=str(bag),
        scenario_file=source,
        engine="composed" if composed else "ros",
        live_port=live_port,
        external=json.dumps(external) if external else "",  # for the bag's metadata
        label=label or "",
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
        env = ros_env(domain, log_dir=logs)
        plan = {} if composed else cpu_plan(affinity)
        if not composed:
            env[SCHED_ENV] = sched
        procs: dict[str, subprocess.Popen[bytes]] = {}
        # the launcher's own node: the plant waits for its /clock subscription before step 0
        watcher = _ClockWatcher(domain, sc, switches, progress, logs) if watching else None
        modules = {"composed": "composed"} if composed else {n: f"{n}_node" for n in START_ORDER}
        children = _Children(procs, logs, own=[n for n, c in external.items() if c is not None])
        try:
            for name, module in modules.items():
                if name in external:
                    command = external[name]
                    if command is None:
                        _say_how_to_start(name, domain, args, startup_timeout)
                        continue
                    own = ["-r", f"__node:={name}", "-r", f"__ns:={NAMESPACE}"]
                    # a user's node cannot watch the launcher as ours do: it ends with it
                    words = command_line(command, option=f"--external {name}=")
                    procs[name] = start_process(
                        ending_with_this_process([*words, *args, *own]),
                        log=logs / f"{name}.log",
                        env={**env, CPUS_ENV: plan[name]} if name in plan else env,
                    )
                    continue
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
            _watch(children, watcher, bag, sc.run.steps, peer_timeout)
        except KeyboardInterrupt:
            write_stop_reason(logs, "interrupted (Ctrl-C)")
            # each line is printed once further presses are counted: a press that answers it
            # is acted on, never raised in the instant before the stop takes presses over
            try:
                left = stop_processes(
                    procs,
                    announce="predictive-drive: interrupted: the nodes finish what is in flight "
                    "and the bag closes (Ctrl-C again to have them finish quickly)",
                )
            except KeyboardInterrupt:  # pressed twice before the stop took presses over
                left = stop_processes(procs, urgent=True, announce=AGAIN)
            children.abandoned = bool(left)
            raise Interrupted(_interrupted_report(children, bag, left, sc.run.steps)) from None
        finally:
            if not children.abandoned:  # a repeated Ctrl-C leaves them to close on their own
                stop_processes(procs)  # none left after a clean end or a failure
            if watcher is not None:  # first: its participant maps the nodes' ports too
                watcher.close()
            children.shm.clean()


def _say_how_to_start(name: str, domain: int, args: list[str], limit: float) -> None:
    """How to start a node of the user's own by hand into this run's graph, and how long the
    graph waits for it."""
    print(
        f"predictive-drive: waiting for your {node_name(name)} (up to {limit:g} s; "
        f"--startup-timeout S changes it): start it (from another shell) with "
        f"ROS_DOMAIN_ID={domain} ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST and the arguments\n"
        f"  {shlex.join([*args, '-r', f'__node:={name}', '-r', f'__ns:={NAMESPACE}'])}",
        file=sys.stderr,
        flush=True,
    )


#: a node's log line saying a signal stopped it mid-run (node_base.STOPPED_LINE)
_STOPPED_LINE = re.compile(r"^stopped by (SIG\w+) at step (-?\d+)$", re.MULTILINE)
#: s a stop (SIGSTOP, a debugger) must last to be named as the reason a run failed, and how long
#: after it ended it still counts
STOP_BLAME = (1.0, 30.0)
#: s the plant may take to end after a node of the user's own exited 0 (it does at once after
#: the run's last state) before that node is said to have left before its last message
OWN_EXIT_GRACE = 3.0
#: s between the launcher's looks at its children's CPU time and state
CPU_LOOK = 0.25


class _Children:
    """The launcher's view of its node processes: how each ended, which were stopped by a signal
    (SIGSTOP, a debugger) and when, and the shared memory they use (see :class:`SharedMemory`)."""

    def __init__(
        self, procs: dict[str, subprocess.Popen[bytes]], logs: Path, own: Collection[str] = ()
    ) -> None:
        self.procs = procs
        self.logs = logs
        self.own = frozenset(own)  #: the user's nodes this launcher started (``--external``)
        self._own_exit: dict[str, float] = {}  #: when each was seen to exit 0, time.monotonic()
        self.shm = SharedMemory()
        self._stopped_since: dict[str, float] = {}
        self.stops: dict[str, list[tuple[float, float]]] = {}  #: (from, to), time.monotonic()
        self._sample_at = 0.0
        self.abandoned = False  #: a repeated Ctrl-C left children to close on their own
        #: each child's CPU time and whether it was running, looked at every CPU_LOOK s over the
        #: last minute: (time.monotonic(), s of CPU, running) (a node named silent that was
        #: computing the whole time is busy, not hung)
        self.cpu: dict[str, deque[tuple[float, float, bool]]] = {}
        self._cpu_at = 0.0

    def tick(self) -> None:
        """Look at every child once (the watch loop's period)."""
        now = time.monotonic()
        for name in self.own:
            if self.procs[name].poll() == 0:
                self._own_exit.setdefault(name, now)
        for name, p in self.procs.items():
            if p.poll() is None and is_stopped(p.pid):
                self._stopped_since.setdefault(name, now)
            elif name in self._stopped_since:
                self.stops.setdefault(name, []).append((self._stopped_since.pop(name), now))
        if now >= self._sample_at:  # the files a node uses are made at start-up, mostly
            self.shm.sample([p.pid for p in self.procs.values() if p.poll() is None])
            self._sample_at = now + 1.0
        if now >= self._cpu_at:
            for name, p in self.procs.items():
                look = cpu_state(p.pid) if p.poll() is None else None
                if look is not None:
                    kept = self.cpu.setdefault(name, deque(maxlen=round(60 / CPU_LOOK)))
                    kept.append((now, *look))
            self._cpu_at = now + CPU_LOOK

    def busy(self, name: str, span: float) -> tuple[float, float, float] | None:
        """(CPU s, wall s, share of looks it was running) of node ``name`` over about the last
        ``span`` s, where it was computing most of that time: running (or waiting for a CPU)
        at half the looks or more, or using half a CPU or more (None: it waited, idle, or was
        not looked at long enough)."""
        looks = [x for x in self.cpu.get(name, ()) if x[0] >= time.monotonic() - span - CPU_LOOK]
        if len(looks) < 2:
            return None
        wall, used = looks[-1][0] - looks[0][0], looks[-1][1] - looks[0][1]
        running = sum(r for _, _, r in looks) / len(looks)
        busy = wall >= 1.0 and (running >= 0.5 or used >= 0.5 * wall)
        return (used, wall, running) if busy else None

    def stopped(self) -> dict[str, float]:
        """Children stopped (by SIGSTOP, a debugger) long enough, recently enough, to have made
        their peers time out: name → how long (s)."""
        now = time.monotonic()
        out: dict[str, float] = {}
        for name in self.procs:
            spans = list(self.stops.get(name, ()))
            if name in self._stopped_since:
                spans.append((self._stopped_since[name], now))
            for start, end in spans:
                if end - start >= STOP_BLAME[0] and now - end <= STOP_BLAME[1]:
                    out[name] = max(out.get(name, 0.0), end - start)
        return out

    def log(self, name: str) -> Path:
        return self.logs / f"{name}.log"

    def stopped_by_signal(self, name: str) -> tuple[str, int] | None:
        """(signal, step) when the node says a signal stopped it mid-run (it closed cleanly)."""
        path = self.log(name)
        found = _STOPPED_LINE.search(path.read_text(errors="replace")) if path.exists() else None
        return (found.group(1), int(found.group(2))) if found else None

    def own_exited_early(self) -> set[str]:
        """The user's nodes that exited with status 0 while the run goes on: the plant still
        runs :data:`OWN_EXIT_GRACE` s later (it ends right after the run's last state). The
        contract has a node exit 0 after its last message; one that does so before is named at
        once, not by its peers' time-out."""
        now = time.monotonic()
        plant_runs = self.procs["plant"].poll() is None if "plant" in self.procs else False
        return {n for n, t in self._own_exit.items() if plant_runs and now - t > OWN_EXIT_GRACE}

    def ended_early(self) -> set[str]:
        """Children that ended the run before it was done: failed, killed, or stopped by a
        signal from outside (a child that finished the run exits 0 without a word)."""
        return {
            n
            for n, p in self.procs.items()
            if (c := p.poll()) is not None and (c != 0 or self.stopped_by_signal(n) is not None)
        }


def _watch(
    children: _Children,
    watcher: _ClockWatcher | None,
    bag: Path,
    planned: int,
    peer_timeout: float = 10.0,
) -> None:
    """Wait for the children; follow /clock for progress and timed strategy switches. When one
    ends the run early (it failed, was killed, was stopped from outside, or is the user's and
    exited before its last message), say why to the recorder (:func:`~.placement.stop_reason`),
    stop the others (the logger takes what is in flight and closes the bag), then report why
    the run ended and the bag's state. Once this package's nodes have finished the run, a node
    of the user's own that lingers is ended (:func:`~.processes.end_own_nodes`)."""
    procs = children.procs
    ours = [p for n, p in procs.items() if n not in children.own]
    while True:
        if watcher is not None:
            watcher.spin(0.05)
        else:
            time.sleep(0.05)
        children.tick()
        early = children.ended_early()
        if all(p.poll() == 0 for p in ours) and not (early - children.own):
            lingering = {n: procs[n] for n in children.own if procs[n].poll() is None}
            end_own_nodes(lingering, after="the run's last step")
            if watcher is not None and (errors := watcher.final_errors()):
                raise GraphError("; ".join(errors))
            return
        own_early = children.own_exited_early() - early
        if early or own_early:
            seen = time.time()
            why, how, name = _cause(children, seen, early, own_early)
            why += _busy_note(children, why, peer_timeout)
            write_stop_reason(children.logs, why)
            # a child killed outright never acknowledges what its peers sent it, nor does one
            # that left before its last message, nor a user's node that failed (it may have
            # left without closing its participant, os._exit or a crash: its readers stay
            # matched until Fast DDS's lease runs out, 20 s, and the peers' waits for their
            # acknowledgements held the stop that long): they are told to finish quickly
            # (SIGTERM). One of ours that failed left the graph cleanly: they finish as usual,
            # so a recorder that was only slow gets everything
            killed = any(p.returncode is not None and p.returncode < 0 for p in procs.values())
            stop_processes(procs, urgent=killed or bool(own_early) or bool(early & children.own))
            status = bag_status(bag)
            if own_early and not early and status.steps >= planned:
                return  # it had sent its last message after all: the run is whole
            if name in own_early:  # now the step is known: what the bag holds
                last = planned - 1 if name == "torque_controller" else planned
                what = "command" if name == "torque_controller" else "reference"
                why = (
                    f"your {name} (pid {procs[name].pid}) exited with status 0 at step "
                    f"{status.steps}, before its last {what} (step {last})"
                )
            cause = f"{why}; the run was stopped" + (f" ({how})" if how else "")
            raise GraphError(_failure_report(children, status, cause, name))


def _busy_note(children: _Children, why: str, peer_timeout: float) -> str:
    """Where ``why`` names a node that did not answer in time (``no /drive/command for step K
    from /drive/torque_controller``) and that node was computing all that while: say it was
    busy, not hung, and how to give it longer ('' otherwise)."""
    named = re.search(r"^\S+: no \S+ for step \d+ from /\S+/(\w+)", why)
    if named is None or named[1] not in children.procs:
        return ""
    busy = children.busy(named[1], peer_timeout)
    if busy is None:
        return ""
    used, wall, running = busy
    pid = children.procs[named[1]].pid
    return (
        f"; {named[1]} (pid {pid}) was busy, not hung: computing at {100 * running:.0f} % of "
        f"the launcher's looks over the last {wall:.1f} s, {used:.1f} s of CPU (a step that "
        f"long: --peer-timeout S waits longer)"
    )


def _cause(
    children: _Children, seen: float, early: set[str], own_early: set[str]
) -> tuple[str, str, str]:
    """Why the run ended, in one line (what the bag's outcome says too), how the node to
    blame ended ('' where the line says it), and that node (whose log tail the report shows).

    The cause, in this order: a node stopped by SIGSTOP (or a debugger) long enough for its
    peers to time out; a node stopped from outside by SIGINT / SIGTERM (it closed cleanly); a
    node killed or failed; a node of the user's own that exited 0 before its last message.
    Among failed nodes the first is the one whose error came first (a node that logged an error
    before the launcher saw the first end, ``seen`` in wall time, counts; a node that ended
    without a word counts as of ``seen``); its own message is the headline, since it says what
    went wrong and where (a refused command: the plant, the field and the step)."""
    procs = children.procs
    stopped = children.stopped()
    outside = {n: s for n in early if (s := children.stopped_by_signal(n)) is not None}
    ends: dict[str, float] = {}
    said: dict[str, str] = {}
    for name, p in procs.items():
        code = p.poll()
        if code == 0:
            continue
        err = _first_error(children.log(name))
        if err is not None:
            said[name] = err[1]
        when = err[0] if err else seen
        if name in early or (err is not None and when < seen):
            ends[name] = when
    failed_first = min(ends, key=lambda n: ends[n]) if ends else None
    if stopped:
        name = max(stopped, key=lambda n: stopped[n])
        why = (
            f"node {name} (pid {procs[name].pid}) was stopped by a signal (SIGSTOP, or a "
            f"debugger) for {stopped[name]:.1f} s"
        )
        if failed_first not in (None, name):
            why += f"; {failed_first} timed out waiting for it"
        return why, "", failed_first or name
    if outside:
        name = min(outside, key=lambda n: outside[n][1])
        sig, step = outside[name]
        why = (
            f"node {name} (pid {procs[name].pid}) was stopped from outside by {sig} at step "
            f"{step} (it closed cleanly)"
        )
        return why, "", name
    if failed_first is not None:
        name = failed_first
        pid, how = procs[name].pid, ended_how(procs[name].poll())
        if name in said:
            return said[name], f"{name}, pid {pid}, {how}", name
        return f"node {name} (pid {pid}) {how}", "", name
    name = min(own_early)
    return (
        f"your {name} (pid {procs[name].pid}) exited with status 0 before its last message",
        "",
        name,
    )


def _failure_report(children: _Children, status: BagStatus, cause: str, blame: str) -> str:
    """The cause (see :func:`_cause`), the nodes that ended badly after it, the bag's state, and
    what the node to blame said last."""
    others = ", ".join(
        f"{n} {ended_how(p.returncode)}"
        for n, p in children.procs.items()
        if n != blame and p.returncode not in (None, 0)
    )
    return "\n".join(
        [
            cause + (f" (then: {others})" if others else ""),
            status.describe() + f"; node logs in {children.logs}",
            f"  {blame} said:",
            _tail(children.log(blame)) or "    (nothing)",
        ]
    )


def _interrupted_report(children: _Children, bag: Path, left: list[str], planned: int) -> str:
    """What is true when an interrupted run's command exits: the bag's state, or — when a
    repeated Ctrl-C left the nodes to finish on their own — who is still closing it."""
    if "metrics_logger" in left or "composed" in left:
        name = "metrics_logger" if "metrics_logger" in left else "composed"
        status = bag_status(bag)
        so_far = f"{status.steps} steps so far" if status.readable else "no whole step yet"
        return (
            f"interrupted: {name} (pid {children.procs[name].pid}) is still closing the bag "
            f"{bag} ({so_far}, of {planned} planned); it is complete when that process ends "
            f"(on its own, within a minute); node logs in {children.logs}"
        )
    return f"interrupted: {bag_status(bag).describe()} (of {planned} planned)"


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
        logs: Path,
    ) -> None:
        from rclpy.parameter_client import AsyncParameterClient

        from .transport import ros_session

        self._session = ros_session(LAUNCHER_NODE, domain=domain, namespace=NAMESPACE, log_dir=logs)
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

        key, value = parse_switch(name)  # a strategy, or horizon=N
        fut = self.client.set_parameters([Parameter(key, value=value)])
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
        from .transport import spin_once

        # /clock only once a timed switch can go out at once: the plant holds step 0 until then
        if self._clock_sub is None and (not self.pending or self.client.services_are_ready()):
            self._follow_clock()
        spin_once(self.ex, timeout)  # a Ctrl-C raised when it returns: not in the drawing
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
