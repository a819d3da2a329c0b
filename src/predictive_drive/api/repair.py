"""``predictive-drive repair``: rebuild a recording whose writer was killed (as ``ros2 bag
reindex`` / ``mcap recover`` do); the original file is kept."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..bag import repair_bag
from ..errors import BagError
from ..readback import read_bag

__all__ = ["Repaired", "repair"]


@dataclass(frozen=True)
class Repaired:
    """``repair``: the bag, whether it was rebuilt (or left alone, intact), where the original
    file is kept, and the messages and whole steps the bag holds now."""

    bag: Path
    repaired: bool
    original: Path | None
    messages: int
    steps: int

    def as_dict(self) -> dict[str, Any]:
        return {
            "bag": str(self.bag),
            "repaired": self.repaired,
            "original": None if self.original is None else str(self.original),
            "messages": self.messages,
            "steps": self.steps,
        }


def repair(bag: str | Path) -> Repaired:
    """Repair ``bag`` in place; says what it holds now and where the original went. A file that
    is no recording, or holds no complete step, is left as it is (BagError says why)."""
    try:
        read_bag(bag)  # read as far as it goes, whole or cut: does it hold a step at all?
    except BagError as e:
        raise BagError(f"{e}; nothing repaired: the file is left as it was") from None
    r = repair_bag(bag)
    return Repaired(r.bag, r.original is not None, r.original, r.messages, read_bag(r.bag)[0].steps)
