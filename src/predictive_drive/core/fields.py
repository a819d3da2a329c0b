"""Parameter fields with their meaning, unit and allowed range, as dataclass field metadata.

Every parameter dataclass of a scenario declares its fields with :func:`quantity` (numbers) or
:func:`choice` (names). The same metadata validates the values (:func:`check_fields`, called from
``__post_init__``), words the errors (the field, the value and the allowed range), and describes
the ROS parameters the nodes declare (unit in the description, ``FloatingPointRange`` /
``IntegerRange``), so a range is stated once.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ..errors import ConfigError

__all__ = ["Quantity", "check_fields", "choice", "flag", "quantity", "spec_of"]

_KEY = "predictive_drive"


@dataclass(frozen=True)
class Quantity:
    """What a field means: ``description``, SI ``unit`` ('' for a pure number, a name or a flag),
    and the allowed range ``low``..``high`` (None: unbounded; ``open_low``: strictly above low).
    ``nan_default``: NaN stands for a default derived elsewhere (said in the text). ``choices``:
    the allowed names of a string field (empty: checked elsewhere, e.g. by a registry)."""

    description: str
    unit: str = ""
    low: float | None = None
    high: float | None = None
    open_low: bool = False
    nan_default: str = ""
    choices: tuple[str, ...] = ()
    integer: bool = False
    flag: bool = False  #: true or false

    def range_text(self) -> str:
        """The allowed values in words, e.g. '> 0', '>= 0', '0..1', 'one of a, b'."""
        if self.choices:
            return "one of " + ", ".join(self.choices)
        if self.flag:
            return "true or false"
        if self.integer and self.high is None and self.low is not None and not self.open_low:
            return f"an integer >= {self.low:g}"
        low = None if self.low is None else f"{'>' if self.open_low else '>='} {self.low:g}"
        if self.high is None:
            return low or ""
        if self.low is None:
            return f"<= {self.high:g}"
        return f"{self.low:g}..{self.high:g}" + (
            " (excluding the lower end)" if self.open_low else ""
        )

    def text(self) -> str:
        """One line for a ROS parameter description: meaning, unit, range."""
        parts = [self.description]
        if self.unit:
            parts.append(f"unit {self.unit}")
        if rng := self.range_text():
            parts.append(rng)
        if self.nan_default:
            parts.append(f"NaN: {self.nan_default}")
        return "; ".join(parts)

    def check(self, where: str, value: Any) -> None:
        """ConfigError naming ``where``, the value and the allowed range if ``value`` is outside."""
        if self.choices:
            if value not in self.choices:
                raise ConfigError(f"{where}: {value!r} is not {self.range_text()}")
            return
        if self.flag:
            if not isinstance(value, bool):
                raise ConfigError(f"{where} must be true or false, got {value!r}")
            return
        values = value if isinstance(value, tuple) else (value,)
        for v in values:
            if isinstance(v, str):
                return
            if isinstance(v, float) and math.isnan(v) and self.nan_default:
                continue
            ok = isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
            if self.integer:
                ok = isinstance(v, int) and not isinstance(v, bool)
            if ok and self.low is not None:
                ok = v > self.low if self.open_low else v >= self.low
            if ok and self.high is not None:
                ok = v <= self.high
            if not ok:
                unit = f" {self.unit}" if self.unit else ""
                rng = self.range_text()
                if self.integer:
                    want = rng or "an integer"
                else:
                    want = f"a finite number {rng}{unit}" if rng else f"a finite number{unit}"
                raise ConfigError(f"{where} must be {want}, got {v!r}")


def quantity(
    description: str,
    unit: str = "",
    *,
    gt: float | None = None,
    ge: float | None = None,
    le: float | None = None,
    integer: bool = False,
    nan_default: str = "",
    default: Any = dataclasses.MISSING,
) -> Any:
    """A numeric dataclass field (scalar or tuple of numbers) with its metadata."""
    if gt is not None and ge is not None:
        raise ValueError("give gt or ge, not both")
    q = Quantity(
        description,
        unit,
        low=gt if gt is not None else ge,
        high=le,
        open_low=gt is not None,
        nan_default=nan_default,
        integer=integer,
    )
    return _field(q, default)


def choice(
    description: str, choices: Sequence[str] = (), *, default: Any = dataclasses.MISSING
) -> Any:
    """A string field: one of ``choices`` (or, when empty, names checked elsewhere)."""
    return _field(Quantity(description, choices=tuple(choices)), default)


def flag(description: str, *, default: bool = False) -> Any:
    """A true/false field."""
    return _field(Quantity(description, flag=True), default)


def _field(q: Quantity, default: Any) -> Any:
    if default is dataclasses.MISSING:
        return dataclasses.field(metadata={_KEY: q})
    return dataclasses.field(default=default, metadata={_KEY: q})


def spec_of(f: dataclasses.Field[Any]) -> Quantity | None:
    """The metadata of a field declared with :func:`quantity` or :func:`choice`, else None."""
    q = f.metadata.get(_KEY)
    return q if isinstance(q, Quantity) else None


def check_fields(obj: Any) -> None:
    """Check every field of a dataclass instance against its metadata (call in __post_init__).
    An error names the field as a user writes it (the key, not the class): whoever reads the
    value from a file or an option puts where it came from in front (``config`` does)."""
    for f in dataclasses.fields(obj):
        q = spec_of(f)
        if q is not None:
            q.check(f.name, getattr(obj, f.name))
