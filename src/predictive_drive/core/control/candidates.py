"""Candidate vector sets of paper 001's simplified strategies 2 and 3
(docs/physics.md#mptc-of-the-pmsm), as data.

The sets live in ``candidate_tables.json`` beside this module, in the shape
``predictive-drive analyze --write-tables`` writes them: the utilization analysis of a recording
regenerates them (docs/physics.md#utilization-analysis), so they are never hand-typed constants in the code.
"""

from __future__ import annotations

import json
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any, NamedTuple

from ...errors import ConfigError

__all__ = [
    "CANDIDATE_TABLES_FILE",
    "FLUX_SIGNS",
    "TABLES",
    "TORQUE_SIGNS",
    "CandidateTables",
    "class_document",
    "load_candidate_tables",
    "sector",
]

TWO_PI = 2.0 * math.pi
CANDIDATE_TABLES_FILE = Path(__file__).with_name("candidate_tables.json")


def sector(angle: float, count: int) -> int:
    """0-based sector of an αβ angle (rad) among ``count`` equal sectors starting at 0°:
    sector 0 is [0°, 360°/count). Paper 001 eq 11-12 number them θ1..θcount. An angle that rounds
    to 360° is 0°."""
    return int(angle % TWO_PI / (TWO_PI / count)) % count


class CandidateTables(NamedTuple):
    """Candidate vectors per class. ``six[t][s]``: torque-error sign t (0: ΔT > th, 1: ΔT < -th),
    6-sector s. ``twelve[t][f][s]``: f the flux-error sign (0: Δψ ≥ 0, 1: Δψ < 0), 12-sector s.
    Every set is a tuple of vector numbers in ascending order (V0 first)."""

    six: tuple[tuple[tuple[int, ...], ...], ...]
    twelve: tuple[tuple[tuple[tuple[int, ...], ...], ...], ...]
    rule: str = ""
    source: str = ""


#: class keys of the table file: torque-error sign (index t), flux-error sign (index f)
TORQUE_SIGNS = ("T+", "T-")
FLUX_SIGNS = ("psi+", "psi-")


def class_document(six: Any, twelve: Any, cell: Callable[[Any], Any] = list) -> dict[str, Any]:
    """Per-class data in the table file's shape: ``six[t][s]`` under ``six_sector`` → ``T±``,
    ``twelve[t][f][s]`` under ``twelve_sector`` → ``T±psi±``; each entry passed through ``cell``.
    The candidate tables, and the analysis' utilization tables, are written in this shape."""
    return {
        "six_sector": {TORQUE_SIGNS[t]: [cell(c) for c in six[t]] for t in range(2)},
        "twelve_sector": {
            TORQUE_SIGNS[t] + FLUX_SIGNS[f]: [cell(c) for c in twelve[t][f]]
            for t in range(2)
            for f in range(2)
        },
    }


def load_candidate_tables(path: str | Path = CANDIDATE_TABLES_FILE) -> CandidateTables:
    """Read candidate tables as written by ``predictive-drive analyze --write-tables``."""
    path = Path(path)

    def sets(cells: list[Any]) -> tuple[tuple[int, ...], ...]:
        return tuple(tuple(sorted(int(v) for v in cell)) for cell in cells)

    try:
        doc = json.loads(path.read_text())
        six = tuple(sets(doc["six_sector"][t]) for t in TORQUE_SIGNS)
        twelve = tuple(
            tuple(sets(doc["twelve_sector"][t + f]) for f in FLUX_SIGNS) for t in TORQUE_SIGNS
        )
    except (OSError, ValueError, KeyError, TypeError) as e:
        raise ConfigError(f"{path}: not a candidate table file ({e})") from None
    if any(len(row) != 6 for row in six) or any(len(r) != 12 for t in twelve for r in t):
        raise ConfigError(f"{path}: need 6 sectors per six_sector row and 12 per twelve_sector row")
    for cell in [c for row in six for c in row] + [c for t in twelve for r in t for c in r]:
        if not cell or cell[0] != 0 or any(not 0 <= v <= 6 for v in cell):
            raise ConfigError(
                f"{path}: candidate sets must be subsets of V0..V6 holding V0 (strategies 2 and 3 "
                f"always keep the zero vector), got {list(cell)}"
            )
    return CandidateTables(six, twelve, doc.get("rule", ""), doc.get("source", ""))


TABLES = load_candidate_tables()
