"""What the controller measures: phase currents through an ADC with noise, the rotor position
from an incremental encoder and the speed from its counts (docs/physics.md#sensors).

Two phase currents are measured (a and b; c = -a - b, as a drive with two sensors does): each
gets Gaussian noise of ``noise`` A rms, then the ADC rounds it to its step 2·range/2^bits and
clips it to ±range. The encoder counts 4 edges per line (quadrature); the angle is the count's,
and the speed is the count difference over the last ``window`` periods (the M-method: its
resolution is 2π/(4·lines·window·Ts) rad/s and it lags by half the window; over the first
periods of a run the window is the periods there have been). Every random number comes from one
seeded generator (numpy's PCG64), drawn in the same order on every engine: the same seed gives
the same measurements bit for bit.
"""

from __future__ import annotations

import math
from collections import deque

import numpy as np

from .inverter import inverse_clarke

__all__ = ["Sensors"]

TWO_PI = 2.0 * math.pi
SQRT3 = math.sqrt(3.0)


class Sensors:
    """``measure(i_ab, theta_m, omega_m) -> (i_alpha, i_beta, omega_m, theta_e)`` as measured,
    once per sample instant, in step order."""

    def __init__(
        self,
        *,
        ts: float,
        pole_pairs: int,
        noise: float = 0.0,
        adc_bits: int = 0,
        adc_range: float = math.nan,
        encoder_lines: int = 0,
        speed_window: float = 1e-3,
        seed: int = 0,
    ) -> None:
        self.ts = ts
        self.p = pole_pairs
        self.noise = noise
        self.lsb = 2.0 * adc_range / 2**adc_bits if adc_bits else 0.0
        self.adc_range = adc_range
        self.counts_per_rev = 4 * encoder_lines
        self.window = max(1, round(speed_window / ts))
        self._counts: deque[int] = deque(maxlen=self.window + 1)
        self._rng = np.random.Generator(np.random.PCG64(seed))

    def _adc(self, i: float) -> float:
        if self.noise:
            i += self.noise * float(self._rng.standard_normal())
        if self.lsb:
            i = min(max(round(i / self.lsb) * self.lsb, -self.adc_range), self.adc_range)
        return i

    def measure(
        self, i_ab: complex, theta_m: float, omega_m: float
    ) -> tuple[float, float, float, float]:
        """The measured (i_α, i_β, ω_m, θ_e wrapped) of the true current, shaft angle and speed."""
        if self.noise or self.lsb:
            a, b, _ = inverse_clarke(i_ab)
            i_a, i_b = self._adc(a), self._adc(b)
            i_alpha, i_beta = i_a, (i_a + 2.0 * i_b) / SQRT3
        else:
            i_alpha, i_beta = i_ab.real, i_ab.imag
        if self.counts_per_rev:
            count = math.floor(theta_m * self.counts_per_rev / TWO_PI)
            counts = self._counts
            counts.append(count)
            span = len(counts) - 1
            step = TWO_PI / self.counts_per_rev
            omega_m = (count - counts[0]) * step / (span * self.ts) if span else 0.0
            theta_m = count * step
        return i_alpha, i_beta, omega_m, (self.p * theta_m) % TWO_PI
