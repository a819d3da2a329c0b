"""The drive plant: inverter + machine + mechanics, advanced one control period per command.

Each period is split into the command's piecewise-constant switching segments (SPEC §2.1) and each
segment is integrated with the integrator passed in (RK4 with sub-steps of at most ``max_substep``).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from .inverter import clarke, segments
from .motors import IM_STATE, InductionCoefficients, InductionMotor, induction_rk4
from .profiles import StepProfile
from .signals import Command, State

__all__ = ["InductionPlant", "rk4"]

Dynamics = Callable[[float, Any, Any, Any], Any]
TWO_PI = 2.0 * math.pi


def rk4(f: Dynamics) -> Callable[..., tuple]:
    """Classic 4th-order Runge-Kutta of ``f(t, x, u, c)``: returns ``integrate(t, x, u, c, h, n)``."""

    def integrate(t: float, x: tuple, u: Any, c: Any, h: float, n: int) -> tuple:
        return _rk4(f, t, x, u, c, h, n)

    return integrate


def _rk4(f: Dynamics, t: float, x: tuple, u: Any, c: Any, h: float, n: int) -> tuple:
    dt = h / n
    half = 0.5 * dt
    sixth = dt / 6.0
    for _ in range(n):
        k1 = f(t, x, u, c)
        k2 = f(t + half, tuple(a + half * b for a, b in zip(x, k1)), u, c)
        k3 = f(t + half, tuple(a + half * b for a, b in zip(x, k2)), u, c)
        k4 = f(t + dt, tuple(a + dt * b for a, b in zip(x, k3)), u, c)
        x = tuple(
            a + sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
            for a, b1, b2, b3, b4 in zip(x, k1, k2, k3, k4)
        )
        t += dt
    return x


class InductionPlant:
    """Induction motor on a two-level inverter with a stepped load (SPEC §2.1, §2.2, §2.4).

    ``step(command)`` applies command k for one period Ts and returns state k+1. Initial state: all
    zero (de-energised machine at standstill), switches 000.
    """

    def __init__(
        self,
        motor: InductionMotor,
        *,
        ts: float,
        u_dc: float,
        load: StepProfile,
        max_substep: float,
        integrator: Callable[..., tuple] = induction_rk4,
    ) -> None:
        self.motor = motor
        self.ts = ts
        self.u_dc = u_dc
        self._coef = InductionCoefficients.of(motor)
        self._load = load.sampled(ts)
        self._max_substep = max_substep
        self._integrate = integrator
        self._volts = {s: u_dc * clarke(*s) for s in _ALL_STATES}
        self.k = 0
        self.x: tuple = (0j, 0j, 0.0, 0.0)
        self.switches = (0, 0, 0)
        self._transitions = 0

    def state(self) -> State:
        """The present state k as published (measured channels + truth)."""
        i, psi, w, th = self.x
        c = self._coef
        te = c.torque_k * (psi.real * i.imag - psi.imag * i.real)
        return State(
            float(self.k),
            self.k * self.ts,
            i.real,
            i.imag,
            w,
            (c.p * th) % TWO_PI,
            self.u_dc,
            te,
            psi.real,
            psi.imag,
            th,
            self._load.at(self.k),
            float(self._transitions),
        )

    def step(self, command: Command) -> State:
        if int(command.k) != self.k:
            raise ValueError(f"plant is at step {self.k} but got the command for step {command.k}")
        segs, self.switches, self._transitions = segments(command[2:8], self.switches)
        ts = self.ts
        t = self.k * ts
        load = self._load.at(self.k)  # constant over the period
        x = self.x
        volts, coef, integrate, max_sub = (
            self._volts,
            self._coef,
            self._integrate,
            self._max_substep,
        )
        for sw, frac in segs:
            h = frac * ts
            n = 1 if h <= max_sub else math.ceil(h / max_sub - 1e-9)
            x = integrate(t, x, (volts[sw], load), coef, h, n)
            t += h
        self.x = x
        self.k += 1
        return self.state()

    @property
    def i_s(self) -> complex:
        return self.x[IM_STATE.i_s]

    @property
    def psi_s(self) -> complex:
        return self.x[IM_STATE.psi_s]


_ALL_STATES = [(a, b, c) for a in (0, 1) for b in (0, 1) for c in (0, 1)]
