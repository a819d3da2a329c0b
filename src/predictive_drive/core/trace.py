"""A run as columns: the state, reference and command records of every step, in step order.

Both engines and the bag reader produce a :class:`Trace`; the metrics read only this.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np

from .signals import Command, Reference, State

__all__ = ["RECORDS", "Trace", "TraceBuilder"]

#: record name → field tuple type
RECORDS = {"state": State, "reference": Reference, "command": Command}


@dataclass
class Trace:
    """Rows indexed by step k: states 0..n, references 0..n, commands 0..n-1."""

    ts: float
    state: np.ndarray
    reference: np.ndarray
    command: np.ndarray
    strategy_names: tuple[str, ...] = ()

    def col(self, record: str, name: str) -> np.ndarray:
        return getattr(self, record)[:, RECORDS[record]._fields.index(name)]

    @property
    def steps(self) -> int:
        return int(self.command.shape[0])


@dataclass
class TraceBuilder:
    ts: float
    strategy_names: tuple[str, ...] = ()
    rows: dict[str, list[tuple[float, ...]]] = field(
        default_factory=lambda: {name: [] for name in RECORDS}
    )

    def add(self, record: str, row: tuple[float, ...]) -> None:
        """Append one record; records of each kind must arrive in step order from 0."""
        self.rows[record].append(row)

    def build(self) -> Trace:
        arrays = {}
        for name, cls in RECORDS.items():
            rows = self.rows[name]
            width = len(cls._fields)
            arr = np.fromiter(
                itertools.chain.from_iterable(rows), dtype=np.float64, count=len(rows) * width
            ).reshape(-1, width)
            if arr.shape[0] and not np.array_equal(arr[:, 0], np.arange(arr.shape[0])):
                raise ValueError(f"{name} records are not contiguous from step 0")
            arrays[name] = arr
        return Trace(
            self.ts, arrays["state"], arrays["reference"], arrays["command"], self.strategy_names
        )
