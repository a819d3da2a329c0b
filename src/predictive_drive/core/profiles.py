"""Piecewise-constant step profiles of simulated time (load torque, speed reference)."""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

from ..errors import ConfigError

__all__ = ["StepProfile"]


@dataclass(frozen=True)
class StepProfile:
    """value(t) = values[i] for times[i] <= t < times[i+1]; times[0] must be 0, times increasing."""

    times: tuple[float, ...]
    values: tuple[float, ...]

    def __post_init__(self) -> None:
        if len(self.times) == 0 or len(self.times) != len(self.values):
            raise ConfigError(
                f"step profile needs equally many times and values (at least one), got "
                f"{len(self.times)} times and {len(self.values)} values"
            )
        if self.times[0] != 0.0:
            raise ConfigError(f"step profile must start at time 0, got times[0] = {self.times[0]}")
        if any(b <= a for a, b in zip(self.times, self.times[1:])):
            raise ConfigError(f"step profile times must increase strictly, got {list(self.times)}")
        if not all(math.isfinite(v) for v in (*self.times, *self.values)):
            raise ConfigError("step profile times and values must be finite numbers")

    def step_indices(self, ts: float) -> tuple[int, ...]:
        """First step index at which each value is in force (robust to t = k·Ts rounding)."""
        return tuple(math.ceil(t / ts - 1e-9) for t in self.times)

    def sampled(self, ts: float) -> SampledProfile:
        return SampledProfile(self.step_indices(ts), tuple(float(v) for v in self.values))


@dataclass(frozen=True)
class SampledProfile:
    """A step profile on the step grid: value at step k, exact and deterministic."""

    starts: tuple[int, ...]
    values: tuple[float, ...]

    def at(self, k: int) -> float:
        if k >= self.starts[-1]:
            return self.values[-1]
        return self.values[bisect.bisect_right(self.starts, k) - 1]
