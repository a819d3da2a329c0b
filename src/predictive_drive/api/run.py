"""``predictive-drive run``: a scenario on an engine, recorded to a bag, evaluated from the bag."""

from __future__ import annotations

import contextlib
import math
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from .. import interrupts
from ..bag import BagWriter, check_new_bag, claim_bag_dir
from ..config import OWN_NODES, load_scenario, scenario_with
from ..core.control import EXTERNAL, strategy_names
from ..core.control.base import parse_switch
from ..core.metrics import Metrics
from ..core.runner import build_controller, run_inprocess
from ..core.scenario import Scenario
from ..core.signals import external_name
from ..core.timebase import step_index
from ..dependencies import require_ros
from ..errors import ConfigError, Interrupted
from ..live import LiveView, check_port
from ..readback import bag_status
from ..recording import RunRecorder, bag_info, default_bag_dir
from ..ros.processes import command_line
from .report import RecordingDetails, details_of, evaluate

__all__ = ["ENGINES", "EXTERNAL_NODES", "RunResult", "run", "run_inprocess_to_bag", "switch_steps"]

ENGINES = ("ros", "composed", "inprocess")


@dataclass(frozen=True)
class RunResult:
    """``run``: what ran, where it is recorded, how long it took (wall s), and the recording's
    metrics and details (evaluated from the bag, as ``report`` would)."""

    scenario: str
    strategy: str
    engine: str
    steps: int
    bag: Path
    wall_s: float
    metrics: Metrics
    details: RecordingDetails
    window_note: str = ""

    def as_dict(self) -> dict[str, Any]:
        return {
            "scenario": self.scenario,
            "strategy": self.strategy,
            "engine": self.engine,
            "steps": self.steps,
            "bag": str(self.bag),
            "wall_s": self.wall_s,
            "metrics": self.metrics.as_dict(),
            **self.details.as_dict(),
            "window_note": self.window_note,
        }


def switch_steps(sc: Scenario, switches: Sequence[tuple[float, str]]) -> list[tuple[int, str]]:
    """``--switch T:STRATEGY`` (or ``T:horizon=N``) pairs → (step, switch); ConfigError for an
    unknown strategy, a horizon the law in force cannot take (each switch checked after the ones
    before it, by the controller itself), or a time outside the run."""
    names = strategy_names(sc.family)
    out = []
    ctrl = build_controller(sc) if switches and not sc.external else None
    in_force: dict[str, Any] = {"strategy": sc.strategy, "horizon": getattr(ctrl, "horizon", 1)}
    for t, name in sorted(switches):
        try:
            key, value = parse_switch(name)
        except ValueError as e:
            raise ConfigError(f"--switch {t}:{e}") from None
        if key == "strategy" and name not in names:
            raise ConfigError(f"--switch {t}:{name}: unknown strategy; valid: {', '.join(names)}")
        if not (0 <= t < sc.run.duration):
            raise ConfigError(f"--switch {t}:{name}: time must lie in [0, {sc.run.duration}) s")
        if value == in_force[key]:
            raise ConfigError(f"--switch {t}:{name}: {value} is already the {key} then")
        reason = ctrl.switch_refusal(key, value) if ctrl is not None else None
        if reason is not None:
            raise ConfigError(f"--switch {t}:{name}: {reason}")
        if ctrl is not None:
            ctrl.switch(key, value)
        in_force[key] = value
        out.append((step_index(t, sc.ts), name))
    return out


def run_inprocess_to_bag(
    sc: Scenario,
    out: Path,
    switches: Sequence[tuple[int, str]] = (),
    progress: Callable[[int], None] | None = None,
    live_port: int = 0,
    claimed: bool = False,
) -> int:
    """The in-process engine with recording; returns the number of steps recorded. ``switches``:
    (step, strategy) pairs, as :func:`switch_steps` makes them; ``live_port``: serve the live
    view there too (the strategy read-only: this engine has no parameter service); ``claimed``:
    the caller holds ``out``'s claim (:func:`~predictive_drive.bag.claim_bag_dir`)."""
    names = strategy_names(sc.family)
    live = (
        LiveView(port=live_port, ts=sc.ts, strategy=sc.strategy, strategy_names=names)
        if live_port
        else None
    )
    try:
        losses = sc.plant.losses.on
        with BagWriter(
            out, info=bag_info(sc, "inprocess"), claimed=claimed, losses=losses
        ) as writer:
            rec = RunRecorder(
                writer,
                ts=sc.ts,
                steps=sc.run.steps,
                torque_limit=sc.torque_limit,
                strategy_names=names,
                record_tools=True,
                live=None if live is None else live.offer,
                losses=losses,
            )

            def record(states: bytes, references: bytes, commands: bytes, lost: bytes) -> None:
                with interrupts.held():  # a batch goes into the bag whole (see interrupts)
                    rec.record_rows(states, references, commands, lost)

            try:
                trace = run_inprocess(sc, switches=switches, sinks=[record], progress=progress)
            except KeyboardInterrupt:
                with interrupts.held():
                    rec.finish("interrupted")
                raise
            except Exception as e:
                with interrupts.held():
                    rec.finish(f"failed: {e}")
                raise
            with interrupts.held():
                rec.finish()
    finally:
        if live is not None:
            live.close()
    return trace.steps


@contextlib.contextmanager
def scenario_file(
    scenario: str | Path, settings: dict[str, Any] | None, *, own: Sequence[str] = ()
) -> Iterator[str | Path]:
    """The scenario with ``settings`` applied, as a file that lasts as long as the block (a ROS
    engine's nodes read it); the scenario itself when there are none. ``own``: the nodes of the
    user's own, whose sections take any key (a torque controller's section is the user's:
    :func:`~predictive_drive.config.for_your_controller`)."""
    if not settings and "torque_controller" not in own:
        yield scenario
        return
    with tempfile.TemporaryDirectory(prefix="predictive-drive-") as tmp:
        yield scenario_with(scenario, settings or {}, Path(tmp), own=own)


#: the nodes a user may replace with their own (``run --external``)
EXTERNAL_NODES = OWN_NODES


def _check_external(
    external: Mapping[str, str | None],
    engine: str,
    strategy: str | None,
    switches: Sequence[tuple[float, str]],
    label: str | None,
) -> None:
    """ConfigError for an --external that cannot be: an unknown node, an empty command or one
    that cannot start, an engine without separate node processes, a strategy or a switch for a
    controller of one's own; a --label without a node of one's own."""
    if label is not None and not external:
        raise ConfigError(
            f"--label {label}: names a node of your own: give --external "
            "torque_controller[=COMMAND] or speed_pi[=COMMAND] too"
        )
    if not external:
        return
    for name, command in external.items():
        if name not in EXTERNAL_NODES:
            raise ConfigError(
                f"--external {name}: not a node you can replace; one of {', '.join(EXTERNAL_NODES)}"
            )
        if command is not None and not command.strip():
            raise ConfigError(
                f"--external {name}=: an empty command (leave out '=' to start it by hand)"
            )
    if engine != "ros":
        raise ConfigError(
            f"--external runs your node as a process of its own: --engine ros, not {engine}"
        )
    if "torque_controller" in external and (strategy is not None or switches):
        raise ConfigError(
            "--external torque_controller: your node is the torque controller, so --strategy and "
            "--switch do not apply"
        )
    for name, command in external.items():  # a typo is said before anything starts
        if command is not None:
            command_line(command, option=f"--external {name}=")


def run(
    scenario: str | Path,
    *,
    strategy: str | None = None,
    duration: float | None = None,
    settings: dict[str, Any] | None = None,
    engine: str = "ros",
    out: str | Path | None = None,
    switches: Sequence[tuple[float, str]] = (),
    progress: Callable[[int, int], None] | None = None,
    affinity: str = "paired",
    sched: str = "batch",
    peer_timeout: float = 10.0,
    live: int = 0,
    external: Mapping[str, str | None] | None = None,
    label: str | None = None,
    startup_timeout: float = 60.0,
    announce: Callable[[str], None] | None = None,
) -> RunResult:
    """Run a scenario on an engine, record it, and evaluate the recording. ``affinity`` and
    ``sched``: CPU placement (``paired`` | ``none``, see
    :func:`predictive_drive.ros.placement.cpu_plan`) and scheduling policy (``batch`` |
    ``other``) of the ``ros`` engine's node processes; ``peer_timeout``: s of wall time a node
    of a ROS engine waits for a silent peer before the run fails; ``startup_timeout``: s the
    graph waits for every node to match and for command 0 (a node started by hand included);
    ``live``: a port to serve the
    running drive on to Foxglove / Lichtblick (0: none; see :mod:`predictive_drive.live`);
    ``settings``: scenario keys changed for this run (see
    :func:`predictive_drive.config.apply_settings`); ``external``: nodes of the user's own in
    place of ours, by name (``torque_controller``, ``speed_pi``): the command that starts one,
    or None to start it by hand (docs/ros.md#writing-your-own-controller); their sections of
    the scenario (and ``settings`` of them) are theirs, not checked; ``label``: the name of a
    torque controller of one's own, ``external:LABEL`` in the recording, tables and figures (of
    a speed loop of one's own, with our torque controller: the run's label beside its strategy);
    ``announce``: told what the user should know before the run starts (where the live view
    serves), once every check has passed."""
    if engine not in ENGINES:
        raise ConfigError(f"--engine: {engine!r} is not one of {', '.join(ENGINES)}")
    external = dict(external or {})
    _check_external(external, engine, strategy, switches, label)
    if "torque_controller" in external:
        strategy = external_name(label) if label is not None else EXTERNAL
    elif label is not None:  # a speed loop of one's own: the run's label, beside the strategy
        external_name(label)  # the same rules: it names the run in tables and figures
    for option, value in (("--peer-timeout", peer_timeout), ("--startup-timeout", startup_timeout)):
        if not (math.isfinite(value) and value > 0):
            raise ConfigError(f"{option} must be a positive number of seconds, got {value}")
    with scenario_file(scenario, settings, own=list(external)) as source:
        try:
            sc = load_scenario(source, strategy=strategy, duration=duration, own=list(external))
        except ConfigError as e:  # name what the user gave, not the file made of it
            if source == scenario:
                raise
            given = " ".join(f"--set {k}={v}" for k, v in (settings or {}).items())
            raise ConfigError(str(e).replace(str(source), f"{scenario} {given}")) from None
        bag = Path(out) if out is not None else default_bag_dir(sc)
        n = sc.run.steps
        cb = (lambda k: progress(k, n)) if progress is not None else None
        # checked for every engine, so a bad --switch or --out fails before anything starts
        at_steps = switch_steps(sc, switches)
        check_new_bag(bag)
        if engine != "inprocess":
            require_ros(f"--engine {engine}")
        if live:
            check_port(live)
            if announce is not None:
                announce(
                    f"live view on ws://127.0.0.1:{live} (Foxglove / Lichtblick: open "
                    "connection, Foxglove WebSocket)"
                )
        t0 = time.perf_counter()
        # claimed before anything starts: a second run given the same --out is refused
        with claim_bag_dir(bag):
            try:
                if engine == "inprocess":
                    run_inprocess_to_bag(sc, bag, at_steps, cb, live_port=live, claimed=True)
                else:
                    # rclpy only when a ROS engine is asked for
                    from ..ros.launcher import run_graph

                    run_graph(
                        sc,
                        bag,
                        composed=(engine == "composed"),
                        switches=switches,
                        progress=cb,
                        affinity=affinity,
                        sched=sched,
                        peer_timeout=peer_timeout,
                        live_port=live,
                        external=external,
                        startup_timeout=startup_timeout,
                        label=label if "torque_controller" not in external else None,
                    )
            except KeyboardInterrupt:
                status = bag_status(bag).describe()
                raise Interrupted(f"interrupted: {status} (of {n} planned)") from None
        wall = time.perf_counter() - t0
        ev = evaluate(bag)
        return RunResult(
            sc.name,
            sc.strategy,
            engine,
            ev.steps,
            bag,
            wall,
            ev.metrics,
            details_of(ev),
            ev.window_note,
        )
