"""``predictive-drive layout``: write the Foxglove / Lichtblick layout for the drive's topics."""

from __future__ import annotations

import argparse

HELP = "write a Foxglove / Lichtblick layout for the drive's topics (JSON)"
JSON = False  # prints one line: no --json


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="drive.foxglove.json", help="default: %(default)s")


def main(a: argparse.Namespace) -> int:
    from ..reports.layout import write_layout

    path = write_layout(a.out)
    print(f"wrote {path}: import it in Foxglove or Lichtblick (Layouts → Import from file)")
    return 0
