"""``predictive-drive report BAG``: a recording's metrics, from the recording alone."""

from __future__ import annotations

import argparse

from ..api.report import report
from .common import print_recording, say_json

HELP = "metrics of a recording, from the recording alone (and its figures, as PNG)"


def _window(text: str) -> tuple[float, float]:
    a, sep, b = text.partition(",")
    try:
        if not sep:
            raise ValueError
        return float(a), float(b)
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected A,B in s (e.g. 0.1,0.4), got {text!r}"
        ) from None


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bag", help="bag directory (or its .mcap file)")
    p.add_argument("--figures", metavar="DIR", help="also draw the run's figures (PNG) here")
    p.add_argument(
        "--window", type=_window, metavar="A,B",
        help="the metrics over [A, B) s of the run instead of the recorded scenario's window",
    )  # fmt: skip
    p.add_argument(
        "--thd-window", type=_window, metavar="A,B",
        help="the phase-a THD over the whole electrical cycles in [A, B] s instead of the "
        "recorded scenario's THD window",
    )  # fmt: skip


def main(a: argparse.Namespace) -> int:
    r = report(a.bag, figures=a.figures, window=a.window, thd_window=a.thd_window)
    if a.json:
        return say_json(r)
    print_recording(r)
    if not r.complete:
        print(
            "  note: the recording is truncated (no index: its writer was killed); read up "
            f"to its last complete step; `predictive-drive repair {r.bag}` rebuilds it"
        )
    if r.steps < r.planned_steps:
        print(
            f"  note: the run stopped early: {r.steps} of {r.planned_steps} planned steps recorded"
        )
    for f in r.figures:
        print(f"figure   {f}")
    return 0
