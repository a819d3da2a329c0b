"""Paper 002: field-oriented control of the PMSM with SVPWM, the controller family ``foc_pmsm``
(docs/physics.md#field-oriented-control-and-mtpa). Its strategies are the MTPA laws of :mod:`.mtpa`.

Per step: the torque reference T* asks the MTPA law for the current amplitude I_s (|T*|/k_t, k_t =
1.5 p ψ_f, for i_d = 0 and the injection; the amplitude that makes T* at the MTPA angle for the
formula) and the angle θ from the q axis (the sign carried by i_q), i_d* = -I_s sin θ,
i_q* = ±I_s cos θ; the :class:`CurrentLoop` (a PI per axis with decoupling) turns the current
error into u_dq, limited to the circle inscribed in the hexagon (the PIs hold their integrators
while it limits: clamping anti-windup); inverse Park at the rotor angle of the period's middle
(θ_e + ω_e·Ts/2: the volt-seconds of a period act, on average, there), then SVPWM.

The current PIs (:mod:`.foc`, shared with ``foc_im``) are designed on the zero-order-hold model
of each axis with the controller's own R_s, L_d, L_q: the PI zero cancels the pole, so the
closed loop is first order at the chosen bandwidth f_c (or tuned by the technical optimum); with
``current_target: period_mean`` they hold the period's mean current, not the sample
(:func:`~.foc.mean_offset_dq`): at 0.5 kHz on paper 001's IPMSM the sample held leaves |ψ_s| 2.9 %
below its reference, the mean 0.5 % above.
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Mapping
from dataclasses import dataclass

from ...errors import ConfigError
from ..fields import check_fields, choice, quantity
from ..inverter import inverse_park, park
from ..machines import Machine
from ..machines.magnetics import PMSMSaturation
from ..machines.pmsm import PMSM, PMSMCoefficients
from ..signals import Reference, State
from ..svpwm import linear_limit
from .base import delay_compensation, pmsm_predicted
from .foc import (
    CurrentPI,
    DQCurrentLoop,
    FieldOrientedController,
    Modulator,
    current_bandwidth,
    current_pi,
    current_pi_of,
    current_target,
    current_tuning,
    dead_time_compensation,
    drop_compensation,
    mean_offset_dq,
)
from .maps import MapMTPA, flux_map_of, map_current
from .mtpa import INJECTION_FORMS, FormulaMTPA, InjectionMTPA, MTPAContext, MTPAInputs, ZeroD

__all__ = [
    "FOC_STRATEGIES",
    "CurrentLoop",
    "CurrentPI",
    "FOCController",
    "FOCParams",
    "current_pi",
]

NAN = math.nan
TWO_PI = 2.0 * math.pi

#: strategy name → MTPA law; registry order is the ``strategy`` index in commands
FOC_STRATEGIES: Mapping[str, type] = {
    "foc_zero_d": ZeroD,
    "foc_formula": FormulaMTPA,
    "foc_injection": InjectionMTPA,
}


@dataclass(frozen=True)
class FOCParams:
    """Controller settings of field-oriented control with MTPA (paper 002).

    ``motor`` is the controller's own model (may differ from the plant's: parameter mismatch);
    ``foc_injection`` uses its R_s and ψ_f (the power and the gradient's scale) but not L_d, L_q.
    """

    motor: PMSM
    strategy: str = choice("MTPA law; switchable at run time", tuple(FOC_STRATEGIES))
    current_bandwidth_hz: float = current_bandwidth(300.0)
    current_tuning: str = current_tuning("bandwidth")
    current_target: str = current_target("sample")
    injection_amplitude: float = quantity(
        "dither amplitude A of the current angle (foc_injection)", "rad", ge=0, le=0.5, default=0.05
    )
    injection_hz: float = quantity(
        "dither frequency f_h; 1/(f_h·Ts) must be a whole number of samples M",
        "Hz",
        gt=0,
        default=500.0,
    )
    injection_gain: float = quantity(
        "integrator gain of the angle per unit of the gradient d(T/I)/dθ / k_t (k_t = 1.5 p ψ_f)",
        "rad/s",
        ge=0,
        default=20.0,
    )
    injection_lowpass_hz: float = quantity(
        "low-pass cutoff of the demodulated gradient", "Hz", gt=0, default=20.0
    )
    injection_form: str = choice(
        "corrected (default) or as_printed (paper 002 eq 16, 19: biased; to show it)",
        INJECTION_FORMS,
        default="corrected",
    )
    injection_min_speed: float = quantity(
        "speed below which the angle holds (the power carries ω_m·T)", "rad/s", ge=0, default=5.0
    )
    max_current_angle: float = quantity(
        "bound of the injection's operating angle θ0", "rad", gt=0, le=1.5, default=0.8
    )
    injection_observer_hz: float = quantity(
        "how fast the injection's flux observer follows the voltage balance",
        "Hz",
        gt=0,
        default=5.0,
    )
    delay_compensation: bool = delay_compensation()
    dead_time_compensation: float = dead_time_compensation()
    drop_compensation: float = drop_compensation()
    #: the controller's own flux map (docs/physics.md#saturation): with a model, foc_formula
    #: and foc_zero_d take their current for T* from it; none: from the linear ``motor``
    saturation: PMSMSaturation = PMSMSaturation()

    def __post_init__(self) -> None:
        check_fields(self)


class CurrentLoop(DQCurrentLoop):
    """The PMSM's dq current loop (:class:`~.foc.DQCurrentLoop`): a PI per axis on its own R_s,
    L_d, L_q, decoupled by -ω_e L_q i_q and ω_e (L_d i_d + ψ_f), limited to ``u_max``."""

    def __init__(
        self, motor: PMSM, *, ts: float, bandwidth_hz: float, tuning: str = "bandwidth"
    ) -> None:
        self.l_d, self.l_q, self.psi_f = motor.l_d, motor.l_q, motor.psi_f
        r = motor.r_s
        super().__init__(
            current_pi_of(tuning, r=r, ind=motor.l_d, ts=ts, bandwidth_hz=bandwidth_hz),
            current_pi_of(tuning, r=r, ind=motor.l_q, ts=ts, bandwidth_hz=bandwidth_hz),
        )

    def voltage(self, i_ref: complex, i_dq: complex, w_e: float, u_max: float) -> complex:
        """u_dq (V) for the coming period from the reference and measured currents (A), the
        electrical speed (rad/s) and the voltage limit (V)."""
        l_d, l_q, psi_f = self.l_d, self.l_q, self.psi_f

        def decoupling(i_m: complex) -> complex:
            return complex(-w_e * l_q * i_m.imag, w_e * (l_d * i_m.real + psi_f))

        return self.voltage_with(i_ref, i_dq, u_max, decoupling)


class FOCController(FieldOrientedController):
    """Field-oriented control of the PMSM: ``step(state k, reference k) -> command k``."""

    family = "foc_pmsm"
    machine = Machine.PMSM
    params_type = FOCParams
    strategies = FOC_STRATEGIES

    def __init__(self, params: FOCParams, *, ts: float) -> None:
        m = params.motor
        samples = 1.0 / (params.injection_hz * ts)
        #: why foc_injection cannot run at this period (None: it can); the other laws can
        self._dither_error: str | None = None
        if abs(samples - round(samples)) > 1e-6 or round(samples) < 4:
            self._dither_error = (
                f"torque_controller.injection_hz: {params.injection_hz:g} Hz gives "
                f"{samples:.4g} samples per dither period at Ts = {ts:g} s; it must be a whole "
                f"number >= 4 (e.g. {1.0 / (round(max(samples, 4)) * ts):g} Hz)"
            )
            if params.strategy == "foc_injection":
                raise ConfigError(self._dither_error)
        self._ctx = MTPAContext(
            ts=ts,
            p=m.p,
            r_s=m.r_s,
            l_d=m.l_d,
            l_q=m.l_q,
            psi_f=m.psi_f,
            amplitude=params.injection_amplitude,
            samples=max(4, round(samples)),
            gain=params.injection_gain,
            lowpass_hz=params.injection_lowpass_hz,
            form=params.injection_form,
            min_speed=params.injection_min_speed,
            max_angle=params.max_current_angle,
            observer_hz=params.injection_observer_hz,
        )
        self.loop = CurrentLoop(
            m, ts=ts, bandwidth_hz=params.current_bandwidth_hz, tuning=params.current_tuning
        )
        self._k_t = 1.5 * m.p * m.psi_f
        self._coef = PMSMCoefficients.of(m)
        self._modulator = Modulator(
            ts=ts, dead_time=params.dead_time_compensation, drop=params.drop_compensation
        )
        self.theta = 0.0  #: current angle in use, rad
        self.u_dq = 0j  #: the voltage applied over the last period, rotor frame, V
        self.u_ab = 0j  #: the same in αβ, V
        self._theta_e_prev: float | None = None
        self.i_ref = 0j
        self._i_prev: complex | None = None
        self._i_dq = 0j
        self._mean = params.current_target == "period_mean"
        self.est_torque = self.est_flux = self.est_flux_angle = 0.0
        fm = flux_map_of(m, params.saturation)
        self._map = None if fm is None else MapMTPA(fm, m.p)
        super().__init__(params, ts=ts)

    def refusal(self, name: str) -> str | None:
        if name == "foc_injection" and self._dither_error is not None:
            return self._dither_error
        return super().refusal(name)

    def set_strategy(self, name: str) -> None:
        super().set_strategy(name)
        self.strategy.start(self.theta, self._ctx)  # bumpless: the new law starts where we are

    def _predict(self, state: State, u_ab: complex) -> State:
        return pmsm_predicted(self._coef, self.ts, state, u_ab)

    def _observe(self, state: State) -> None:
        c = self._ctx
        the = state.theta_e
        i_dq = park(complex(state.i_alpha, state.i_beta), the)
        if self._mean:  # the period's mean current, what the torque follows (.foc)
            i_dq += mean_offset_dq(
                self.u_dq, w=c.p * state.omega_m, ts=self.ts, r=c.r_s, l_d=c.l_d, l_q=c.l_q
            )
        self._i_dq = i_dq
        psi = complex(c.l_d * i_dq.real + c.psi_f, c.l_q * i_dq.imag)
        self.est_torque = 1.5 * c.p * (psi.real * i_dq.imag - psi.imag * i_dq.real)
        self.est_flux = abs(psi)
        self.est_flux_angle = (the + cmath.phase(psi)) % TWO_PI

    def _decide(self, state: State, ref: Reference) -> complex:
        c = self._ctx
        t_ref = ref.torque_ref
        sign = 1.0 if t_ref >= 0.0 else -1.0
        i_s = self.strategy.current(t_ref, c)
        i_dq = self._i_dq
        i_prev = i_dq if self._i_prev is None else self._i_prev
        the_prev = state.theta_e if self._theta_e_prev is None else self._theta_e_prev
        x = MTPAInputs(
            int(state.k),
            i_s,
            sign,
            i_dq,
            i_prev,
            self.u_dq,
            self.u_ab,
            state.theta_e,
            the_prev,
            state.omega_m,
        )
        theta = self.strategy.angle(x, c)
        if self._map is not None:  # T*'s current from the controller's flux map
            i_s, theta = map_current(self._map, self.strategy.name, t_ref, i_s, theta)
        i_ref = complex(-i_s * math.sin(theta), sign * i_s * math.cos(theta))
        w_e = c.p * state.omega_m
        u = self.loop.voltage(i_ref, i_dq, w_e, linear_limit(state.u_dc))
        self.u_dq = u
        self._i_prev = i_dq
        self._theta_e_prev = state.theta_e
        self.theta = theta
        self.i_ref = i_ref
        # αβ at the rotor angle of the period's middle, where its volt-seconds act on average
        self.u_ab = inverse_park(u, state.theta_e + 0.5 * w_e * self.ts)
        return self.u_ab

    def _mtpa(self) -> tuple[float, float]:
        return self.theta, getattr(self.strategy, "gradient", NAN)
