"""``predictive-drive repair``: rebuild a recording whose writer was killed (as ``ros2 bag
reindex`` / ``mcap recover`` do); the original file is kept."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..bag import repair_bag
from ..readback import read_bag

__all__ = ["repair"]


def repair(bag: str | Path) -> dict[str, Any]:
    """Repair ``bag`` in place; says what it holds now and where the original went."""
    r = repair_bag(bag)
    return {
        "bag": str(r.bag),
        "repaired": r.original is not None,
        "original": None if r.original is None else str(r.original),
        "messages": r.messages,
        "steps": read_bag(r.bag)[0].steps,
    }
