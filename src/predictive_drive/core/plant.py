"""The drive plant: inverter + machine + mechanics, advanced one control period per command.

Each period is split into the command's piecewise-constant switching segments
(docs/physics.md#the-inverter-and-the-command) and each segment is integrated with the integrator
passed in, in sub-steps of at most ``max_substep`` (the IM's exact discretisation for frozen ω, the
PMSM's fused RK4).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any

from .inverter import clarke, segments
from .machines import Machine
from .machines.induction import IM_STATE, InductionCoefficients, InductionMotor, induction_exact
from .machines.pmsm import PMSM, PMSM_STATE, PMSMCoefficients, pmsm_rk4
from .signals import COMMAND_INDEX, PULSES, State, new_record
from .timebase import StepProfile

__all__ = ["PLANTS", "InductionPlant", "InverterPlant", "PMSMPlant", "make_plant", "rk4"]

Dynamics = Callable[[float, Any, Any, Any], Any]
TWO_PI = 2.0 * math.pi
_K = COMMAND_INDEX.k
_IM_I, _IM_PSI, _IM_W, _IM_TH = IM_STATE.i_s, IM_STATE.psi_s, IM_STATE.omega_m, IM_STATE.theta_m
_PM_I, _PM_W, _PM_TH = PMSM_STATE.i_dq, PMSM_STATE.omega_m, PMSM_STATE.theta_m


def rk4(f: Dynamics) -> Callable[..., tuple[Any, ...]]:
    """Classic 4th-order Runge-Kutta of ``f(t, x, u, c)``: returns ``integrate(t, x, u, c, h, n)``."""

    def integrate(
        t: float, x: tuple[Any, ...], u: Any, c: Any, h: float, n: int
    ) -> tuple[Any, ...]:
        return _rk4(f, t, x, u, c, h, n)

    return integrate


def _rk4(
    f: Dynamics, t: float, x: tuple[Any, ...], u: Any, c: Any, h: float, n: int
) -> tuple[Any, ...]:
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


class InverterPlant:
    """A machine on a two-level inverter with a stepped load
    (docs/physics.md#the-inverter-and-the-command; docs/physics.md#mechanics-and-load).

    ``step(command)`` applies command k for one period Ts and returns state k+1: each switching segment
    is integrated with ``integrator`` (default: the machine's own, see above) in sub-steps of at most
    ``max_substep``. Subclasses name the machine's coefficients, initial state and integrator, and
    say what the state publishes. Initial switches: 000.
    """

    coefficients: Any  #: class with ``of(motor)``: the machine's precomputed constants
    x0: tuple[Any, ...]  #: initial state
    default_integrator: Callable[..., tuple[Any, ...]]

    def __init__(
        self,
        motor: Any,
        *,
        ts: float,
        u_dc: float,
        load: StepProfile,
        max_substep: float,
        integrator: Callable[..., tuple[Any, ...]] | None = None,
    ) -> None:
        self.motor = motor
        self.ts = ts
        self.u_dc = u_dc
        self._coef = self.coefficients.of(motor)
        self._load = load.sampled(ts)
        self._max_substep = max_substep
        self._integrate = integrator or type(self).default_integrator
        self._volts = {s: u_dc * clarke(*s) for s in _ALL_STATES}
        self.k = 0
        self.load = self._load.at(0)  #: N·m, load torque during the coming period k
        self.x: tuple[Any, ...] = self.x0
        self.switches = (0, 0, 0)
        self._transitions = 0

    def _outputs(self) -> tuple[complex, float, float, float, complex, float]:
        """(i_s αβ, ω_m, θ_e wrapped, T_e, ψ_s αβ, θ_m) of the present state."""
        raise NotImplementedError

    def state(self) -> State:
        """The present state k as published (measured channels + truth)."""
        i, w, the, te, psi, th = self._outputs()
        return new_record(
            State,
            (
                float(self.k),
                self.k * self.ts,
                i.real,
                i.imag,
                w,
                the,
                self.u_dc,
                te,
                psi.real,
                psi.imag,
                th,
                self.load,
                float(self._transitions),
            ),
        )

    def step(self, command: Sequence[float]) -> State:
        """Apply ``command`` (a :class:`Command`, or its row of numbers) for one period."""
        if command[_K] != self.k:  # k as float
            raise ValueError(
                f"plant is at step {self.k} but got the command for step {command[_K]:g}"
            )
        segs, self.switches, self._transitions = segments(command[PULSES], self.switches)
        ts = self.ts
        t = self.k * ts
        load = self.load  # constant over the period
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
        self.load = self._load.at(self.k)
        return self.state()


class InductionPlant(InverterPlant):
    """Induction motor (docs/physics.md#induction-motor); state (i_s, ψ_s, ω_m, θ_m), initially all
    zero (de-energised, at standstill)."""

    motor: InductionMotor
    coefficients = InductionCoefficients
    x0 = (0j, 0j, 0.0, 0.0)
    default_integrator = staticmethod(induction_exact)

    def _outputs(self) -> tuple[complex, float, float, float, complex, float]:
        x = self.x
        i, psi, w, th = x[_IM_I], x[_IM_PSI], x[_IM_W], x[_IM_TH]
        c = self._coef
        te = c.torque_k * (psi.real * i.imag - psi.imag * i.real)
        return i, w, (c.p * th) % TWO_PI, te, psi, th


class PMSMPlant(InverterPlant):
    """PMSM (docs/physics.md#pmsm); state (i_dq, ω_m, θ_m), initially no current, at standstill, θ_m = 0. The
    published currents and flux are turned into αβ with θ_e = p·θ_m."""

    motor: PMSM
    coefficients = PMSMCoefficients
    x0 = (0j, 0.0, 0.0)
    default_integrator = staticmethod(pmsm_rk4)

    def _outputs(self) -> tuple[complex, float, float, float, complex, float]:
        x = self.x
        i_dq, w, th = x[_PM_I], x[_PM_W], x[_PM_TH]
        c = self._coef
        the = c.p * th
        rot = complex(math.cos(the), math.sin(the))
        psi_dq = complex(c.l_d * i_dq.real + c.psi_f, c.l_q * i_dq.imag)
        te = c.torque_k * i_dq.imag * (c.psi_f + (c.l_d - c.l_q) * i_dq.real)
        return i_dq * rot, w, the % TWO_PI, te, psi_dq * rot, th


_ALL_STATES = [(a, b, c) for a in (0, 1) for b in (0, 1) for c in (0, 1)]

#: machine type → plant class
PLANTS: dict[str, type[InverterPlant]] = {
    Machine.INDUCTION: InductionPlant,
    Machine.PMSM: PMSMPlant,
}


def make_plant(
    machine: str, motor: Any, *, ts: float, u_dc: float, load: StepProfile, max_substep: float
) -> InverterPlant:
    """The plant of a machine type (every engine and the plant node alike)."""
    return PLANTS[machine](motor, ts=ts, u_dc=u_dc, load=load, max_substep=max_substep)
