"""Two-level inverter: switching states, voltage vectors and per-period switching sequences
(docs/physics.md#the-inverter-and-the-command).

Space vectors use the amplitude-invariant Clarke transform, u = (2/3)·U_dc·(S_a + a·S_b + a²·S_c) with
a = exp(j·2π/3). Vector numbering follows both papers: V0 = 000, V1 = 100 (0°), V2 = 110 (60°),
V3 = 010 (120°), V4 = 011 (180°), V5 = 001 (240°), V6 = 101 (300°), V7 = 111.

The command format shared by every strategy is a single pulse per phase and period: phase x is high on
[delay_x, delay_x + duty_x) (fractions of Ts) and low elsewhere. One active vector for the whole period,
a vector followed by a zero vector (deadbeat duty) and centre-aligned PWM are all special cases.
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Sequence

from .signals import PhasePulses, new_record

__all__ = [
    "VECTOR_STATES",
    "PhasePulses",
    "active_then_zero",
    "clarke",
    "inverse_clarke",
    "inverse_park",
    "park",
    "segments",
    "state_to_vector",
    "unit_vectors",
    "vector_voltages",
    "zero_state_for",
]

A = cmath.exp(2j * math.pi / 3)
_HALF_SQRT3 = 0.5 * math.sqrt(3.0)

#: switching state (S_a, S_b, S_c) of V0..V7
VECTOR_STATES: tuple[tuple[int, int, int], ...] = (
    (0, 0, 0),
    (1, 0, 0),
    (1, 1, 0),
    (0, 1, 0),
    (0, 1, 1),
    (0, 0, 1),
    (1, 0, 1),
    (1, 1, 1),
)
_STATE_INDEX = {s: n for n, s in enumerate(VECTOR_STATES)}


def clarke(x_a: float, x_b: float, x_c: float) -> complex:
    """Amplitude-invariant Clarke transform, x_αβ = 2/3 (x_a + a x_b + a² x_c)."""
    return (2.0 / 3.0) * (x_a + A * x_b + A * A * x_c)


def inverse_clarke(x_ab: complex) -> tuple[float, float, float]:
    """The phase quantities (a, b, c) of a space vector without zero sequence (a balanced
    three-wire machine's currents): x_a = Re x, x_b = Re(x·a²), x_c = Re(x·a)."""
    r, i = x_ab.real, _HALF_SQRT3 * x_ab.imag
    return r, -0.5 * r + i, -0.5 * r - i


def park(x_ab: complex, theta: float) -> complex:
    """Stationary αβ → rotor dq at the electrical angle θ (rad): x_dq = x_αβ·e^{-jθ}."""
    return x_ab * complex(math.cos(theta), -math.sin(theta))


def inverse_park(x_dq: complex, theta: float) -> complex:
    """Rotor dq at the electrical angle θ (rad) → stationary αβ: x_αβ = x_dq·e^{jθ}."""
    return x_dq * complex(math.cos(theta), math.sin(theta))


def unit_vectors() -> tuple[complex, ...]:
    """V0..V6 for U_dc = 1 V (multiply by U_dc to get volts)."""
    return tuple(clarke(*VECTOR_STATES[n]) for n in range(7))


_UNIT = unit_vectors()


def vector_voltages(u_dc: float) -> tuple[complex, ...]:
    """Voltage space vectors V0..V6 in V for the given DC-link voltage."""
    return tuple(u_dc * v for v in _UNIT)


def state_to_vector(state: tuple[int, int, int]) -> int:
    """Vector number 0..7 of a switching state."""
    return _STATE_INDEX[state]


def zero_state_for(previous: tuple[int, int, int]) -> tuple[int, int, int]:
    """The zero vector (000 or 111) needing fewer switch changes from ``previous`` (ties: 000)."""
    return (1, 1, 1) if sum(previous) >= 2 else (0, 0, 0)


def active_then_zero(
    vector: int, fraction: float, previous: tuple[int, int, int]
) -> tuple[PhasePulses, tuple[int, int, int]]:
    """Vector ``vector`` for ``fraction``·Ts, then the zero vector for the rest.

    The zero vector is 000 or 111, whichever needs fewer switch changes from the state before it: the
    active vector if it is applied at all, otherwise ``previous`` (the state at the end of the last
    period). Vector 0 (or 7) alone is one zero vector for the whole period. Returns the pulses and the
    state at the end of the period.
    """
    if vector in (0, 7) or fraction <= 0.0:
        z = zero_state_for(previous)
        return _FULL[state_to_vector(z)], z
    if fraction >= 1.0:
        return _FULL[vector], VECTOR_STATES[vector]
    (ka, kb, kc), z = _THEN_ZERO[vector]
    f = fraction
    delay = (0.0, 0.0, f, 0.0)  # by kind, see _then_zero_kinds
    duty = (1.0, f, 1.0 - f, 0.0)
    return new_record(
        PhasePulses, (delay[ka], delay[kb], delay[kc], duty[ka], duty[kb], duty[kc])
    ), z


def segments(
    pulses: Sequence[float], previous: tuple[int, int, int]
) -> tuple[list[tuple[tuple[int, int, int], float]], tuple[int, int, int], int]:
    """Piecewise-constant switching states of one period.

    ``pulses`` is a :class:`PhasePulses` (or the same six numbers in that order).
    Returns ``(segments, end_state, transitions)``: segments as (state, fraction of Ts) in time order
    with empty ones dropped, the state at the end of the period, and the number of on/off transitions of
    the six devices in the period counted from ``previous`` (two per leg change).
    """
    ra, rb, rc, da, db, dc = pulses
    fa, fb, fc = ra + da, rb + db, rc + dc
    inner = {ra, rb, rc, fa, fb, fc}
    inner.discard(0.0)
    inner.discard(1.0)
    prev = previous[0] * 4 + previous[1] * 2 + previous[2]
    if not inner:  # one state all period (FCS): each phase high all period or low all period
        code = (da > 0.0) * 4 + (db > 0.0) * 2 + (dc > 0.0)
        return [(_CODE_STATE[code], 1.0)], _CODE_STATE[code], 2 * _LEGS[code ^ prev]
    if len(inner) == 1:  # one edge inside the period (a vector, then a zero vector)
        t = inner.pop()
        mid = 0.5 * t
        c1 = (ra <= mid < fa) * 4 + (rb <= mid < fb) * 2 + (rc <= mid < fc)
        mid += 0.5
        c2 = (ra <= mid < fa) * 4 + (rb <= mid < fb) * 2 + (rc <= mid < fc)
        s2 = _CODE_STATE[c2]
        if c1 == c2:
            return [(s2, 1.0)], s2, 2 * _LEGS[c2 ^ prev]
        return [(_CODE_STATE[c1], t), (s2, 1.0 - t)], s2, 2 * (_LEGS[c1 ^ prev] + _LEGS[c2 ^ c1])
    out: list[tuple[tuple[int, int, int], float]] = []
    transitions = 0
    t0 = 0.0
    for t1 in (*sorted(inner), 1.0):
        mid = 0.5 * (t0 + t1)
        code = (ra <= mid < fa) * 4 + (rb <= mid < fb) * 2 + (rc <= mid < fc)
        if code != prev or not out:
            transitions += _LEGS[code ^ prev]
            prev = code
            out.append((_CODE_STATE[code], t1 - t0))
        else:
            out[-1] = (out[-1][0], out[-1][1] + (t1 - t0))
        t0 = t1
    return out, _CODE_STATE[prev], 2 * transitions


#: switching state of the 3-bit code S_a·4 + S_b·2 + S_c, and how many legs differ (popcount)
_CODE_STATE = tuple(((c >> 2) & 1, (c >> 1) & 1, c & 1) for c in range(8))
_LEGS = tuple(bin(x).count("1") for x in range(8))


#: one vector for the whole period, V0..V7
_FULL = tuple(PhasePulses(0.0, 0.0, 0.0, *(float(x) for x in st)) for st in VECTOR_STATES)


def _then_zero_kinds(vector: int) -> tuple[tuple[int, int, int], tuple[int, int, int]]:
    """Per phase: 0 high all period, 1 high then low, 2 low then high, 3 low all period."""
    active = VECTOR_STATES[vector]
    z = zero_state_for(active)
    kinds = tuple((0 if s and zs else 1 if s else 2 if zs else 3) for s, zs in zip(active, z))
    return (kinds[0], kinds[1], kinds[2]), z


_THEN_ZERO = {n: _then_zero_kinds(n) for n in range(1, 7)}
