"""What the field-oriented control families share (docs/physics.md#field-oriented-control-and-mtpa):
the dq current PIs and how they are tuned, the loop that closes them with the family's
decoupling, and the modulation — SVPWM with the dead-time and device-drop feed-forward.

A current PI is designed on the zero-order-hold model of one axis, i(k+1) = a·i(k) + b·u(k) with
a = e^{-R Ts/L}, b = (1 - a)/R (the controller's own R, L of the axis): the PI zero cancels the
pole, C(z) = kp (z - a)/(z - 1), so the nominal closed loop is first order, i(k+1) = i(k) +
K·(i* - i(k)), K = kp·b. In PI form: u = kp·e + I, I += kp(1 - a)·e per step. Two rules choose
kp (``current_tuning``):

- ``bandwidth``: K = 1 - e^{-2π f_c Ts}, the chosen bandwidth f_c exactly on the nominal model,
  whatever the period;
- ``technical_optimum``: kp = L/(2 T_σ), T_σ = 1.5 Ts (a period of computation and half a
  period of modulation): the textbook rule (Schröder), so the loop follows the period — K ≈ 1/3
  per period, the bandwidth about f_sw/16 — and a drive tuned so at any carrier is well tuned.

What the loop holds on the reference is the sampled current. Over a period the modulator applies
one voltage vector while the frame turns by ω Ts, so the current between the samples bows off
the sampled one: its period mean differs from the sample by a fixed share of the voltage
(:func:`mean_offset`, about jωTs²·u/(12 L)), 1.2 A of paper 000's 3.9 A at 0.5 kHz. A family
that aims the period's mean current instead (``current_target: period_mean``) adds that offset
to the measured current before the loop and its models see it.
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from ..fields import choice, quantity
from ..inverter import clarke, inverse_clarke
from ..signals import Command, State
from ..svpwm import Modulation, svpwm
from .base import Controller

__all__ = [
    "CURRENT_TARGETS",
    "CURRENT_TUNINGS",
    "CurrentPI",
    "DQCurrentLoop",
    "FieldOrientedController",
    "Modulator",
    "current_bandwidth",
    "current_pi",
    "current_pi_of",
    "current_target",
    "current_tuning",
    "dead_time_compensation",
    "drop_compensation",
    "mean_offset",
    "mean_offset_dq",
    "technical_optimum",
]

NAN = math.nan
TWO_PI = 2.0 * math.pi
#: how the current PIs are tuned (module text)
CURRENT_TUNINGS = ("bandwidth", "technical_optimum")
#: T_σ of the technical optimum, in periods: computation (1) and modulation (1/2)
T_SIGMA_PERIODS = 1.5


@dataclass(frozen=True)
class CurrentPI:
    """Gains of one axis: u = kp·e + I, I += ki·e per step (see the module's text)."""

    kp: float  #: V/A
    ki: float  #: V/A per step
    pole: float  #: a = e^{-R Ts/L}: the open-loop pole the PI zero cancels
    gain: float  #: K = kp·b: the nominal closed loop's step per period


def _pole_cancelling(r: float, ind: float, ts: float, kp: float) -> CurrentPI:
    a = math.exp(-r * ts / ind)
    b = (1.0 - a) / r
    return CurrentPI(kp=kp, ki=kp * (1.0 - a), pole=a, gain=kp * b)


def current_pi(*, r_s: float, l_s: float, ts: float, bandwidth_hz: float) -> CurrentPI:
    """Pole-cancelling discrete PI of an R-L axis (R_s in Ω, L in H, Ts in s) for a first-order
    closed loop at the bandwidth (Hz)."""
    a = math.exp(-r_s * ts / l_s)
    b = (1.0 - a) / r_s
    k = 1.0 - math.exp(-TWO_PI * bandwidth_hz * ts)
    return CurrentPI(kp=k / b, ki=k * (1.0 - a) / b, pole=a, gain=k)


def technical_optimum(*, r: float, ind: float, ts: float) -> CurrentPI:
    """Pole-cancelling discrete PI of an R-L axis (R in Ω, inductance in H) with
    kp = L/(2 T_σ), T_σ = 1.5 Ts."""
    return _pole_cancelling(r, ind, ts, ind / (2.0 * T_SIGMA_PERIODS * ts))


def current_pi_of(
    tuning: str, *, r: float, ind: float, ts: float, bandwidth_hz: float
) -> CurrentPI:
    """The PI of one axis (R in Ω, inductance in H) by the rule ``tuning``
    (:data:`CURRENT_TUNINGS`)."""
    if tuning == "technical_optimum":
        return technical_optimum(r=r, ind=ind, ts=ts)
    return current_pi(r_s=r, l_s=ind, ts=ts, bandwidth_hz=bandwidth_hz)


def mean_offset(u: complex, *, w: float, ts: float, r: float, ind: float) -> complex:
    """How far the period's mean current lies from its sample (A, the frame's dq) when the
    voltage ``u`` (V, dq at the period's middle) is held in αβ over the period while the frame
    turns at ``w`` (rad/s), on an axis of resistance ``r`` (Ω) and inductance ``ind`` (H) in the
    periodic steady state: L di/dτ = u·e^{-jwτ} - (R + jwL)·i - e, τ from -Ts/2 to Ts/2, e
    constant. With a = (R + jwL)/L, g = 1/(L(a - jw)), x = wTs/2 and the particular solution's
    rise over the period Δ = -2j·sin(x)·g·u, it is g·u·(sin x/x - e^{-jx}) + Δ·(1/(aTs) -
    e^{-aTs/2}/(2 sinh(aTs/2))): jwTs²·u/(12 L) to first order."""
    a = complex(r, w * ind) / ind
    x = 0.5 * w * ts
    g = u / (ind * (a - 1j * w))
    rise = -2j * math.sin(x) * g
    at = a * ts
    sinc = math.sin(x) / x if x else 1.0
    return g * (sinc - cmath.exp(-1j * x)) + rise * (
        1.0 / at - cmath.exp(-0.5 * at) / (2.0 * cmath.sinh(0.5 * at))
    )


def mean_offset_dq(u: complex, *, w: float, ts: float, r: float, l_d: float, l_q: float) -> complex:
    """:func:`mean_offset` of a machine whose axes differ (a salient PMSM): the d part as if both
    axes were L_d, the q part as if both were L_q (exact when L_d = L_q; for L_d ≠ L_q the
    first-order term jωTs²u/12 divided axis by axis)."""
    d = mean_offset(u, w=w, ts=ts, r=r, ind=l_d)
    return d if l_d == l_q else complex(d.real, mean_offset(u, w=w, ts=ts, r=r, ind=l_q).imag)


#: what the current loop holds on the reference: the sample, or the period's mean current
CURRENT_TARGETS = ("period_mean", "sample")


def current_target(default: str) -> Any:
    """The ``current_target`` field of a field-oriented family (the module's text)."""
    return choice(
        "what the current loop holds on the reference: period_mean (the sample moved by the "
        "offset the period's single voltage vector leaves between the samples) or sample",
        CURRENT_TARGETS,
        default=default,
    )


def current_bandwidth(default: float) -> Any:
    """The ``current_bandwidth_hz`` field of a field-oriented family."""
    return quantity(
        "current-loop bandwidth (first order on the nominal model; current_tuning: bandwidth)",
        "Hz",
        gt=0,
        default=default,
    )


def current_tuning(default: str) -> Any:
    """The ``current_tuning`` field of a field-oriented family."""
    return choice(
        "how the current PIs are tuned: bandwidth (current_bandwidth_hz, whatever Ts) or "
        "technical_optimum (kp = L/(2·1.5·Ts): the loop follows the period)",
        CURRENT_TUNINGS,
        default=default,
    )


def dead_time_compensation() -> Any:
    """The ``dead_time_compensation`` field of a family that modulates."""
    return quantity(
        "dead time the voltage feed-forward compensates: each phase's reference raised by "
        "sign(i)·(t_d/Ts·U_dc + drop) (0: none)",
        "s",
        ge=0,
        default=0.0,
    )


def drop_compensation() -> Any:
    """The ``drop_compensation`` field of a family that modulates."""
    return quantity(
        "device drop the voltage feed-forward compensates (with dead_time_compensation)",
        "V",
        ge=0,
        default=0.0,
    )


class DQCurrentLoop:
    """A PI per dq axis with the family's decoupling added, the voltage limited to a circle with
    clamping anti-windup. The decoupling is given the current the closed loop will have at the
    middle of the period the voltage acts over, i + K/2·(i* - i): with the sampled current
    instead, the coupling left over lets the d and q responses differ, so a rotating reference
    makes the current's amplitude ripple."""

    def __init__(self, d: CurrentPI, q: CurrentPI) -> None:
        self.d, self.q = d, q
        self.integral = 0j  #: the integrators, V (d + j·q)

    def voltage_with(
        self,
        i_ref: complex,
        i_dq: complex,
        u_max: float,
        decoupling: Callable[[complex], complex],
    ) -> complex:
        """u_dq (V) for the coming period from the reference and measured currents (A), the
        voltage limit (V) and ``decoupling(i_mid)`` (V, the feed-forward of the family)."""
        pd, pq = self.d, self.q
        e = i_ref - i_dq
        i_m = i_dq + complex(0.5 * pd.gain * e.real, 0.5 * pq.gain * e.imag)
        ff = decoupling(i_m)
        u = complex(
            pd.kp * e.real + self.integral.real + ff.real,
            pq.kp * e.imag + self.integral.imag + ff.imag,
        )
        mag = abs(u)
        if mag > u_max:
            return u * (u_max / mag)  # limited: the integrators hold (clamping anti-windup)
        self.integral += complex(pd.ki * e.real, pq.ki * e.imag)
        return u


class Modulator:
    """SVPWM of a voltage reference, with the dead-time and drop feed-forward: each phase's
    voltage raised by what the inverter loses in the direction of its current
    (docs/physics.md#dead-time-and-device-drops)."""

    def __init__(self, *, ts: float, dead_time: float, drop: float) -> None:
        self._ff_time = dead_time / ts  #: share of Ts to feed forward
        self._ff_drop = drop

    def feed_forward(self, state: State) -> complex:
        """The dead-time and drop feed-forward (αβ, V) for the measured currents."""
        v = self._ff_time * state.u_dc + self._ff_drop
        sign = [(x > 0.0) - (x < 0.0) for x in inverse_clarke(complex(state.i_alpha, state.i_beta))]
        return clarke(sign[0] * v, sign[1] * v, sign[2] * v)

    def modulate(self, u_ab: complex, state: State) -> tuple[Modulation, complex]:
        """The pulses for ``u_ab`` (V, αβ) and the voltage the machine gets (the inverter's loss
        made good)."""
        if self._ff_time or self._ff_drop:
            ff = self.feed_forward(state)
            mod = svpwm(u_ab + ff, state.u_dc)
            return mod, mod.applied - ff
        mod = svpwm(u_ab, state.u_dc)
        return mod, mod.applied


class FieldOrientedController(Controller):
    """The FOC families' command: the law's αβ voltage (V) modulated by the :class:`Modulator`
    ``_modulator``, with the diagnostics every FOC command carries — no finite-control-set
    decision, the estimate (``est_torque``, ``est_flux``, ``est_flux_angle``), the current
    reference ``i_ref`` (A, dq) and what :meth:`_mtpa` adds. ``u_ab`` is the voltage the machine
    got over the last period."""

    _modulator: Modulator
    i_ref: complex
    u_ab: complex
    est_torque: float
    est_flux: float
    est_flux_angle: float

    def _cal(self) -> float:
        """The command's ``cal``: no vector predicted (a law that searches says how much)."""
        return 0.0

    def _mtpa(self) -> tuple[float, float]:
        """(current angle from the q axis, rad; the MTPA gradient, 1/rad): NaN without MTPA."""
        return NAN, NAN

    def _command(self, u_ab: complex, state: State, compute_ns: float) -> Command:
        mod, self.u_ab = self._modulator.modulate(u_ab, state)
        angle, gradient = self._mtpa()
        diagnostics = (
            NAN,  # vector: no finite-control-set decision
            NAN,  # duty
            NAN,  # t_u
            self._cal(),
            self.law_horizon,
            self.est_torque,
            self.est_flux,
            self.est_flux_angle,
            angle,
            self.i_ref.real,
            self.i_ref.imag,
            gradient,
        )
        return self.command(state, mod.pulses, diagnostics, compute_ns)
