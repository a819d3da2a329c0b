"""``predictive-drive layout``: write the Foxglove / Lichtblick layout for the drive's topics."""

from __future__ import annotations

import argparse
from pathlib import Path

from .common import dumps

HELP = "write a Foxglove / Lichtblick layout for the drive's topics (JSON)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--out", default="drive.foxglove.json", help="default: %(default)s")
    p.add_argument("--force", action="store_true", help="replace the file if it exists")


def main(a: argparse.Namespace) -> int:
    from ..reports.layout import write_layout

    replaced = a.force and Path(a.out).exists()
    path = write_layout(a.out, replace=a.force)
    if a.json:
        print(dumps({"layout": str(path), "replaced": replaced}))
        return 0
    print(
        f"{'replaced' if replaced else 'wrote'} {path}: import it in Foxglove or Lichtblick "
        "(Layouts → Import from file)"
    )
    return 0
