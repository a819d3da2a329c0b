"""A run as columns: the state, reference and command records of every step, in step order, and
the plant's losses where it booked them.

Both engines and the bag reader produce a :class:`Trace`; the metrics read only this.
"""

from __future__ import annotations

import dataclasses
import struct
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from .signals import EXTERNAL, Command, Losses, Reference, State

__all__ = ["RECORDS", "Trace", "TraceBuilder", "no_losses"]

#: record name → its fields, in wire order
RECORDS: dict[str, tuple[str, ...]] = {
    "state": State._fields,
    "reference": Reference._fields,
    "command": Command._fields,
    "losses": Losses._fields,
}


@dataclass
class Trace:
    """Rows indexed by step k: states 0..n, references 0..n, commands 0..n-1; the plant's losses
    0..n where it booked them (none: no rows)."""

    ts: float
    state: np.ndarray
    reference: np.ndarray
    command: np.ndarray
    strategy_names: tuple[str, ...] = ()
    #: the name of the strategy of commands without an index: a controller of one's own
    external: str = EXTERNAL
    losses: np.ndarray = dataclasses.field(default_factory=lambda: no_losses())

    def col(self, record: str, name: str) -> np.ndarray:
        """The column of field ``name`` of ``record`` (state, reference, command or losses)."""
        rows: np.ndarray = getattr(self, record)
        return rows[:, RECORDS[record].index(name)]

    @property
    def has_losses(self) -> bool:
        """The run booked its losses and temperatures (``plant.losses`` on)."""
        return len(self.losses) > 0

    def truth(self, name: str) -> np.ndarray:
        """The true value of a measured state field (``i_alpha``, ``i_beta``, ``omega_m``,
        ``theta_e``): its ``<name>_true`` column, or the field itself in a recording made before
        the state carried the truth (there the two were one)."""
        true = self.col("state", f"{name}_true")
        return true if np.isfinite(true).all() else self.col("state", name)

    @property
    def steps(self) -> int:
        return int(self.command.shape[0])


def no_losses() -> np.ndarray:
    """The losses of a run that booked none: no rows."""
    return np.empty((0, len(Losses._fields)))


class TraceBuilder:
    """Collects records packed as little-endian doubles, one buffer per record kind, so a long run
    keeps no Python float or tuple alive per step; :meth:`build` views them as 2-D arrays."""

    def __init__(self, ts: float, strategy_names: tuple[str, ...] = ()) -> None:
        self.ts = ts
        self.strategy_names = strategy_names
        self.buffers = {name: bytearray() for name in RECORDS}
        self._packers = {
            name: struct.Struct(f"<{len(fields)}d") for name, fields in RECORDS.items()
        }

    def packer(self, record: str) -> tuple[Callable[[bytes], None], Callable[..., bytes]]:
        """``(add, pack)`` for hot loops: ``add(pack(*row))`` appends one ``record`` row
        (struct.error if the row is not as wide as the record)."""
        return self.buffers[record].extend, self._packers[record].pack

    def add(self, record: str, row: tuple[float, ...]) -> None:
        """Append one record; records of each kind must arrive in step order from 0."""
        self.buffers[record].extend(self._packers[record].pack(*row))

    def build(self) -> Trace:
        arrays = {}
        for name, fields in RECORDS.items():
            width = len(fields)
            # a copy: the builder's buffers stay growable and the trace owns writable arrays
            arr = np.frombuffer(self.buffers[name], dtype="<f8").reshape(-1, width).copy()
            if arr.shape[0] and not np.array_equal(arr[:, 0], np.arange(arr.shape[0])):
                raise ValueError(f"{name} records are not contiguous from step 0")
            arrays[name] = arr
        return Trace(
            self.ts,
            arrays["state"],
            arrays["reference"],
            arrays["command"],
            self.strategy_names,
            losses=arrays["losses"],
        )
