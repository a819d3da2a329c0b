"""``predictive-drive``: the command line. One module per verb (``add_arguments`` + ``main``),
each calling its :mod:`predictive_drive.api` module and printing the typed result.

Only the standard library is imported here: the verbs (and numpy, rclpy behind them) are
imported once :func:`main` has taken over Ctrl-C, so an interrupt at any moment ends the command
with its exit status, never a traceback.
"""

from __future__ import annotations

import argparse
import importlib
import os
import signal
import sys
from collections.abc import Sequence
from types import ModuleType

from ..errors import Interrupted, PredictiveDriveError

__all__ = ["DESCRIPTION", "VERBS", "build_parser", "main"]

#: the verbs, in the order ``--help`` lists them
VERBS = (
    "run", "report", "compare", "sweep", "reproduce", "analyze", "replay", "repair", "layout",
    "param", "bench",
)  # fmt: skip

DESCRIPTION = """\
Simulate electric drives under model predictive torque control on a lock-step ROS 2 graph,
record every run to MCAP, and evaluate, compare, replay and sweep the recordings.

A first session:
  predictive-drive run im_short                    the default graph: four node processes
  predictive-drive report bags/<run> --figures f   metrics and figures from the recording
  predictive-drive sweep im_short --strategy mptc,db_mptc
  predictive-drive reproduce im_paper              paper 000's Table 2, ours beside the paper's

`predictive-drive VERB --help` explains each verb; the documentation is in the project's docs/
(physics.md, ros.md, recordings.md, reproduction.md, performance.md)."""


def _verb(name: str) -> ModuleType:
    return importlib.import_module(f"{__name__}.{name}")


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    p = argparse.ArgumentParser(
        prog="predictive-drive",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = p.add_subparsers(dest="verb", required=True, metavar="VERB")
    json_option = argparse.ArgumentParser(add_help=False)
    json_option.add_argument(
        "--json", action="store_true", help="print one JSON object (an error too)"
    )
    for name in VERBS:
        verb = _verb(name)
        parents = [json_option] if getattr(verb, "JSON", True) else []
        sp = sub.add_parser(name, help=verb.HELP, description=verb.HELP, parents=parents)
        verb.add_arguments(sp)
        sp.set_defaults(main=verb.main)
    return p


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main(argv: Sequence[str] | None = None) -> int:
    # Ctrl-C and SIGTERM both end the command the same way: children stopped, bag closed. (A
    # shell's background job inherits SIGINT ignored; the graph's owner must still honour it.)
    signal.signal(signal.SIGINT, _interrupt)
    signal.signal(signal.SIGTERM, _interrupt)
    as_json = "--json" in (sys.argv[1:] if argv is None else argv)
    try:
        args = build_parser().parse_args(argv)
        as_json = bool(getattr(args, "json", False))
        return int(args.main(args))
    except KeyboardInterrupt:
        _say_error(Interrupted("interrupted"), as_json)
        return 130
    except BrokenPipeError:
        # the reader went away (`report BAG | head -1`): nothing more to say to it
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 2
    except Interrupted as e:
        _say_error(e, as_json)
        return 130
    except PredictiveDriveError as e:
        _say_error(e, as_json)
        return 2


def _say_error(e: Exception, as_json: bool) -> None:
    """An error on stderr; with --json also as one JSON object on stdout."""
    from .common import dumps

    print(f"predictive-drive: error: {e}", file=sys.stderr)
    if as_json:
        print(dumps({"error": str(e), "kind": type(e).__name__}))
