"""``predictive-drive repair BAG``: rebuild a recording whose writer was killed."""

from __future__ import annotations

import argparse

from ..api.repair import repair
from .common import say_json

HELP = (
    "rebuild a recording whose writer was killed (index, footer, metadata.yaml); the original "
    "file is kept as <name>.mcap.orig"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bag", help="bag directory (or its .mcap file)")


def main(a: argparse.Namespace) -> int:
    r = repair(a.bag)
    if a.json:
        return say_json(r)
    if r.repaired:
        print(
            f"repaired {r.bag}: {r.messages} messages, {r.steps} whole steps; the original "
            f"file is kept as {r.original}"
        )
    else:
        print(f"{r.bag} is intact ({r.messages} messages, {r.steps} steps): left as it is")
    return 0
