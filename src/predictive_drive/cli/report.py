"""``predictive-drive report BAG``: a recording's metrics, from the recording alone."""

from __future__ import annotations

import argparse

from ..api.report import report
from .common import print_recording, say_json

HELP = "metrics of a recording, from the recording alone (and its figures, as PNG)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bag", help="bag directory (or its .mcap file)")
    p.add_argument("--figures", metavar="DIR", help="also draw the run's figures (PNG) here")


def main(a: argparse.Namespace) -> int:
    r = report(a.bag, figures=a.figures)
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
