"""Saturating machines: the PMSM on a magnetic model (:mod:`.magnetics`) and the induction motor
with main-flux saturation, both integrated in flux coordinates with the currents read from the
magnetics, so the model stays consistent (docs/physics.md#saturation).

Dynamics signature as the linear machines': ``f(t, x, u, c)``, x the state (indices in
:data:`SAT_PMSM_STATE`, :data:`SAT_IM_STATE`), u = (u_s in αβ, V; T_L, N·m), c the coefficients.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import NamedTuple

from ...errors import ConfigError
from ..fields import check_fields, choice, quantity
from .induction import InductionMotor
from .magnetics import MagneticModel
from .pmsm import PMSM

__all__ = [
    "IM_MAGNETICS",
    "IMSaturation",
    "SAT_IM_STATE",
    "SAT_PMSM_STATE",
    "SaturatedIMCoefficients",
    "SaturatedPMSMCoefficients",
    "saturated_im_rk4",
    "saturated_pmsm_rk4",
]

#: the models an induction motor's ``saturation.model`` names ("none": the linear plant)
IM_MAGNETICS = ("none", "curve")


@dataclass(frozen=True)
class IMSaturation:
    """Main-flux saturation of the induction motor in its Γ-equivalent circuit
    (docs/physics.md#saturation): the magnetising inductance L_M (= L_s of the T circuit)
    falls with the stator flux as L_M(ψ) = L_s/(1 + c·(ψ/ψ_n)^S), c = drop/(1 - drop): by
    ``drop`` at the rated flux ψ_n, little below it, fast above it."""

    model: str = choice("magnetic model (none: linear)", IM_MAGNETICS, default="none")
    flux_rated: float = quantity(
        "curve: rated magnetising (stator) flux ψ_n", "Wb", gt=0,
        nan_default="none (needed with model curve)", default=math.nan,
    )  # fmt: skip
    drop: float = quantity(
        "curve: share by which L_M is down at the rated flux", ge=0, le=0.9, default=0.1
    )
    exponent: float = quantity("curve: exponent S of the saturation", gt=0, default=6.0)

    def __post_init__(self) -> None:
        check_fields(self)
        if self.model == "curve" and math.isnan(self.flux_rated):
            raise ConfigError("saturation.flux_rated: model curve needs the rated flux ψ_n (Wb)")

    @property
    def on(self) -> bool:
        return self.model != "none"


# --- the PMSM on a magnetic model ---------------------------------------------------------


class SaturatedPMSM(NamedTuple):
    """A PMSM whose magnetics are a :class:`~.magnetics.MagneticModel` (L_d, L_q and ψ_f of
    ``motor`` are not used: the model replaces them)."""

    motor: PMSM
    magnetics: MagneticModel

    @property
    def p(self) -> int:
        return self.motor.p


class SaturatedPMSMCoefficients(NamedTuple):
    r_s: float
    p: int
    torque_k: float  #: 1.5 p
    inv_j: float
    b: float
    current: Callable[[float, float], tuple[float, float]]  #: (ψ_d, ψ_q) → (i_d, i_q)

    @classmethod
    def of(cls, m: SaturatedPMSM) -> SaturatedPMSMCoefficients:
        mo = m.motor
        return cls(mo.r_s, mo.p, 1.5 * mo.p, 1.0 / mo.j, mo.b, m.magnetics.current)


class SatPMSMStateIndex(NamedTuple):
    psi_dq: int = 0  #: stator flux linkage in the rotor frame, Wb (complex: ψ_d + j·ψ_q)
    omega_m: int = 1  #: mechanical speed, rad/s
    theta_m: int = 2  #: shaft angle, rad


SAT_PMSM_STATE = SatPMSMStateIndex()


def saturated_pmsm_rk4(
    t: float,
    x: tuple[complex, float, float],
    u: tuple[complex, float],
    c: SaturatedPMSMCoefficients,
    h: float,
    n: int,
) -> tuple[complex, float, float]:
    """RK4 over [t, t+h] in ``n`` sub-steps of dψ_dq/dt = u_dq - R_s i_dq - jω_e ψ_dq with
    i_dq = i(ψ_dq), T_e = 1.5 p (ψ_d i_q - ψ_q i_d), J dω_m/dt = T_e - T_L - b ω_m."""
    psi, w, th = x
    u_s, tl = u
    rs, p, tk, ij, fb, current = c
    ua, ub = u_s.real, u_s.imag
    cos, sin = math.cos, math.sin
    dt = h / n
    half = 0.5 * dt
    sixth = dt / 6.0

    def f(pd: float, pq: float, w: float, th: float) -> tuple[float, float, float]:
        the = p * th
        co, si = cos(the), sin(the)
        we = p * w
        i_d, i_q = current(pd, pq)
        dpd = ua * co + ub * si - rs * i_d + we * pq
        dpq = ub * co - ua * si - rs * i_q - we * pd
        dw = (tk * (pd * i_q - pq * i_d) - tl - fb * w) * ij
        return dpd, dpq, dw

    pd, pq = psi.real, psi.imag
    for _ in range(n):
        a1, b1, c1 = f(pd, pq, w, th)
        w2 = w + half * c1
        a2, b2, c2 = f(pd + half * a1, pq + half * b1, w2, th + half * w)
        w3 = w + half * c2
        a3, b3, c3 = f(pd + half * a2, pq + half * b2, w3, th + half * w2)
        w4 = w + dt * c3
        a4, b4, c4 = f(pd + dt * a3, pq + dt * b3, w4, th + dt * w3)
        pd += sixth * (a1 + 2.0 * a2 + 2.0 * a3 + a4)
        pq += sixth * (b1 + 2.0 * b2 + 2.0 * b3 + b4)
        th += sixth * (w + 2.0 * w2 + 2.0 * w3 + w4)
        w += sixth * (c1 + 2.0 * c2 + 2.0 * c3 + c4)
    return complex(pd, pq), w, th


# --- the induction motor with main-flux saturation ----------------------------------------


class SaturatedIM(NamedTuple):
    """An induction motor (T-circuit data) with main-flux saturation."""

    motor: InductionMotor
    saturation: IMSaturation

    @property
    def p(self) -> int:
        return self.motor.p


class SaturatedIMCoefficients(NamedTuple):
    """The Γ circuit of the T circuit's data: L_M = L_s, L_σ = L_s(L_s L_r - L_m²)/L_m²,
    R_R = R_r (L_s/L_m)², ψ_R = (L_s/L_m) ψ_r; the magnetising current
    i_M = ψ_s/L_s·(1 + k|ψ_s|^S), k = c/ψ_n^S."""

    r_s: float
    r_rr: float  #: R_R, Ω
    inv_lsig: float  #: 1/L_σ, 1/H
    inv_lm: float  #: 1/L_M unsaturated, 1/H
    k_sat: float  #: c/ψ_n^S, 1/Wb^S
    half_s: float  #: S/2
    p: int
    torque_k: float
    inv_j: float
    b: float

    @classmethod
    def of(cls, m: SaturatedIM) -> SaturatedIMCoefficients:
        mo, sat = m.motor, m.saturation
        g = mo.l_s / mo.l_m
        l_sig = mo.l_s * (mo.l_s * mo.l_r - mo.l_m * mo.l_m) / (mo.l_m * mo.l_m)
        c = sat.drop / (1.0 - sat.drop)
        return cls(
            r_s=mo.r_s,
            r_rr=mo.r_r * g * g,
            inv_lsig=1.0 / l_sig,
            inv_lm=1.0 / mo.l_s,
            k_sat=c / sat.flux_rated**sat.exponent,
            half_s=0.5 * sat.exponent,
            p=mo.p,
            torque_k=1.5 * mo.p,
            inv_j=1.0 / mo.j,
            b=mo.b,
        )


class SatIMStateIndex(NamedTuple):
    psi_s: int = 0  #: stator flux, Wb (complex αβ)
    psi_rr: int = 1  #: Γ-circuit rotor flux ψ_R, Wb (complex αβ)
    omega_m: int = 2  #: mechanical speed, rad/s
    theta_m: int = 3  #: shaft angle, rad


SAT_IM_STATE = SatIMStateIndex()


def saturated_im_current(psi_s: complex, psi_rr: complex, c: SaturatedIMCoefficients) -> complex:
    """i_s = i_M(ψ_s) - i_R, i_R = (ψ_R - ψ_s)/L_σ, A (αβ)."""
    q = psi_s.real * psi_s.real + psi_s.imag * psi_s.imag
    i_m: complex = psi_s * (c.inv_lm * (1.0 + c.k_sat * q**c.half_s))
    return i_m - (psi_rr - psi_s) * c.inv_lsig


def saturated_im_rk4(
    t: float,
    x: tuple[complex, complex, float, float],
    u: tuple[complex, float],
    c: SaturatedIMCoefficients,
    h: float,
    n: int,
) -> tuple[complex, complex, float, float]:
    """RK4 over [t, t+h] in ``n`` sub-steps of the Γ circuit in αβ: dψ_s/dt = u_s - R_s i_s,
    dψ_R/dt = -R_R i_R + jω_r ψ_R, T_e = 1.5 p Im(conj(ψ_s) i_s)."""
    ps, pr, w, th = x
    u_s, tl = u
    rs, rr, ils, ilm, ks, hs, p, tk, ij, fb = c
    dt = h / n
    half = 0.5 * dt
    sixth = dt / 6.0

    def f(ps: complex, pr: complex, w: float) -> tuple[complex, complex, float]:
        q = ps.real * ps.real + ps.imag * ps.imag
        i_r = (pr - ps) * ils
        i_s = ps * (ilm * (1.0 + ks * q**hs)) - i_r
        dps = u_s - rs * i_s
        dpr = complex(-rr * i_r.real - p * w * pr.imag, -rr * i_r.imag + p * w * pr.real)
        dw = (tk * (ps.real * i_s.imag - ps.imag * i_s.real) - tl - fb * w) * ij
        return dps, dpr, dw

    for _ in range(n):
        s1, r1, c1 = f(ps, pr, w)
        w2 = w + half * c1
        s2, r2, c2 = f(ps + half * s1, pr + half * r1, w2)
        w3 = w + half * c2
        s3, r3, c3 = f(ps + half * s2, pr + half * r2, w3)
        w4 = w + dt * c3
        s4, r4, c4 = f(ps + dt * s3, pr + dt * r3, w4)
        ps = ps + sixth * (s1 + 2.0 * s2 + 2.0 * s3 + s4)
        pr = pr + sixth * (r1 + 2.0 * r2 + 2.0 * r3 + r4)
        th += sixth * (w + 2.0 * w2 + 2.0 * w3 + w4)
        w += sixth * (c1 + 2.0 * c2 + 2.0 * c3 + c4)
    return ps, pr, w, th
