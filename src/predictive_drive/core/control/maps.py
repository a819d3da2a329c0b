"""What a PMSM controller that knows the machine's saturation reads off its flux map
(docs/physics.md#saturation): the apparent inductances and magnet flux at the measured current
(``mptc_pmsm``), the MTPA current and the i_d = 0 current of a torque (``foc_pmsm``).

A family takes the map when its section's ``saturation`` group names a model (the controller's
own map, as its ``motor`` is its own linear model); without one it keeps its linear ``motor``.
"""

from __future__ import annotations

import math
from bisect import bisect_left

import numpy as np

from ..machines.magnetics import FluxMap, PMSMSaturation, magnetic_model
from ..machines.pmsm import PMSM, PMSMCoefficients

__all__ = ["ApparentModel", "MapMTPA", "flux_map_of", "map_current"]

#: below this current (A) an apparent inductance is the incremental one (0/0 at zero current)
_SMALL = 1e-3


def flux_map_of(motor: PMSM, saturation: PMSMSaturation) -> FluxMap | None:
    """The controller's flux map (None: it keeps its linear ``motor``)."""
    return magnetic_model(motor, saturation).flux_map if saturation.on else None


class ApparentModel:
    """The linear model that agrees with the map at the measured current: ψ_f' = ψ_d(0, i_q),
    L_d' = (ψ_d(i) - ψ_f')/i_d, L_q' = ψ_q(i)/i_q (the incremental inductances where a current is
    ~0), so flux and torque formed from it are the map's at that current."""

    def __init__(self, flux_map: FluxMap, base: PMSMCoefficients) -> None:
        self.map = flux_map
        self.base = base

    def at(self, i_alpha: float, i_beta: float, theta_e: float) -> PMSMCoefficients:
        co, si = math.cos(theta_e), math.sin(theta_e)
        i_d = i_alpha * co + i_beta * si
        i_q = i_beta * co - i_alpha * si
        fm = self.map
        psi_d, psi_q = fm.flux(i_d, i_q)
        psi_f = fm.flux(0.0, i_q)[0]
        if abs(i_d) > _SMALL and abs(i_q) > _SMALL:
            l_d, l_q = (psi_d - psi_f) / i_d, psi_q / i_q
        else:
            l_dd, l_qq, _ = fm.incremental(i_d, i_q)
            l_d = (psi_d - psi_f) / i_d if abs(i_d) > _SMALL else l_dd
            l_q = psi_q / i_q if abs(i_q) > _SMALL else l_qq
        return self.base._replace(
            l_d=l_d, l_q=l_q, inv_l_d=1.0 / l_d, inv_l_q=1.0 / l_q, psi_f=psi_f
        )


class MapMTPA:
    """Torque → current on the map: along its MTPA curve (the angle that makes the most torque
    of each current amplitude, found over a grid of amplitudes and angles and refined), and
    along i_d = 0. Tables built once; a torque is looked up by linear interpolation."""

    def __init__(self, flux_map: FluxMap, p: int, *, amplitudes: int = 200) -> None:
        i_max = min(-flux_map.i_d[0], flux_map.i_d[-1], -flux_map.i_q[0], flux_map.i_q[-1])
        amp = np.linspace(0.0, i_max, amplitudes)
        theta = np.linspace(-0.5, 1.4, 761)  # from the q axis, towards -d
        aa, tt = np.meshgrid(amp, theta, indexing="ij")
        i_d, i_q = -aa * np.sin(tt), aa * np.cos(tt)
        pd, pq = flux_map.many(i_d, i_q)[:2]
        torque = 1.5 * p * (pd * i_q - pq * i_d)
        best = np.argmax(torque, axis=1)
        t_max = torque[np.arange(amplitudes), best]
        # torque must rise with the amplitude along the curve: keep its rising part
        keep = np.concatenate(([True], np.diff(t_max) > 0.0))
        self._t = t_max[keep].tolist()
        self._amp = amp[keep].tolist()
        self._theta = theta[best][keep].tolist()
        iq = np.linspace(0.0, flux_map.i_q[-1], 400)
        pd0, pq0 = flux_map.many(np.zeros_like(iq), iq)[:2]
        t0 = 1.5 * p * pd0 * iq
        rising = np.concatenate(([True], np.diff(t0) > 0.0))
        self._t0, self._iq0 = t0[rising].tolist(), iq[rising].tolist()

    def mtpa(self, torque: float) -> tuple[float, float]:
        """(amplitude A, angle from the q axis rad) of the MTPA point of |torque|."""
        t = abs(torque)
        return _interp(self._t, self._amp, t), _interp(self._t, self._theta, t)

    def zero_d(self, torque: float) -> float:
        """The i_q (A, its magnitude) that makes |torque| with i_d = 0."""
        return _interp(self._t0, self._iq0, abs(torque))


def _interp(xs: list[float], ys: list[float], x: float) -> float:
    """Linear interpolation on rising ``xs``, held at the ends."""
    k = bisect_left(xs, x)
    if k <= 0:
        return ys[0]
    if k >= len(xs):
        return ys[-1]
    a = (x - xs[k - 1]) / (xs[k] - xs[k - 1])
    return ys[k - 1] + a * (ys[k] - ys[k - 1])


def map_current(
    mtpa: MapMTPA, law: str, torque: float, i_s: float, theta: float
) -> tuple[float, float]:
    """(amplitude, angle) of ``foc_pmsm``'s current for ``torque`` on the map: the MTPA point
    (``foc_formula``), the i_d = 0 current (``foc_zero_d``); another law's (the injection finds
    its angle without a model) as it is."""
    if law == "foc_formula":
        return mtpa.mtpa(torque)
    if law == "foc_zero_d":
        return mtpa.zero_d(torque), 0.0
    return i_s, theta
