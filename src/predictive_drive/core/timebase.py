"""The run's timebase: simulated time ↔ step index, and step profiles on the step grid.

Step k samples at t = k·Ts. One rounding rule turns a time into a step everywhere (profiles,
metrics windows, switches, run lengths): :func:`step_index`.
"""

from __future__ import annotations

import bisect
import math
from dataclasses import dataclass

from ..errors import ConfigError

__all__ = ["SampledProfile", "StepProfile", "every_steps", "step_index"]


def step_index(t: float, ts: float) -> int:
    """The first step k whose sample instant k·Ts is at or after ``t`` (s). A time within 1e-9
    of a step (in steps) counts as on it, so t = k·Ts computed in floating point gives k."""
    return math.ceil(t / ts - 1e-9)


def every_steps(period: float, ts: float) -> int:
    """Decimation: a periodic event every ``period`` s of simulated time is every this many steps
    (at least 1)."""
    return max(1, round(period / ts))


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

    def sampled(self, ts: float) -> SampledProfile:
        """The profile on the step grid: each value from :func:`step_index` of its time on."""
        starts = tuple(step_index(t, ts) for t in self.times)
        return SampledProfile(starts, tuple(float(v) for v in self.values))


@dataclass(frozen=True)
class SampledProfile:
    """A step profile on the step grid: value at step k, exact and deterministic."""

    starts: tuple[int, ...]
    values: tuple[float, ...]

    def at(self, k: int) -> float:
        if k >= self.starts[-1]:
            return self.values[-1]
        return self.values[bisect.bisect_right(self.starts, k) - 1]
