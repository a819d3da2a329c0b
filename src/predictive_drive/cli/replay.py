"""``predictive-drive replay BAG``: a recording onto ROS topics (as ``ros2 bag play``), or into a
controller node step by step (``--into``)."""

from __future__ import annotations

import argparse
import sys

from ..api.replay import replay, replay_into
from ..core.metrics import METRICS
from .common import refuse, say_json, single_settings

HELP = (
    "publish a recording onto ROS topics with its QoS, paced by its log time (as ros2 bag play "
    "does), on the environment's ROS_DOMAIN_ID; or feed it into a controller node (--into)"
)
#: the options of playing onto topics, and of replaying into a node
PLAY_OPTIONS = ("rate", "start_offset", "playback_duration", "loop", "topics", "exclude_topics",
                "remap", "clock", "start_paused", "wait_for")  # fmt: skip
INTO_OPTIONS = ("strategy", "out", "label", "set")


def _remap(text: str) -> tuple[str, str]:
    old, sep, new = text.partition(":=")
    if not (sep and old and new):
        raise argparse.ArgumentTypeError(
            f"expected OLD:=NEW (e.g. /clock:=/sim_clock), got {text!r}"
        )
    return old, new


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bag", help="bag directory (or its .mcap file)")
    play = p.add_argument_group("playing onto topics (as ros2 bag play)")
    play.add_argument("--rate", type=float, help="recorded s per wall s (> 0; default 1)")
    play.add_argument("--start-offset", type=float, metavar="S",
                      help="start S s of recorded time after the bag's start")  # fmt: skip
    play.add_argument("--playback-duration", type=float, metavar="S",
                      help="play S s of recorded time")  # fmt: skip
    play.add_argument("--loop", action="store_true", help="play again from the start at the end")
    play.add_argument("--topics", nargs="+", metavar="TOPIC", help="play only these topics")
    play.add_argument("--exclude-topics", nargs="+", metavar="TOPIC", help="leave these out")
    play.add_argument("--remap", action="append", type=_remap, metavar="OLD:=NEW",
                      help="publish topic OLD as NEW (repeatable)")  # fmt: skip
    play.add_argument("--clock", type=float, nargs="?", const=40.0, metavar="HZ",
                      help="publish /clock from the replayed time at HZ (default 40) instead of "
                      "the recorded /clock")  # fmt: skip
    play.add_argument("--start-paused", action="store_true",
                      help="start paused (it says how to resume: `predictive-drive param set player "
                      "paused false` on its ROS_DOMAIN_ID)")  # fmt: skip
    play.add_argument("--wait-for", type=int, metavar="N",
                      help="before the first message, wait until each played topic has N "
                      "subscribers (default: a discovery settle of 3 s or more, until the "
                      "subscribers already running have matched)")  # fmt: skip
    into = p.add_argument_group("replaying into a node (--into)")
    into.add_argument(
        "--into",
        metavar="torque_controller[=COMMAND]",
        help="feed the recorded states and references step by step into a node of this kind "
        "and record its new commands (deterministic replay); =COMMAND: into your own node, "
        "started by that command line (docs/ros.md, 'Writing your own controller')",
    )
    into.add_argument(
        "--strategy",
        help="the strategy to replay into (default: the recording's, switched where it switched)",
    )
    into.add_argument("--out", help="the new bag (default: beside the recording)")
    into.add_argument(
        "--label",
        metavar="NAME",
        help="with =COMMAND: your controller's name, external:NAME in the new bag (as run --label)",
    )
    into.add_argument(
        "--set",
        action="append",
        metavar="torque_controller.KEY=VALUE",
        help="a parameter of the controller replayed into (repeatable): any key for your own "
        "node (as run --set gives it), one of the family's for ours",
    )


def main(a: argparse.Namespace) -> int:
    if a.into:
        refuse(a, "is an option of playing onto topics, not of --into", *PLAY_OPTIONS)
        return _into(a)
    refuse(a, "applies with --into only (replaying into a node)", *INTO_OPTIONS)
    options = {
        "rate": a.rate,
        "start_offset": a.start_offset,
        "playback_duration": a.playback_duration,
        "loop": a.loop,
        "topics": tuple(a.topics or ()),
        "exclude_topics": tuple(a.exclude_topics or ()),
        "remap": dict(a.remap or ()),
        "clock_hz": a.clock,
        "start_paused": a.start_paused,
        "wait_for": a.wait_for,
    }
    if a.start_paused:
        from ..ros.params import domain_id

        print(
            "predictive-drive: the replay starts paused; to start it, from another shell: "
            f"ROS_DOMAIN_ID={domain_id()} predictive-drive param set player paused false",
            file=sys.stderr,
            flush=True,
        )
    d = replay(a.bag, **{k: v for k, v in options.items() if v is not None})
    if a.json:
        say_json(d)
        return 130 if d.interrupted else 0
    total = sum(d.published.values())
    print(
        ("interrupted: " if d.interrupted else "")
        + f"replayed {d.bag}: {total} messages in {d.wall_s:.2f} s "
        f"({d.passes} pass{'es' if d.passes > 1 else ''}), achieved rate "
        f"{d.achieved_rate:.3g} (recorded s per wall s)"
    )
    for topic, n in d.published.items():
        print(f"  {topic:<28}{n:>9}")
    if d.max_lag_s > 0.1:
        print(
            f"  fell behind the recording's pace by up to {d.max_lag_s:.2f} s (at the end "
            f"{d.lag_s:.2f} s): every message was published, in order, but late"
        )
    return 130 if d.interrupted else 0


def _into(a: argparse.Namespace) -> int:
    node, sep, command = a.into.partition("=")
    d = replay_into(
        a.bag, node=node, strategy=a.strategy, out=a.out, command=command if sep else None,
        label=a.label, settings=single_settings(a.set),
    )  # fmt: skip
    if a.json:
        return say_json(d)
    print(
        f"replayed {a.bag} into the torque controller ({d.strategy}): {d.steps} steps at "
        f"{d.steps_per_s:,.0f} steps/s; new bag {d.bag}"
    )
    vector, pulses = METRICS["vector_agreement"], METRICS["pulse_agreement"]
    print(
        f"  agreement with the recorded commands: vector {vector.with_unit(d.vector_agreement)}, "
        f"pulses {pulses.with_unit(d.pulse_agreement)}; compute "
        f"{METRICS['compute_us_per_step'].with_unit(d.compute_us_per_step)}"
    )
    return 0
