"""Paper 002: maximum torque per ampere (MTPA) laws — the current angle of field-oriented control
(docs/physics.md, "Field-oriented control and MTPA"). One law per strategy of the ``foc_pmsm``
family.

The current vector is I_s at the angle θ from the q axis: i_d = -I_s sin θ, i_q = ±I_s cos θ
(the sign of the torque). T = 1.5 p I_s cos θ [ψ_f - (L_d - L_q) I_s sin θ] (paper 002 eq 8).

Each law also says the amplitude I_s the torque reference asks for (``current``):

- ``foc_zero_d``: θ = 0 (i_d = 0 control), I_s = |T*|/k_t, k_t = 1.5 p ψ_f.
- ``foc_formula``: paper 002 eq 10 with the controller's L_d, L_q, ψ_f, at the amplitude whose
  eq-10 angle gives T* by eq 8 — the reluctance torque counted (:func:`mtpa_current`): |T*|/k_t
  at 13.1° gives paper 001's IPMSM 15.47 N·m for 15.
- ``foc_injection``: θ = θ0 + A sin(ω_h t); the torque's response to the dither, extracted by a
  sliding DFT (eq 17-18, M samples per dither period), says which way dT/dθ points; an
  integrator moves θ0 until it is zero, without L_d, L_q — and so at I_s = |T*|/k_t, the
  reluctance torque left to the speed loop. Two forms:

  ``corrected`` (default) — the torque per ampere T/|i|, the torque from a flux estimate that
  needs no L_d, L_q (:class:`FluxObserver`: the volt-seconds the controller applied, pulled
  slowly towards the steady-state voltage balance), and the *measured* current angle Θ each go
  through a sliding DFT at the dither frequency; Re(τ_h·conj(Θ_h)) / |Θ_h|² is d(T/I)/dθ, whatever
  phase the current loop and sampling add (they delay the measured angle too).

  ``as_printed`` — eq 16 with the ratios (u_d - R_s i_d)/(ω_e i_q) and (u_q - R_s i_q)/ω_e taken
  as constant over a dither period (their sliding-DFT means) and the dithered reference currents,
  its dither component demodulated with sin(ω_h t) (eq 19), low-passed, integrated. Kept to show
  its bias: eq 15 does not hold ((u_d - R_s i_d)/(ω_e i_q) = -L_q, not L_d - L_q), so the
  estimate's gradient vanishes near twice the MTPA angle, and the plain sin(ω_h t) demodulation
  ignores the current loop's phase lag.
"""

from __future__ import annotations

import cmath
import math
from typing import NamedTuple

__all__ = [
    "INJECTION_FORMS",
    "MTPAPoint",
    "FormulaMTPA",
    "InjectionMTPA",
    "MTPAInputs",
    "SlidingDFT",
    "ZeroD",
    "formula_angle",
    "mtpa_current",
    "mtpa_point",
    "torque_at",
]

#: ``foc_injection`` variants: the corrected default and paper 002 as printed (eq 16, 19)
INJECTION_FORMS = ("corrected", "as_printed")
TWO_PI = 2.0 * math.pi


def formula_angle(i_s: float, psi_f: float, l_d: float, l_q: float) -> float:
    """θ_MTPA (rad, from the q axis) for the current amplitude ``i_s`` (A), paper 002 eq 10:
    asin[(ψ_f - sqrt(ψ_f² + 8(L_d - L_q)² I_s²)) / (4 (L_d - L_q) I_s)]; 0 for a surface machine
    or no current."""
    dl = l_d - l_q
    if i_s <= 0.0 or dl == 0.0:
        return 0.0
    x = (psi_f - math.sqrt(psi_f * psi_f + 8.0 * dl * dl * i_s * i_s)) / (4.0 * dl * i_s)
    return math.asin(min(max(x, -1.0), 1.0))


def torque_at(i_s: float, theta: float, *, p: int, psi_f: float, l_d: float, l_q: float) -> float:
    """T = 1.5 p I_s cos θ [ψ_f - (L_d - L_q) I_s sin θ], N·m (paper 002 eq 8), θ from the q
    axis."""
    return 1.5 * p * i_s * math.cos(theta) * (psi_f - (l_d - l_q) * i_s * math.sin(theta))


def mtpa_current(
    torque: float, *, p: int, psi_f: float, l_d: float, l_q: float, start: float = 0.0
) -> float:
    """The amplitude I_s (A) whose eq-10 angle gives ``torque`` (N·m, its magnitude) by eq 8:
    Newton's method on T(I_s) along the MTPA curve, whose slope there is ∂T/∂I_s at the fixed
    angle (∂T/∂θ = 0 at MTPA), 1.5 p cos θ (ψ_f - 2(L_d - L_q) I_s sin θ). From ``start`` (A;
    default |T|/k_t, which i_d = 0 needs and MTPA never exceeds) to 1e-12 of I_s."""
    t = abs(torque)
    if t == 0.0:
        return 0.0
    dl = l_d - l_q
    i_s = start if start > 0.0 else t / (1.5 * p * psi_f)
    for _ in range(50):
        th = formula_angle(i_s, psi_f, l_d, l_q)
        sin, cos = math.sin(th), math.cos(th)
        made = 1.5 * p * i_s * cos * (psi_f - dl * i_s * sin)
        step = (made - t) / (1.5 * p * cos * (psi_f - 2.0 * dl * i_s * sin))
        i_s -= step
        if abs(step) <= 1e-12 * i_s:
            break
    return i_s


class MTPAPoint(NamedTuple):
    """Where a machine makes a torque with the least current."""

    theta: float  #: current angle from the q axis, rad
    i_s: float  #: current amplitude, A (the minimum for the torque)
    i_s_zero_d: float  #: the amplitude i_d = 0 control needs for the same torque, A


def mtpa_point(torque: float, *, p: int, psi_f: float, l_d: float, l_q: float) -> MTPAPoint:
    """The MTPA operating point of ``torque`` (N·m, its magnitude) on the model: the amplitude
    whose eq-10 angle gives the torque (bisection; T grows with I_s along the MTPA curve)."""
    t = abs(torque)
    k_t = 1.5 * p * psi_f
    zero_d = t / k_t
    if t == 0.0:
        return MTPAPoint(0.0, 0.0, 0.0)

    def along(i_s: float) -> float:
        th = formula_angle(i_s, psi_f, l_d, l_q)
        return torque_at(i_s, th, p=p, psi_f=psi_f, l_d=l_d, l_q=l_q)

    lo, hi = 0.0, zero_d  # MTPA never needs more current than i_d = 0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if along(mid) < t:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-13 * zero_d:
            break
    i_s = 0.5 * (lo + hi)
    return MTPAPoint(formula_angle(i_s, psi_f, l_d, l_q), i_s, zero_d)


class SlidingDFT:
    """Bin ``k`` of an ``m``-sample DFT, updated per sample (paper 002 eq 17-18):
    X_n = (X_{n-1} - x(n-m) + x(n))·e^{j2πk/m}. ``value`` is the complex amplitude of that
    component *at the latest sample*: a component a·cos(2πkn/m + φ) gives value = a·e^{j(2πkn/m
    + φ)} (bin 0: the mean) once m samples are in; ``numpy.fft`` of the last m samples gives the
    same, referred to the window's first sample."""

    __slots__ = ("m", "k", "_twiddle", "_buf", "_i", "_x", "_scale")

    def __init__(self, m: int, k: int = 1) -> None:
        if m < 2 or not 0 <= k < m:
            raise ValueError(f"sliding DFT needs m >= 2 samples and 0 <= k < m, got m={m}, k={k}")
        self.m = m
        self.k = k
        self._twiddle = cmath.exp(2j * math.pi * k / m)
        self._buf = [0.0] * m
        self._i = 0
        self._x = 0j
        self._scale = (1.0 if k == 0 else 2.0) / m

    def update(self, x: float) -> complex:
        """Add a sample; returns :attr:`value`."""
        i = self._i
        self._x = (self._x - self._buf[i] + x) * self._twiddle
        self._buf[i] = x
        self._i = (i + 1) % self.m
        return self.value

    @property
    def value(self) -> complex:
        # the recursion's phasor is referred to the sample after the latest; one step back
        return self._x * self._scale / self._twiddle

    def reset(self, x: float = 0.0) -> None:
        """Fill the window with ``x`` (the DFT of a constant: bin 0 = x, other bins 0)."""
        self._buf = [x] * self.m
        self._x = complex(x * self.m) if self.k == 0 else 0j


class MTPAInputs(NamedTuple):
    """What an MTPA law sees at step k (SI units; dq quantities in the rotor frame)."""

    k: int  #: step index
    i_s: float  #: current amplitude asked of the current loop, A
    sign: float  #: sign of the torque reference (+1 / -1)
    i_dq: complex  #: measured i_d + j·i_q at step k, A
    i_dq_prev: complex  #: measured at step k-1, A
    u_dq_prev: complex  #: voltage applied over period k-1, rotor frame at its middle, V
    u_ab_prev: complex  #: the same voltage in αβ (what the inverter applied), V
    theta_e: float  #: measured rotor electrical angle at step k, rad
    theta_e_prev: float  #: at step k-1, rad
    omega_m: float  #: measured mechanical speed, rad/s


def _k_t_current(torque: float, ctl: MTPAContext) -> float:
    """|T|/k_t (A), k_t = 1.5 p ψ_f: the amplitude the magnet's torque alone needs."""
    return abs(torque) / (1.5 * ctl.p * ctl.psi_f)


class ZeroD:
    """i_d = 0 control: θ = 0."""

    name = "foc_zero_d"

    def current(self, torque: float, ctl: MTPAContext) -> float:
        """The amplitude (A) the torque reference (N·m) asks for: |T*|/k_t."""
        return _k_t_current(torque, ctl)

    def angle(self, x: MTPAInputs, ctl: MTPAContext) -> float:
        return 0.0

    def start(self, theta: float, ctl: MTPAContext) -> None:
        """Take over at the present current angle (a live switch)."""


class FormulaMTPA:
    """Paper 002 eq 10 with the controller's L_d, L_q, ψ_f, at the amplitude that makes the
    torque with them (:func:`mtpa_current`)."""

    name = "foc_formula"

    def __init__(self) -> None:
        self._last = (0.0, 0.0)  #: (|T*|, I_s) of the last call: T* held, no search

    def current(self, torque: float, ctl: MTPAContext) -> float:
        t = abs(torque)
        if t != self._last[0]:
            i_s = mtpa_current(
                t, p=ctl.p, psi_f=ctl.psi_f, l_d=ctl.l_d, l_q=ctl.l_q, start=self._last[1]
            )
            self._last = (t, i_s)
        return self._last[1]

    def angle(self, x: MTPAInputs, ctl: MTPAContext) -> float:
        return formula_angle(x.i_s, ctl.psi_f, ctl.l_d, ctl.l_q)

    def start(self, theta: float, ctl: MTPAContext) -> None:
        """Memoryless: nothing to take over."""


class MTPAContext(NamedTuple):
    """The controller's constants an MTPA law may use."""

    ts: float  #: control period, s
    p: int  #: pole pairs
    r_s: float  #: Ω
    l_d: float  #: H (the formula only)
    l_q: float  #: H (the formula only)
    psi_f: float  #: Wb (the formula only)
    amplitude: float  #: dither amplitude A, rad
    samples: int  #: M, samples per dither period
    gain: float  #: integrator gain, rad/s per unit of gradient d(T/I)/dθ / k_t
    lowpass_hz: float  #: demodulated-gradient low-pass cutoff, Hz
    form: str  #: one of INJECTION_FORMS
    min_speed: float  #: rad/s below which θ0 holds (the flux balance divides by ω_e)
    max_angle: float  #: rad, bound of θ0
    observer_hz: float  #: how fast the flux observer is pulled to the voltage balance, Hz


class InjectionMTPA:
    """θ = θ0 + A sin(2πk/M): the dithered current angle; θ0 moved by an integrator until the
    demodulated gradient is zero (see the module's text for the two forms). ``gradient`` is the
    last low-passed one, normalised by the torque constant k_t = 1.5·p·ψ_f (the torque per ampere
    at θ = 0): d(T/I)/dθ / k_t in 1/rad — recorded in the command as ``mtpa_gradient``."""

    name = "foc_injection"

    def __init__(self) -> None:
        self.theta0 = 0.0
        self.gradient = math.nan
        self._lp = 0.0
        self._dfts: dict[str, SlidingDFT] = {}
        self._observer: FluxObserver | None = None
        self._current = SlidingDFT(2)  # replaced by the dither period's mean of I_s
        self._m = 0
        self._since = 0  #: steps since the law started (its DFT windows fill)

    def current(self, torque: float, ctl: MTPAContext) -> float:
        """|T*|/k_t: without L_d, L_q the injection cannot count the reluctance torque."""
        return _k_t_current(torque, ctl)

    def start(self, theta: float, ctl: MTPAContext) -> None:
        """Take over at the present current angle: θ0 starts there."""
        self.theta0 = theta

    def _windows(self, ctl: MTPAContext) -> dict[str, SlidingDFT]:
        if self._m != ctl.samples:
            m = self._m = ctl.samples
            if ctl.form == "corrected":  # bin 1: the dither component
                bins = {"tpa": 1, "th": 1}
                self._observer = FluxObserver(m, TWO_PI * ctl.observer_hz)
            else:  # bin 0: the means over a dither period
                bins = {"t": 1, "ud": 0, "uq": 0, "id": 0, "iq": 0}
            self._dfts = {name: SlidingDFT(m, k) for name, k in bins.items()}
            self._current = SlidingDFT(m, 0)
        return self._dfts

    def angle(self, x: MTPAInputs, ctl: MTPAContext) -> float:
        dfts = self._windows(ctl)
        m = ctl.samples
        dither = math.sin(TWO_PI * (x.k % m) / m)
        if self._since > 0:  # a period k-1 to learn from
            if self._observer is not None:
                g = _corrected(self._observer, dfts, x, ctl)
            else:
                g = _as_printed(dfts, x, ctl, self.theta0 + ctl.amplitude * dither)
            # two dither periods: the first fills the windows, the second lets the current
            # loop's response to the dither settle into them; and the current asked for must
            # have held within 2 % over the last period (a step in it is no gradient)
            mean = self._current.update(x.i_s).real
            steady = abs(x.i_s - mean) <= 0.02 * mean
            if self._since > 2 * m and steady and abs(x.omega_m) >= ctl.min_speed:
                a = 1.0 - math.exp(-TWO_PI * ctl.lowpass_hz * ctl.ts)  # first-order low-pass
                self._lp += a * (g - self._lp)
                self.gradient = self._lp
                lim = ctl.max_angle
                self.theta0 = min(max(self.theta0 + ctl.gain * ctl.ts * self._lp, -lim), lim)
        self._since += 1
        return self.theta0 + ctl.amplitude * dither


def _corrected(
    obs: FluxObserver, dfts: dict[str, SlidingDFT], x: MTPAInputs, ctl: MTPAContext
) -> float:
    """d(T/I)/dθ / k_t (1/rad) at step k, k_t = 1.5·p·ψ_f: the torque per ampere from the
    voltage-model flux and the measured current, against the measured current angle."""
    psi = obs.update(x, ctl)
    i = x.i_dq
    mag = abs(i)
    torque = 1.5 * ctl.p * (psi.real * i.imag - psi.imag * i.real)
    per_amp = dfts["tpa"].update(torque / mag if mag > 0.0 else 0.0)
    theta_h = dfts["th"].update(math.atan2(-i.real, x.sign * i.imag))
    den = abs(theta_h) ** 2
    scale = 1.5 * ctl.p * ctl.psi_f  # k_t, the torque per ampere at θ = 0: a share per radian
    if den == 0.0:
        return 0.0
    return x.sign * (per_amp.real * theta_h.real + per_amp.imag * theta_h.imag) / den / scale


class FluxObserver:
    """The stator flux from the voltage the controller applied, without L_d, L_q: in αβ,
    ψ(k) = ψ(k-1) + Ts·u(k-1) - R_s·Ts·(i(k-1) + i(k))/2 (the volt-seconds of a period are
    exact), pulled slowly (``pull`` 1/s) towards the steady-state balance of the rotor-frame
    voltage equations, ψ_d = (u_q - R_s i_q)/ω_e, ψ_q = -(u_d - R_s i_d)/ω_e, averaged over a
    dither period (which removes the dither exactly). The balance fixes the integrator's DC
    drift; the dither's fast flux changes come from the integration."""

    def __init__(self, samples: int, pull: float) -> None:
        self.psi_ab = 0j
        self.pull = pull
        self._balance = (SlidingDFT(samples, 0), SlidingDFT(samples, 0))
        self._started = False

    def update(self, x: MTPAInputs, ctl: MTPAContext) -> complex:
        """The flux in the rotor frame at step k (Wb). From the first step the rotor turns, the
        balance of that step fills the averaging window and starts the integration."""
        rot = cmath.exp(1j * x.theta_e)
        i_mid = 0.5 * (x.i_dq + x.i_dq_prev)
        w_e = ctl.p * x.omega_m
        d, q = self._balance
        if w_e != 0.0:
            v = x.u_dq_prev - ctl.r_s * i_mid
            if not self._started:
                d.reset(v.imag / w_e)
                q.reset(-v.real / w_e)
            d.update(v.imag / w_e)
            q.update(-v.real / w_e)
        balance = complex(d.value.real, q.value.real) * rot
        if not self._started:
            self.psi_ab = balance
            self._started = w_e != 0.0
            return self.psi_ab / rot
        i_ab = 0.5 * (x.i_dq * rot + x.i_dq_prev * cmath.exp(1j * x.theta_e_prev))
        du = x.u_ab_prev - ctl.r_s * i_ab + self.pull * (balance - self.psi_ab)
        self.psi_ab += ctl.ts * du
        return self.psi_ab / rot


def _as_printed(
    dfts: dict[str, SlidingDFT], x: MTPAInputs, ctl: MTPAContext, theta: float
) -> float:
    """Paper 002 eq 16 and 19 as printed (see the module's text); ``theta`` the dithered angle."""
    i, u = x.i_dq, x.u_dq_prev
    id_mean = dfts["id"].update(i.real).real
    iq_mean = dfts["iq"].update(i.imag).real
    ud_mean = dfts["ud"].update(u.real).real
    uq_mean = dfts["uq"].update(u.imag).real
    w_e = ctl.p * x.omega_m
    i_dh = -x.i_s * math.sin(theta)
    i_qh = x.sign * x.i_s * math.cos(theta)
    t_h = 0.0
    if w_e != 0.0 and iq_mean != 0.0:
        r_d = (ud_mean - ctl.r_s * id_mean) / (w_e * iq_mean)  # eq 15: "(L_d - L_q)·p"
        r_q = (uq_mean - ctl.r_s * iq_mean) / w_e  # eq 15: "ψ_f·p"
        t_h = 1.5 * i_qh * (r_d * i_dh + r_q)  # eq 16
    m = ctl.samples
    # the dither-frequency component as a signal (eq 17-18), demodulated with sin (eq 19)
    demod = dfts["t"].update(t_h).real * math.sin(TWO_PI * (x.k % m) / m)
    # eq 14 has no p: k_t·I_s of its torque, so the gradient is dT/dθ / (k_t I_s) as above
    scale = x.i_s * 1.5 * ctl.psi_f
    if scale <= 0.0:
        return 0.0
    return x.sign * demod / (0.5 * ctl.amplitude * scale)
