"""``predictive-drive run SCENARIO``: run a scenario on an engine, record it, print its metrics."""

from __future__ import annotations

import argparse
import sys

from ..api.run import ENGINES, run
from ..errors import ConfigError
from ..live import DEFAULT_PORT
from ..ros.placement import AFFINITIES, SCHED_POLICIES
from .common import (
    print_recording,
    progress,
    refuse,
    say_json,
    scenario_argument,
    seconds,
    single_settings,
)

HELP = "run a scenario, record it to bags/<run>/ and print its metrics"


def _switch(text: str) -> tuple[float, str]:
    t, sep, name = text.partition(":")
    try:
        if not sep:
            raise ValueError
        return float(t), name
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected T:STRATEGY or T:horizon=N (e.g. 2.5:mptc), got {text!r}"
        ) from None


def _external(texts: list[str]) -> dict[str, str | None]:
    """``NODE[=COMMAND]`` arguments → node → command (None: started by hand)."""
    out: dict[str, str | None] = {}
    for text in texts:
        name, sep, command = text.partition("=")
        if name in out:
            raise ConfigError(f"--external {name}: given twice")
        out[name] = command if sep else None
    return out


def add_arguments(p: argparse.ArgumentParser) -> None:
    scenario_argument(p)
    p.add_argument("--strategy", help="override the scenario's torque_controller.strategy")
    p.add_argument("--duration", type=seconds, help="simulated seconds (default: the scenario's)")
    p.add_argument(
        "--set", action="append", metavar="KEY=VALUE",
        help="a scenario setting, e.g. plant.actuation_delay_steps=1 or "
        "torque_controller.motor.l_q=*0.7 (repeatable; the bag stores the scenario as run)",
    )  # fmt: skip
    p.add_argument(
        "--engine",
        default="ros",
        choices=ENGINES,
        help="ros: four node processes (default); composed: one process; inprocess: no ROS",
    )
    p.add_argument(
        "--composed", dest="engine", action="store_const", const="composed",
        help="same as --engine composed",
    )  # fmt: skip
    p.add_argument(
        "--affinity",
        choices=AFFINITIES,
        help="--engine ros: CPU placement of the node processes: paired (default) keeps plant + "
        "torque_controller on one CPU and speed_pi + metrics_logger on another; none: the "
        "kernel's choice",
    )
    p.add_argument(
        "--sched",
        choices=tuple(SCHED_POLICIES),
        help="--engine ros: scheduling policy of the node processes' threads: batch (default, "
        "SCHED_BATCH: a woken node does not preempt the one publishing to it) or other",
    )
    p.add_argument(
        "--external",
        action="append",
        metavar="NODE[=COMMAND]",
        help="your own node in place of ours (torque_controller or speed_pi; --engine ros): "
        "COMMAND starts it (any executable; --ros-args with its name, namespace and the "
        "parameter files are appended), or without =COMMAND you start it by hand as the run "
        "says (docs/ros.md, 'Writing your own controller')",
    )
    p.add_argument(
        "--label",
        metavar="NAME",
        help="with --external torque_controller: your controller's name, external:NAME in the "
        "bag, its folder name, report, compare and figures (letters, digits, _ . + -, at most 64; "
        "default torque_controller); --set torque_controller.KEY=VALUE gives it parameters. "
        "With --external speed_pi alone: your speed loop's name, [speed_pi:NAME] beside the "
        "strategy in report, compare and figures",
    )
    p.add_argument("--out", help="bag directory to write (must not exist)")
    p.add_argument(
        "--live",
        type=int,
        nargs="?",
        const=DEFAULT_PORT,
        metavar="PORT",
        help="serve the running drive to Foxglove / Lichtblick on ws://127.0.0.1:PORT (default "
        f"{DEFAULT_PORT}; the foxglove.sdk.v1 WebSocket protocol, see docs/ros.md)",
    )
    p.add_argument(
        "--peer-timeout",
        type=float,
        metavar="S",
        help="ROS engines: s of wall time a node waits for a silent peer (or the recorder) "
        "before the run fails (default 10)",
    )
    p.add_argument(
        "--startup-timeout",
        type=float,
        metavar="S",
        help="ROS engines: s of wall time the graph waits for every node to match and for command "
        "0, a node you start by hand included (default 60)",
    )
    p.add_argument(
        "--switch", action="append", type=_switch, metavar="T:STRATEGY",
        help="switch the strategy at simulated time T, or its horizon (T:horizon=N) "
        "(repeatable)",
    )  # fmt: skip


def main(a: argparse.Namespace) -> int:
    if a.engine != "ros":
        refuse(a, f"applies to --engine ros only (separate node processes), not {a.engine}",
               "affinity", "sched")  # fmt: skip
    if a.engine == "inprocess":
        refuse(a, "applies to the ROS engines only (there are no peers in-process)",
               "peer_timeout", "startup_timeout")  # fmt: skip
    update, close = progress(sys.stderr.isatty() and not a.json)
    try:
        r = run(
            a.scenario,
            strategy=a.strategy,
            duration=a.duration,
            settings=single_settings(a.set),
            engine=a.engine,
            out=a.out,
            switches=a.switch or (),
            progress=update,
            affinity=a.affinity or "paired",
            sched=a.sched or "batch",
            peer_timeout=10.0 if a.peer_timeout is None else a.peer_timeout,
            startup_timeout=60.0 if a.startup_timeout is None else a.startup_timeout,
            live=a.live or 0,
            external=_external(a.external or []),
            label=a.label,
            announce=lambda line: print(f"predictive-drive: {line}", file=sys.stderr, flush=True),
        )
    finally:
        close()
    if a.json:
        return say_json(r)
    print_recording(r, wall_s=r.wall_s)
    return 0
