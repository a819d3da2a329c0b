"""``predictive-drive``: the command line. One module per verb (``add_arguments`` + ``main``),
each calling its :mod:`predictive_drive.api` module and printing the typed result.

Only the standard library is imported here: the verbs (and numpy, rclpy behind them) are
imported once :func:`main` has taken over Ctrl-C, so an interrupt at any moment ends the command
with its exit status, never a traceback.
"""

from __future__ import annotations

import os
import signal

# the first thing the command does: a Ctrl-C before main() has taken it over (while Python
# imports the command line) ends the command with the interrupted status, without a traceback
signal.signal(signal.SIGINT, lambda _s, _f: os._exit(130))

import argparse  # noqa: E402
import atexit  # noqa: E402
import importlib  # noqa: E402
import sys  # noqa: E402
from collections.abc import Sequence  # noqa: E402
from types import FrameType, ModuleType  # noqa: E402
from typing import NoReturn  # noqa: E402

from .. import interrupts  # noqa: E402
from ..errors import Interrupted, PredictiveDriveError  # noqa: E402

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


class UsageError(PredictiveDriveError):
    """The command line itself is wrong (an unknown option, a missing argument)."""


class _Parser(argparse.ArgumentParser):
    """argparse's parser; with ``--json`` a usage error is one JSON object too."""

    json_errors = False

    def error(self, message: str) -> NoReturn:
        if _Parser.json_errors:
            self.print_usage(sys.stderr)
            _say_error(UsageError(f"{self.prog}: {message}"), True)
            sys.exit(2)
        super().error(message)


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    p = _Parser(
        prog="predictive-drive",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    p.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = p.add_subparsers(dest="verb", required=True, metavar="VERB")
    json_option = _Parser(add_help=False)
    json_option.add_argument(
        "--json", action="store_true", help="print one JSON object (an error too)"
    )
    for name in VERBS:
        verb = _verb(name)
        sp = sub.add_parser(name, help=verb.HELP, description=verb.HELP, parents=[json_option])
        verb.add_arguments(sp)
        sp.set_defaults(main=verb.main, parser=sp)
    return p


#: signals that came while the verbs were being imported
_pending: list[int] = []


def _defer(signum: int, frame: object) -> None:
    _pending.append(signum)


def main(argv: Sequence[str] | None = None) -> int:
    """The command (``argv`` None: the process's own arguments) or one call of it (a list)."""
    code = _main(argv)
    if argv is None:
        _done(code)
    return code


#: the command's status once it has said everything (None before)
_status: int | None = None


def _press(signum: int, frame: FrameType | None) -> None:
    """The command's SIGINT / SIGTERM handler: :func:`interrupts.interrupt` while it works
    (:func:`_main` on the stack); once it is done, the end of the process at once with its
    status; in the moment between, nothing (the exit follows at once). Python resets its
    handlers to the default for the last part of its exit (see :func:`_ignore_at_the_end`),
    and a press after the work, as a second Ctrl-C often is, ended the process by SIGINT
    after everything was written (status -2 to a Python caller, 130 to a shell; 3 of 12 double
    Ctrl-Cs of a sweep that finished within the 20 ms between the presses)."""
    f = frame
    while f is not None:
        if f.f_code is _main.__code__:
            interrupts.interrupt(signum, frame)
            return
        f = f.f_back
    if _status is not None:
        os._exit(_status)


def _done(code: int) -> None:
    """The command has done its work and said so: its output flushed, a press from here on
    ends the process with ``code`` (:func:`_press`)."""
    global _status
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass  # a reader gone (BrokenPipe) or a stream closed: nothing more to say to it
    _status = code


@atexit.register  # registered before the verbs import anything: runs after their exit handlers
def _ignore_at_the_end() -> None:
    """After the exit's own cleanup, a press changes nothing: ignored (a handler of Python's
    would be reset to the default, which ends the process by the signal)."""
    if _status is not None:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_IGN)


def _main(argv: Sequence[str] | None) -> int:
    # Ctrl-C and SIGTERM both end the command the same way: children stopped, bag closed. (A
    # shell's background job inherits SIGINT ignored; the graph's owner must still honour it.)
    # While the verbs are imported, a signal waits for the imports to finish: a
    # KeyboardInterrupt raised inside an extension module's initialisation can make Python
    # end the process by SIGINT at exit whatever main() returned.
    signal.signal(signal.SIGINT, _defer)
    signal.signal(signal.SIGTERM, _defer)
    as_json = _Parser.json_errors = "--json" in (sys.argv[1:] if argv is None else argv)
    try:
        parser = build_parser()
        # a KeyboardInterrupt, held back while a recording is being changed (see interrupts);
        # the command's own process: none once the work is done (see _press)
        handler = _press if argv is None else interrupts.interrupt
        signal.signal(signal.SIGINT, handler)
        signal.signal(signal.SIGTERM, handler)
        if _pending:
            raise KeyboardInterrupt
        args, unknown = parser.parse_known_args(argv)
        if unknown:  # said with the verb's usage, not the command's
            args.parser.error(f"unrecognized arguments: {' '.join(unknown)}")
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
    except ModuleNotFoundError as e:
        # a package the command needs is not installed (a ROS workspace built without rosdep,
        # a venv without an extra): one line that names it, also for --help
        if e.name is None or e.name.split(".")[0] == "predictive_drive":
            raise  # a module of our own missing is a broken install: its traceback says where
        from ..dependencies import how_to_install
        from ..errors import MissingDependency

        _say_error(MissingDependency(how_to_install(e.name)), as_json)
        return 2


def _say_error(e: Exception, as_json: bool) -> None:
    """An error on stderr; with --json also as one JSON object on stdout."""
    from .common import dumps

    print(f"predictive-drive: error: {e}", file=sys.stderr)
    if as_json:
        print(dumps({"error": str(e), "kind": type(e).__name__}))
