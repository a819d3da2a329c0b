"""A scenario: every parameter of one run, as frozen dataclasses grouped by the node that owns them."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..errors import ConfigError
from .control import InductionControllerParams, Machine, PMSMControllerParams
from .motors import PMSM, InductionMotor
from .profiles import StepProfile
from .speed_pi import SpeedPIParams

__all__ = ["LoggerParams", "PlantParams", "RunParams", "Scenario"]


@dataclass(frozen=True)
class RunParams:
    """Shared by every node. ts: control period, s; duration: simulated length, s."""

    scenario: str
    machine: str
    ts: float
    duration: float

    def __post_init__(self) -> None:
        if self.machine not in [m.value for m in Machine]:
            raise ConfigError(
                f"machine: {self.machine!r} is not one of {', '.join(m.value for m in Machine)}"
            )
        for name in ("ts", "duration"):
            v = getattr(self, name)
            if not (math.isfinite(v) and v > 0):
                raise ConfigError(f"{name} must be a positive number of seconds, got {v!r}")

    @property
    def steps(self) -> int:
        return round(self.duration / self.ts)


@dataclass(frozen=True)
class PlantParams:
    """Plant: machine, inverter (u_dc in V), load steps (times in s, values in N·m), RK4 sub-step (s)."""

    motor: InductionMotor | PMSM
    u_dc: float
    load_times: tuple[float, ...]
    load_values: tuple[float, ...]
    max_substep: float

    def __post_init__(self) -> None:
        if not (math.isfinite(self.u_dc) and self.u_dc > 0):
            raise ConfigError(f"plant.u_dc must be a positive voltage, got {self.u_dc!r}")
        if not (math.isfinite(self.max_substep) and self.max_substep > 0):
            raise ConfigError(
                f"plant.max_substep must be a positive time, got {self.max_substep!r}"
            )
        self.load_profile()

    def load_profile(self) -> StepProfile:
        return StepProfile(tuple(self.load_times), tuple(self.load_values))


@dataclass(frozen=True)
class LoggerParams:
    """Metrics window [window_start, window_end) in s (paper 000: 0.05-6 s). thd_window: [start,
    end] in s of the steady-state stretch whose phase-a current THD is reported (whole electrical
    cycles inside it), or empty for none."""

    window_start: float
    window_end: float
    thd_window: tuple[float, ...] = ()

    def __post_init__(self) -> None:
        if not (0 <= self.window_start < self.window_end):
            raise ConfigError(
                f"metrics_logger: need 0 <= window_start < window_end, got "
                f"{self.window_start}, {self.window_end}"
            )
        if self.thd_window and not (
            len(self.thd_window) == 2 and 0 <= self.thd_window[0] < self.thd_window[1]
        ):
            raise ConfigError(
                f"metrics_logger.thd_window must be [] or [start, end] with 0 <= start < end s, "
                f"got {list(self.thd_window)}"
            )


@dataclass(frozen=True)
class Scenario:
    run: RunParams
    plant: PlantParams
    speed_pi: SpeedPIParams
    controller: InductionControllerParams | PMSMControllerParams
    logger: LoggerParams
    source: str = ""

    @property
    def name(self) -> str:
        return self.run.scenario

    @property
    def ts(self) -> float:
        return self.run.ts

    @property
    def machine(self) -> Machine:
        return Machine(self.run.machine)
