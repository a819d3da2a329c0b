"""Lock-step replay into a controller node (``predictive-drive replay BAG --into
torque_controller``): what rosbag2 cannot do. A torque controller node process runs the recorded
scenario; this process plays plant and speed loop for it from the recording, one step at a time
(state k and reference k out, then wait for command k), and records a new bag: the recorded
states, references and tool topics with the new commands.

The controller's own estimate follows its own commands, as in the running drive: the induction
motor's flux estimate integrates the voltage *it* applied. Replayed into the strategy that made
the recording, every command comes out as recorded. Replayed into another, the states are still
those the recorded commands produced, so the new strategy answers a drive it does not steer:
an open-loop what-if, whose flux estimate drifts from the recorded plant's flux as its commands
differ — read its agreement as "what it would have decided here", not as a closed-loop run.
"""

from __future__ import annotations

import dataclasses
import math
import subprocess
import time
from collections.abc import Callable
from dataclasses import dataclass
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from ..bag import LOGS_DIR, BagWriter
from ..codec import CODECS, command_for_step, stamp_ns
from ..config import apply_settings, for_your_controller, load_scenario_text
from ..core.commands import CommandError
from ..core.control import controller_class, strategy_names
from ..core.scenario import Scenario
from ..core.signals import (
    COMMAND_INDEX,
    EXTERNAL,
    EXTERNAL_PREFIX,
    PULSES,
    STATE_INDEX,
    external_name,
    strategy_name,
)
from ..errors import ConfigError, GraphError, Interrupted
from ..interface import LOSSES_TOPIC, NAMESPACE, STEPPER_NODE, TOPICS, node_name
from ..readback import read_bag
from ..recording import bag_info, scenario_of, tool_every, tool_messages
from .placement import ros_env
from .processes import (
    SharedMemory,
    command_line,
    end_own_nodes,
    ended_how,
    ending_with_this_process,
    isolated_domain,
    node_command,
    parameter_args,
    start_process,
    stop_processes,
)
from .transport import raw_publisher, raw_subscription, ros_session, spin_once

__all__ = ["StepResult", "replay_into"]

#: s the stepper waits for one command before it gives the controller up
COMMAND_TIMEOUT = 10.0


@dataclass(frozen=True)
class StepResult:
    """``replay --into``: the new bag, its steps, the strategy replayed into, the share of steps
    whose new command has the recorded vector and the recorded pulses, the controller's compute
    time per step (median) and the pace."""

    bag: Path
    steps: int
    strategy: str
    vector_agreement: float
    pulse_agreement: float
    compute_us_per_step: float
    steps_per_s: float

    def as_dict(self) -> dict[str, Any]:
        return {
            "bag": str(self.bag),
            "steps": self.steps,
            "strategy": self.strategy,
            "agreement": {"vector": self.vector_agreement, "pulses": self.pulse_agreement},
            "compute_us_per_step": self.compute_us_per_step,
            "steps_per_s": self.steps_per_s,
        }


def _with_settings(
    sc: Scenario, source: str | Path, settings: dict[str, Any], *, yours: bool, first: str
) -> Scenario:
    """The recorded scenario as the controller replayed into gets it: a node of the user's own
    gets of a section of ours the controller's model alone, and ``settings`` (checked for ours
    as a run checks them)."""
    where = f"{source} (stored scenario)"
    text = for_your_controller(sc.text, where, settings) if yours else sc.text
    if settings:
        text = apply_settings(text, settings, where, own=["torque_controller"] if yours else ())
    if text == sc.text:
        return sc
    own = sorted(sc.own | ({"torque_controller"} if yours else set()))
    checked = load_scenario_text(
        text, where, legacy=True, own=own, strategy=None if yours else first
    )
    return dataclasses.replace(
        sc, text=text, controller=sc.controller if yours else checked.controller
    )


def replay_into(
    source: str | Path,
    out: Path,
    *,
    strategy: str | None = None,
    command: str | None = None,
    label: str | None = None,
    settings: dict[str, Any] | None = None,
) -> StepResult:
    """Feed the recording ``source`` into a torque controller node step by step and record the
    result to ``out`` as it goes (the caller holds ``out``'s claim). ``strategy``: the one
    strategy to replay into (default: the recording's own, switched at the recorded steps);
    ``command``: a controller node of the user's own to start instead of ours (its command line;
    ``--ros-args``, its name, namespace and parameter files appended), named ``external:label``;
    ``settings``: the controller's parameters changed (``torque_controller.KEY``; a section of
    ours that a node of one's own gets is cut to the controller's model first, as in a run).
    Interrupted (KeyboardInterrupt), the new bag is closed with every step replayed so far and
    :class:`~predictive_drive.errors.Interrupted` says what it holds."""
    from rclpy.parameter import Parameter
    from rclpy.parameter_client import AsyncParameterClient

    trace, info = read_bag(source)
    sc = scenario_of(info.info, info.path)
    n = trace.steps
    names = strategy_names(sc.family)
    if strategy is not None and strategy not in names:
        raise GraphError(f"--strategy {strategy!r}: valid for {sc.family}: {', '.join(names)}")
    recorded = [strategy_name(names, i, trace.external) for i in trace.col("command", "strategy")]
    plan = [strategy] * n if strategy is not None else recorded
    # the law's horizon as recorded (NaN: a law without one, or an older recording: 1)
    horizons = [1 if h != h else int(h) for h in trace.col("command", "horizon")]
    takes_horizon = bool(controller_class(sc.family).horizon_strategies)
    if command is not None:  # the user's node: no strategy to set or switch
        plan = [external_name(label) if label is not None else EXTERNAL] * n
    elif strategy is None and recorded and recorded[0].startswith(EXTERNAL_PREFIX):
        raise ConfigError(
            f"{source}: its torque controller was your own ({recorded[0]}): replay it into "
            f"yours (--into torque_controller=COMMAND) or into one of ours (--strategy: "
            f"{', '.join(names)})"
        )
    sc = _with_settings(sc, source, settings or {}, yours=command is not None, first=plan[0])
    out = out.resolve()
    logs = out / LOGS_DIR
    logs.mkdir(parents=True, exist_ok=True)
    scenario_file = logs / "scenario.yaml"
    scenario_file.write_text(sc.text)
    ours: dict[str, Any] = {"strategy": plan[0]} if command is None else {}
    if command is None and takes_horizon:
        ours["horizon"] = horizons[0] if n else 1
    overrides = {
        node_name("torque_controller"): {
            "duration": n * sc.ts,
            **ours,
            "command_readers": 1,
            "peer_timeout": COMMAND_TIMEOUT,
        }
    }
    args = parameter_args(scenario_file, overrides, logs)
    if command is None:
        start = [*node_command("torque_controller_node"), *args]
    else:
        own = ["-r", "__node:=torque_controller", "-r", f"__ns:={NAMESPACE}"]
        start = ending_with_this_process(
            [*command_line(command, option="--into torque_controller="), *args, *own]
        )
    started = None if command is None else {"torque_controller": command}
    bag_meta = {
        **bag_info(sc.with_strategy(plan[0]), "replay", started),
        "replay_of": str(Path(source).resolve()),
        "replayed_engine": info.info.get("engine", ""),
    }
    commands: list[tuple[float, ...]] = []
    shm = SharedMemory()
    with (
        isolated_domain() as domain,
        ros_session(STEPPER_NODE, domain=domain, namespace=NAMESPACE, log_dir=logs) as (me, ex),
        BagWriter(out, info=bag_meta, claimed=True, losses=trace.has_losses) as writer,
    ):
        got: list[bytes] = []
        sub = raw_subscription(me, "command", got.append)
        pub_state = raw_publisher(me, "state")
        pub_ref = raw_publisher(me, "reference")
        client = AsyncParameterClient(me, node_name("torque_controller"))
        proc = start_process(
            start,
            log=logs / "torque_controller.log",
            env=ros_env(domain, log_dir=logs),
        )
        procs = {"torque_controller": proc}
        recorder = _Recorder(writer, tool_every(sc.ts))
        try:
            _wait(ex, _matched(sub, pub_state, pub_ref), 60.0, proc, logs)
            shm.sample([proc.pid])
            own_law = takes_horizon and command is None
            steps = list(zip(plan, horizons if own_law else [1] * n))
            if command is None and len(set(steps)) > 1:
                services = _until(client.services_are_ready, "its parameter services")
                _wait(ex, services, 60.0, proc, logs)
            state, ref = CODECS["state"], CODECS["reference"]
            in_force = steps[0] if n else ("", 1)
            t0 = time.perf_counter()
            for k in range(n + 1):
                if k < n and steps[k] != in_force:  # the recorded switch, before command k
                    changed = [
                        Parameter(key, value=value)
                        for key, value, before in zip(("strategy", "horizon"), steps[k], in_force)
                        if value != before
                    ]
                    in_force = steps[k]
                    fut = client.set_parameters(changed)
                    answer = _until(fut.done, f"an answer to the switch at step {k}")
                    _wait(ex, answer, COMMAND_TIMEOUT, proc, logs)
                row, reference = tuple(trace.state[k]), tuple(trace.reference[k])
                pub_ref.publish(ref.encode(reference))
                pub_state.publish(state.encode(row))
                lost = tuple(trace.losses[k]) if trace.has_losses else None
                recorder.inputs(row, reference, lost)
                if k < n:
                    answer = _until(
                        partial(_holds, got, k), f"{TOPICS['command'].name} for step {k}"
                    )
                    _wait(ex, answer, COMMAND_TIMEOUT, proc, logs)
                    u_dc = float(row[U_DC])  # a voltage reference is modulated from it
                    commands.append(_applied(got[k], k, row[1], u_dc, out))
                    recorder.command(commands[-1])
            wall = time.perf_counter() - t0
            if command is not None:  # the contract: it exits after its last command
                end_own_nodes(procs, after="its last command")
            else:
                proc.wait(timeout=COMMAND_TIMEOUT + 30)
        except KeyboardInterrupt:
            raise Interrupted(
                f"interrupted: the new bag {out} holds the first {len(commands)} of {n} steps "
                f"replayed (closed; `predictive-drive report {out}` reads it)"
            ) from None
        finally:
            recorder.close()
            stop_processes(procs, urgent=True)
    shm.clean()
    rec = trace.command
    v = COMMAND_INDEX.vector
    # the same vector, or no vector in either (field-oriented control: NaN); no agreement at all
    # where no recorded step picked a vector (nothing to agree with: NaN, shown "-")
    same_vector = [c[v] == r[v] or (c[v] != c[v] and r[v] != r[v]) for c, r in zip(commands, rec)]
    # ... and none where the node replayed into picks none (a controller of one's own that does
    # not say: was 0.00 %)
    picked = bool(np.isfinite(rec[:, v]).any()) and any(c[v] == c[v] for c in commands)
    same_pulses = [tuple(c[PULSES]) == tuple(r[PULSES]) for c, r in zip(commands, rec)]
    # the median step's; a controller of one's own may not say (NaN)
    reported = sorted(t for c in commands if math.isfinite(t := c[COMMAND_INDEX.compute_ns]))
    return StepResult(
        bag=out,
        steps=n,
        strategy=plan[0] if command is not None else strategy or "as recorded",
        vector_agreement=sum(same_vector) / n if picked else math.nan,
        pulse_agreement=sum(same_pulses) / n,
        compute_us_per_step=reported[len(reported) // 2] / 1e3 if reported else math.nan,
        steps_per_s=n / wall,
    )


U_DC = STATE_INDEX.u_dc


class _Recorder:
    """The new bag as the replay goes, in log-time order: per step the recorded state (its
    losses, where the recording has them) and reference, the new command, then the state's tool
    messages (/clock, /drive/joint_states); the last state (it has no command) with its tool
    messages on :meth:`close`."""

    def __init__(self, writer: BagWriter, every: int) -> None:
        self.writer = writer
        self.every = every
        self._pending: tuple[float, ...] | None = None

    def inputs(
        self,
        state: tuple[float, ...],
        reference: tuple[float, ...],
        losses: tuple[float, ...] | None = None,
    ) -> None:
        ns = stamp_ns(state[1])
        self.writer.write("state", ns, CODECS["state"].encode(state))
        if losses is not None:
            self.writer.write(LOSSES_TOPIC, ns, CODECS[LOSSES_TOPIC].encode(losses))
        self.writer.write("reference", ns, CODECS["reference"].encode(reference))
        self._pending = state

    def command(self, command: tuple[float, ...]) -> None:
        state = self._pending
        assert state is not None
        self.writer.write("command", stamp_ns(state[1]), CODECS["command"].encode(command))
        self._tools(state)
        self._pending = None

    def close(self) -> None:
        if self._pending is not None:
            self._tools(self._pending)
            self._pending = None

    def _tools(self, state: tuple[float, ...]) -> None:
        for key, t_ns, data in tool_messages(state, self.every):
            self.writer.write(key, t_ns, data)


def _matched(sub: Any, pub_state: Any, pub_ref: Any) -> Callable[[], str]:
    """What the controller node has not matched yet ('' once it has all)."""

    def missing() -> str:
        out = []
        if sub.get_publisher_count() < 1:
            out.append(f"a {TOPICS['command'].name} publisher")
        for pub in (pub_state, pub_ref):
            if pub.get_subscription_count() < 1:
                out.append(f"a {pub.topic_name} subscription")
        return " and ".join(out)

    return missing


def _until(ready: Callable[[], bool], what: str) -> Callable[[], str]:
    """``what`` is awaited until ``ready()`` (see :func:`_wait`)."""
    return lambda: "" if ready() else what


def _holds(items: list[bytes], k: int) -> bool:
    return len(items) > k


def _applied(data: bytes, k: int, t: float, u_dc: float, out: Path) -> tuple[float, ...]:
    """Command k as the plant would apply it (:func:`~..codec.command_for_step`), or a
    GraphError naming the field and the step, as the plant refuses it."""
    try:
        return tuple(command_for_step(data, k=k, t=t, u_dc=lambda: u_dc))
    except CommandError as e:
        raise GraphError(
            f"{node_name(STEPPER_NODE)}: refused {TOPICS['command'].name} from "
            f"{node_name('torque_controller')}: {e} (as the plant would); the new bag {out} "
            f"holds the {k} steps before it"
        ) from None


def _wait(
    ex: Any, waiting: Callable[[], str], timeout: float, proc: subprocess.Popen[bytes], logs: Path
) -> None:
    """Spin until ``waiting()`` says nothing is awaited any more (''); GraphError naming what
    did not come, from whom, when the node ends or ``timeout`` s pass first."""
    node = node_name("torque_controller")
    log = logs / "torque_controller.log"
    deadline = time.monotonic() + timeout
    while what := waiting():
        if proc.poll() is not None:
            tail = log.read_text(errors="replace")[-1500:]
            raise GraphError(
                f"{node} (pid {proc.pid}) {ended_how(proc.returncode)} while the replay waited "
                f"for {what}; its log {log} ends:\n{tail}"
            )
        if time.monotonic() > deadline:
            raise GraphError(
                f"no {what} from {node} within {timeout:g} s: it runs (pid {proc.pid}) but never "
                f"answered; its log: {log}"
            )
        spin_once(ex, 0.01)
