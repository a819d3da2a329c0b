"""The saturating machines on the inverter: the plants a scenario's ``plant.saturation`` picks
(docs/physics.md#saturation). Everything of the drive around the machine — segments, dead
time, delay, sensors, period means — is :class:`~.plant.InverterPlant`'s, as for the linear
machines; only the machine's state, its integrator and what it publishes differ.

A PMSM on a magnetic model that leaves the range the model holds stops the run: ConfigError
naming the step, the current and the range (the model beyond it is not known).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from ..errors import ConfigError
from .machines import Machine
from .machines.magnetics import OutsideMap, PMSMSaturation, magnetic_model
from .machines.saturated import (
    SAT_IM_STATE,
    SAT_PMSM_STATE,
    IMSaturation,
    SaturatedIM,
    SaturatedIMCoefficients,
    SaturatedPMSM,
    SaturatedPMSMCoefficients,
    saturated_im_current,
    saturated_im_rk4,
    saturated_pmsm_rk4,
)
from .plant import InverterPlant, Point
from .signals import State

__all__ = ["SaturatedIMPlant", "SaturatedPMSMPlant", "make_saturated_plant"]

TWO_PI = 2.0 * math.pi
_PS, _PW, _PT = SAT_PMSM_STATE.psi_dq, SAT_PMSM_STATE.omega_m, SAT_PMSM_STATE.theta_m
_IS, _IR, _IW, _IT = (
    SAT_IM_STATE.psi_s, SAT_IM_STATE.psi_rr, SAT_IM_STATE.omega_m, SAT_IM_STATE.theta_m
)  # fmt: skip


class SaturatedPMSMPlant(InverterPlant):
    """PMSM on a magnetic model; state (ψ_dq, ω_m, θ_m), initially the magnet's flux (zero
    current), at standstill."""

    motor: SaturatedPMSM
    coefficients = SaturatedPMSMCoefficients
    speed_index = _PW
    default_integrator = staticmethod(saturated_pmsm_rk4)

    def __init__(self, motor: SaturatedPMSM, **kwargs: Any) -> None:
        self.x0 = (complex(*motor.magnetics.psi0), 0.0, 0.0)
        super().__init__(motor, **kwargs)

    def _i_dq(self, x: tuple[Any, ...]) -> complex:
        psi = x[_PS]
        return complex(*self._coef.current(psi.real, psi.imag))

    def _i_ab(self, x: tuple[Any, ...]) -> complex:
        the = self._coef.p * x[_PT]
        return self._i_dq(x) * complex(math.cos(the), math.sin(the))

    def _point(self, x: tuple[Any, ...]) -> Point:
        psi, the = x[_PS], self._coef.p * x[_PT]
        i = self._i_dq(x)
        te = self._coef.torque_k * (psi.real * i.imag - psi.imag * i.real)
        return te, abs(psi), i, the, complex(math.cos(the), math.sin(the))

    def _outputs(self) -> tuple[complex, float, float, float, complex, float]:
        x = self.x
        psi, w, th = x[_PS], x[_PW], x[_PT]
        i = self._i_dq(x)
        the = self._coef.p * th
        rot = complex(math.cos(the), math.sin(the))
        te = self._coef.torque_k * (psi.real * i.imag - psi.imag * i.real)
        return i * rot, w, the % TWO_PI, te, psi * rot, th

    def step(self, command: Sequence[float]) -> State:
        """:meth:`InverterPlant.step`, stopped with ConfigError where the current leaves the
        range the magnetic model holds."""
        k, before = self.k, self.x
        try:
            state = super().step(command)
        except OutsideMap:
            self._beyond(k, self._i_dq(before), "during")
        i = self._i_dq(self.x)
        if not self.motor.magnetics.covers(i.real, i.imag):
            self._beyond(self.k, i, "at")
        return state

    def _beyond(self, k: int, i: complex, when: str) -> None:
        raise ConfigError(
            f"plant.saturation: {when} step {k} (t = {k * self.ts:.6g} s) the current i_d = "
            f"{i.real:.4g} A, i_q = {i.imag:.4g} A leaves the range of the machine's magnetics "
            f"({self.motor.magnetics.range_text()}); the model beyond it is not known: widen "
            f"the map or keep the drive's currents inside it (the torque limit)"
        )


class SaturatedIMPlant(InverterPlant):
    """Induction motor with main-flux saturation (Γ circuit); state (ψ_s, ψ_R, ω_m, θ_m),
    initially all zero."""

    motor: SaturatedIM
    coefficients = SaturatedIMCoefficients
    x0 = (0j, 0j, 0.0, 0.0)
    speed_index = _IW
    default_integrator = staticmethod(saturated_im_rk4)

    def _i_ab(self, x: tuple[Any, ...]) -> complex:
        return saturated_im_current(x[_IS], x[_IR], self._coef)

    def _point(self, x: tuple[Any, ...]) -> Point:
        psi, c = x[_IS], self._coef
        i = saturated_im_current(psi, x[_IR], c)
        te = c.torque_k * (psi.real * i.imag - psi.imag * i.real)
        the = c.p * x[_IT]
        rot = complex(math.cos(the), math.sin(the))
        return te, abs(psi), i * rot.conjugate(), the, rot

    def _outputs(self) -> tuple[complex, float, float, float, complex, float]:
        x = self.x
        psi, w, th = x[_IS], x[_IW], x[_IT]
        c = self._coef
        i = saturated_im_current(psi, x[_IR], c)
        te = c.torque_k * (psi.real * i.imag - psi.imag * i.real)
        return i, w, (c.p * th) % TWO_PI, te, psi, th


def make_saturated_plant(machine: str, motor: Any, saturation: Any, **kwargs: Any) -> InverterPlant:
    """The plant of a saturating machine (``saturation`` on); ``kwargs`` as
    :func:`~.plant.make_plant`'s."""
    if machine == Machine.PMSM:
        assert isinstance(saturation, PMSMSaturation)
        return SaturatedPMSMPlant(SaturatedPMSM(motor, magnetic_model(motor, saturation)), **kwargs)
    assert isinstance(saturation, IMSaturation)
    return SaturatedIMPlant(SaturatedIM(motor, saturation), **kwargs)
