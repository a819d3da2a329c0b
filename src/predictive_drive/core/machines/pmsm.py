"""Permanent-magnet synchronous motor in the rotor dq frame: parameters with units and the
continuous-time dynamics (docs/physics.md#pmsm; papers 001, 002).

The dynamics signature is ``f(t, x, u, c)``: ``x`` the state tuple (indices in
:data:`PMSM_STATE`), ``u = (u_s, t_load)`` with u_s the stator voltage in αβ (V, complex) and
t_load the load torque (N·m), ``c`` the precomputed :class:`PMSMCoefficients`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from ..fields import check_fields, quantity

__all__ = [
    "pmsm_exact_step",
    "pmsm_predict_current",
    "PMSM",
    "PMSM_STATE",
    "PMSMCoefficients",
    "PMSMStep",
    "pmsm_dynamics",
    "pmsm_rk4",
    "pmsm_torque",
]


@dataclass(frozen=True)
class PMSM:
    """Permanent-magnet synchronous motor in the rotor dq frame (docs/physics.md#pmsm; papers 001, 002).

    Surface-mounted when l_d == l_q, interior (salient) when l_d < l_q.

    ===============  ========  =====================================================
    field            unit      meaning
    ===============  ========  =====================================================
    r_s              Ω         stator resistance
    l_d              H         d-axis inductance
    l_q              H         q-axis inductance
    psi_f            Wb        permanent-magnet flux linkage
    p                —         pole pairs (θ_e = p·θ_m)
    j                kg·m²     rotor + load inertia
    rated_torque     N·m       nameplate torque (strategy thresholds are shares of it)
    rated_speed_rpm  r/min     nameplate speed (documentation and speed bands)
    b                N·m·s     viscous friction
    ===============  ========  =====================================================

    Defaults are none: the scenario file gives every value (paper 001 §3 and §6 for
    ``spmsm_analysis`` and ``ipmsm_validation``).
    """

    r_s: float = quantity("stator resistance", "Ω", gt=0)
    l_d: float = quantity("d-axis inductance", "H", gt=0)
    l_q: float = quantity("q-axis inductance", "H", gt=0)
    psi_f: float = quantity("permanent-magnet flux linkage", "Wb", gt=0)
    p: int = quantity("pole pairs (θ_e = p·θ_m)", ge=1, integer=True)
    j: float = quantity("rotor + load inertia", "kg·m²", gt=0)
    rated_torque: float = quantity("nameplate torque", "N·m", gt=0)
    rated_speed_rpm: float = quantity("nameplate speed", "r/min", gt=0)
    b: float = quantity("viscous friction", "N·m·s", ge=0, default=0.0)

    def __post_init__(self) -> None:
        check_fields(self)

    @property
    def surface(self) -> bool:
        return self.l_d == self.l_q


class PMSMCoefficients(NamedTuple):
    """Constants of the PMSM state equations, computed once per parameter set."""

    r_s: float
    inv_l_d: float  #: 1/L_d, 1/H
    inv_l_q: float  #: 1/L_q, 1/H
    l_d: float
    l_q: float
    psi_f: float
    p: int
    torque_k: float  #: 1.5 p
    inv_j: float
    b: float

    @classmethod
    def of(cls, m: PMSM) -> PMSMCoefficients:
        return cls(
            r_s=m.r_s,
            inv_l_d=1.0 / m.l_d,
            inv_l_q=1.0 / m.l_q,
            l_d=m.l_d,
            l_q=m.l_q,
            psi_f=m.psi_f,
            p=m.p,
            torque_k=1.5 * m.p,
            inv_j=1.0 / m.j,
            b=m.b,
        )


class PMSMStateIndex(NamedTuple):
    i_dq: int = 0  #: stator current in the rotor frame, A (complex: i_d + j·i_q)
    omega_m: int = 1  #: mechanical speed, rad/s
    theta_m: int = 2  #: shaft angle, rad (θ_e = p·θ_m)


PMSM_STATE = PMSMStateIndex()


def pmsm_torque(i_dq: complex, c: PMSMCoefficients) -> float:
    """T_e = (3/2) p [ψ_f i_q + (L_d - L_q) i_d i_q], N·m (docs/physics.md#pmsm)."""
    return c.torque_k * i_dq.imag * (c.psi_f + (c.l_d - c.l_q) * i_dq.real)


def pmsm_dynamics(
    t: float,
    x: tuple[complex, float, float],
    u: tuple[complex, float],
    c: PMSMCoefficients,
) -> tuple[complex, float, float]:
    """dx/dt of the PMSM plus mechanics (docs/physics.md#pmsm; docs/physics.md#mechanics-and-load).
    u_s is in αβ; it is turned into the rotor frame with θ_e = p·θ_m: u_d + j·u_q =
    u_s·e^{-jθ_e}."""
    i, w, th = x
    u_s, t_load = u
    the = c.p * th
    u_dq = u_s * complex(math.cos(the), -math.sin(the))
    we = c.p * w
    i_d, i_q = i.real, i.imag
    di_d = (u_dq.real - c.r_s * i_d + we * c.l_q * i_q) * c.inv_l_d
    di_q = (u_dq.imag - c.r_s * i_q - we * (c.l_d * i_d + c.psi_f)) * c.inv_l_q
    te = c.torque_k * i_q * (c.psi_f + (c.l_d - c.l_q) * i_d)
    dw = (te - t_load - c.b * w) * c.inv_j
    return complex(di_d, di_q), dw, w


def pmsm_rk4(
    t: float,
    x: tuple[complex, float, float],
    u: tuple[complex, float],
    c: PMSMCoefficients,
    h: float,
    n: int,
) -> tuple[complex, float, float]:
    """RK4 of :func:`pmsm_dynamics` over [t, t+h] in ``n`` sub-steps, fused for speed (a test holds
    it to ``plant.rk4(pmsm_dynamics, ...)``)."""
    i, w, th = x
    u_s, tl = u
    rs, ild, ilq, ld, lq, pf, p, tk, ij, fb = c
    ua, ub = u_s.real, u_s.imag
    dl = ld - lq
    cos, sin = math.cos, math.sin
    dt = h / n
    half = 0.5 * dt
    sixth = dt / 6.0

    def f(i_d: float, i_q: float, w: float, th: float) -> tuple[float, float, float]:
        the = p * th
        co, si = cos(the), sin(the)
        we = p * w
        did = (ua * co + ub * si - rs * i_d + we * lq * i_q) * ild
        diq = (ub * co - ua * si - rs * i_q - we * (ld * i_d + pf)) * ilq
        dw = (tk * i_q * (pf + dl * i_d) - tl - fb * w) * ij
        return did, diq, dw

    i_d, i_q = i.real, i.imag
    for _ in range(n):
        a1, b1, c1 = f(i_d, i_q, w, th)
        w2 = w + half * c1
        a2, b2, c2 = f(i_d + half * a1, i_q + half * b1, w2, th + half * w)
        w3 = w + half * c2
        a3, b3, c3 = f(i_d + half * a2, i_q + half * b2, w3, th + half * w2)
        w4 = w + dt * c3
        a4, b4, c4 = f(i_d + dt * a3, i_q + dt * b3, w4, th + dt * w3)
        i_d += sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        i_q += sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
        th += sixth * (w + 2.0 * w2 + 2.0 * w3 + w4)
        w += sixth * (c1 + 2.0 * c2 + 2.0 * c3 + c4)
    return complex(i_d, i_q), w, th


class PMSMStep(NamedTuple):
    """One period of the PMSM's stator currents at a constant electrical speed, solved exactly
    (docs/physics.md#predicting-the-pmsm-over-a-period): i(k+1) = A·i(k) + G·u(k) + f, in the rotor
    frame, with u(k) = u_αβ·e^{-jθ_e(k)} the period's voltage seen from the rotor at the
    period's start (the voltage stays put in αβ; the rotor turns under it)."""

    a11: float
    a12: float
    a21: float
    a22: float
    g11: float  #: A/V
    g12: float
    g21: float
    g22: float
    f_d: float  #: A
    f_q: float


@lru_cache(maxsize=16)
def pmsm_exact_step(c: PMSMCoefficients, ts: float, w_e: float) -> PMSMStep:
    """:class:`PMSMStep` over ``ts`` (s) at electrical speed ``w_e`` (rad/s): the exponential of
    the linear model's matrix with the voltage's rotation in the rotor frame as two more states
    (du_dq/dt = -jω_e·u_dq) and a constant one, by scaling and squaring of its Taylor series —
    exact to rounding for :func:`pmsm_dynamics`' currents at that speed. Cached: a drive held at
    one speed computes it once."""
    rs, ld, lq = c.r_s, c.l_d, c.l_q
    m = np.zeros((5, 5))
    m[0, :4] = (-rs / ld, w_e * lq / ld, 1.0 / ld, 0.0)
    m[1, :] = (-w_e * ld / lq, -rs / lq, 0.0, 1.0 / lq, -w_e * c.psi_f / lq)
    m[2, 3], m[3, 2] = w_e, -w_e
    x = m * ts
    squarings = max(0, math.ceil(math.log2(max(float(np.abs(x).sum(0).max()), 1e-300) / 0.25)))
    x /= 2.0**squarings
    e, term = np.eye(5), np.eye(5)
    for k in range(1, 16):  # ‖x‖ ≤ 1/4: 4^-16/16! is far below rounding
        term = term @ x / k
        e += term
    for _ in range(squarings):
        e = e @ e
    a, g, f = e[:2, :2].ravel().tolist(), e[:2, 2:4].ravel().tolist(), e[:2, 4].tolist()
    return PMSMStep(a[0], a[1], a[2], a[3], g[0], g[1], g[2], g[3], f[0], f[1])


def pmsm_predict_current(
    c: PMSMCoefficients,
    ts: float,
    i_ab: complex,
    theta_e: float,
    omega_m: float,
    u_ab: complex,
    *,
    exact: PMSMStep | None = None,
) -> tuple[complex, float]:
    """(i_αβ, θ_e) one period ahead with the voltage ``u_ab`` (V, αβ) applied over it, by forward
    Euler of the model's dq equations at constant speed, the voltage turned into dq at the
    period's middle angle (the controllers' delay compensation); or, given ``exact``
    (:func:`pmsm_exact_step` at this speed), the period solved exactly."""
    w_e = c.p * omega_m
    rot = complex(math.cos(theta_e), -math.sin(theta_e))
    i = i_ab * rot
    theta1 = theta_e + w_e * ts
    if exact is not None:
        u = u_ab * rot
        x = exact
        i_d, i_q, u_d, u_q = i.real, i.imag, u.real, u.imag
        i1 = complex(
            x.a11 * i_d + x.a12 * i_q + x.g11 * u_d + x.g12 * u_q + x.f_d,
            x.a21 * i_d + x.a22 * i_q + x.g21 * u_d + x.g22 * u_q + x.f_q,
        )
        return i1 * complex(math.cos(theta1), math.sin(theta1)), theta1
    mid = theta_e + 0.5 * w_e * ts
    u = u_ab * complex(math.cos(mid), -math.sin(mid))
    i_d, i_q = i.real, i.imag
    d_d = (u.real - c.r_s * i_d + w_e * c.l_q * i_q) * c.inv_l_d
    d_q = (u.imag - c.r_s * i_q - w_e * (c.l_d * i_d + c.psi_f)) * c.inv_l_q
    i1 = complex(i_d + ts * d_d, i_q + ts * d_q)
    return i1 * complex(math.cos(theta1), math.sin(theta1)), theta1
