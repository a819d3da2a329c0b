"""Space-vector PWM: a voltage reference u*_αβ per period → centre-aligned per-phase pulses in the
command format every plant understands (docs/physics.md#the-inverter-and-the-command;
docs/physics.md#field-oriented-control-and-mtpa).

The phase references are the inverse (amplitude-invariant) Clarke transform of u*; the min-max
zero sequence v0 = -(max + min)/2 centres them in the DC link, which is what symmetric SVPWM with
equal V0/V7 times does. Leg x is high for the duty d_x = 1/2 + (v_x + v0)/U_dc of the period,
centred in it (rising at (1 - d_x)/2·Ts), so the period starts and ends on V0 and the volt-seconds
it applies are Ts·u* exactly (the common mode cancels in the Clarke transform). Inside the
hexagon this holds for any u*; outside, u* is scaled back onto the hexagon's edge, which keeps its
direction (over-modulation by minimum-phase-error clamping).
"""

from __future__ import annotations

import math
from typing import NamedTuple

from .signals import PhasePulses, new_record

__all__ = ["Modulation", "inverse_clarke", "linear_limit", "svpwm"]

_C = math.cos(2.0 * math.pi / 3.0)  # -1/2
_S = math.sin(2.0 * math.pi / 3.0)  # √3/2


class Modulation(NamedTuple):
    """One period's modulation: the pulses, the voltage they apply (V, αβ: u* or its clamped
    value) and whether u* lay outside the hexagon."""

    pulses: PhasePulses
    applied: complex
    clamped: bool


def inverse_clarke(u: complex) -> tuple[float, float, float]:
    """Phase values (v_a, v_b, v_c) of an αβ vector, amplitude-invariant: v_x = Re(u·e^{-j·φ_x})
    with φ = 0, 120°, 240°; zero-sequence free."""
    ua, ub = u.real, u.imag
    return ua, _C * ua + _S * ub, _C * ua - _S * ub


def linear_limit(u_dc: float) -> float:
    """The largest |u*| every direction can have without clamping: the circle inscribed in the
    hexagon, U_dc/√3 (V)."""
    return u_dc / math.sqrt(3.0)


def svpwm(u: complex, u_dc: float) -> Modulation:
    """Centre-aligned pulses applying ``u`` (V, αβ) on average over the period from ``u_dc`` (V)."""
    va, vb, vc = inverse_clarke(u)
    hi = max(va, vb, vc)
    lo = min(va, vb, vc)
    span = hi - lo  # the line-to-line extent; the hexagon is span <= U_dc
    clamped = span > u_dc
    if clamped:
        s = u_dc / span
        va, vb, vc, hi, lo = va * s, vb * s, vc * s, hi * s, lo * s
        u = u * s
    mid = 0.5 * (hi + lo)
    inv = 1.0 / u_dc
    da = min(max(0.5 + (va - mid) * inv, 0.0), 1.0)
    db = min(max(0.5 + (vb - mid) * inv, 0.0), 1.0)
    dc = min(max(0.5 + (vc - mid) * inv, 0.0), 1.0)
    pulses = new_record(
        PhasePulses, (0.5 * (1.0 - da), 0.5 * (1.0 - db), 0.5 * (1.0 - dc), da, db, dc)
    )
    return Modulation(pulses, u, clamped)
