"""Outer speed loop: discrete PI with clamping anti-windup (docs/physics.md#speed-pi)."""

from __future__ import annotations

import math
from dataclasses import dataclass

from ...errors import ConfigError
from ..fields import check_fields, choice, quantity
from ..signals import Reference, State, new_record
from ..timebase import StepProfile

__all__ = ["SpeedPI", "SpeedPIParams"]

RPM = 2.0 * math.pi / 60.0  #: rad/s per r/min
#: the speed loop's timing (see :attr:`SpeedPIParams.speed_loop`)
SPEED_LOOPS = ("one_step", "immediate")


@dataclass(frozen=True)
class SpeedPIParams:
    """Speed PI and reference profile.

    kp in N·m/(rad/s), ki in N·m/(rad/s)/s (the papers give no units; docs/physics.md#speed-pi: the error in
    rad/s and the integrator advancing by ki·Ts·e per step). torque_limit in N·m, flux_ref in Wb,
    speed_times in s, speed_values_rpm in r/min (converted to rad/s internally).
    """

    kp: float = quantity("proportional gain", "N·m/(rad/s)", ge=0)
    ki: float = quantity("integral gain (integrator += ki·Ts·e per step)", "N·m/rad", ge=0)
    torque_limit: float = quantity("T* saturates at ± this", "N·m", gt=0)
    flux_ref: float = quantity("stator-flux reference ψ*", "Wb", gt=0)
    speed_times: tuple[float, ...] = quantity("times of the speed-reference steps", "s", ge=0)
    speed_values_rpm: tuple[float, ...] = quantity("speed reference from each time on", "r/min")
    torque_times: tuple[float, ...] = quantity(
        "times of the torque-reference steps: with them T* follows torque_values and the PI is "
        "not run (torque control, as on a test bench whose load machine holds the speed)",
        "s",
        ge=0,
        default=(),
    )
    torque_values: tuple[float, ...] = quantity(
        "torque reference T* from each of torque_times on", "N·m", default=()
    )
    speed_loop: str = choice(
        "when the T* computed from state k applies: one_step (at step k+1: the graph's "
        "documented one-sample delay) or immediate (at step k: the controller waits for it)",
        SPEED_LOOPS,
        default="one_step",
    )

    def __post_init__(self) -> None:
        check_fields(self)
        self.speed_profile()  # validates
        if self.torque_times or self.torque_values:
            self.torque_profile()  # validates
            if any(abs(v) > self.torque_limit for v in self.torque_values):
                raise ConfigError(
                    f"speed_pi.torque_values: {list(self.torque_values)} N·m reach beyond "
                    f"torque_limit {self.torque_limit:g} N·m"
                )

    @property
    def torque_control(self) -> bool:
        """T* follows a torque profile; the speed PI is not run."""
        return bool(self.torque_times)

    def torque_profile(self) -> StepProfile:
        return StepProfile(tuple(self.torque_times), tuple(self.torque_values))

    def speed_profile(self) -> StepProfile:
        return StepProfile(tuple(self.speed_times), tuple(v * RPM for v in self.speed_values_rpm))


class SpeedPI:
    """T*(k) = sat(Kp·e(k) + I(k)), I(k+1) = I(k) + Ki·Ts·e(k) unless the output saturates in the
    direction of e (clamping anti-windup). ψ* is constant. With a torque profile
    (``torque_times``) T*(k) is the profile's and the PI is not run: torque control.

    The loop's timing lives here. ``one_step`` (the default, the graph's documented one-sample
    delay): ``step(state k)`` returns the reference for step k+1, and ``initial()`` is the
    reference for step 0 (T* = 0). ``immediate``: ``step(state k)`` returns the reference for
    step k itself (the same T*, applied one step earlier); there is no initial reference.
    """

    def __init__(self, params: SpeedPIParams, *, ts: float) -> None:
        self.params = params
        self.ts = ts
        self._speed = params.speed_profile().sampled(ts)
        self._consts = (params.kp, params.ki * ts, params.torque_limit, params.flux_ref)
        self.integral = 0.0
        self.immediate = params.speed_loop == "immediate"
        self._lag = 0 if self.immediate else 1  #: the step a reference from state k is for: k + lag
        self._torque = params.torque_profile().sampled(ts) if params.torque_control else None

    def initial(self) -> Reference:
        t0 = 0.0 if self._torque is None else self._torque.at(0)
        return Reference(0.0, 0.0, t0, self.params.flux_ref, self._speed.at(0))

    def step(self, state: State) -> Reference:
        k = int(state.k)
        if self._torque is not None:  # torque control: T* is the profile's
            k1 = k + self._lag
            t_ref, flux_ref = self._torque.at(k1), self.params.flux_ref
            return new_record(
                Reference, (float(k1), k1 * self.ts, t_ref, flux_ref, self._speed.at(k1))
            )
        at = self._speed.at
        kp, ki_ts, lim, flux_ref = self._consts
        e = at(k) - state.omega_m
        raw = kp * e + self.integral
        if raw > lim:
            out, saturated = lim, e > 0
        elif raw < -lim:
            out, saturated = -lim, e < 0
        else:
            out, saturated = raw, False
        if not saturated:
            self.integral += ki_ts * e
        k1 = k + self._lag
        return new_record(Reference, (float(k1), k1 * self.ts, out, flux_ref, at(k1)))
