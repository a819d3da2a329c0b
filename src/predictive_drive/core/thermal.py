"""Thermal networks and the temperature laws of a machine's parameters
(docs/physics.md#losses-and-temperature).

Two kinds of network, both advanced exactly for a loss held constant over each step (zero-order
hold: what the plant's period means are):

- :class:`Foster`: a datasheet's junction-to-case impedance Z_th(t) = Σ R_i (1 - e^{-t/τ_i}),
  each term a first-order state driven by the die's loss. Its nodes are not physical: a Foster
  network gives the junction's rise above its case, nothing between.
- :class:`Cauer`: physical nodes with heat capacities, linked by thermal resistances to each
  other and to the coolant (a heatsink; a winding and a rotor). Advanced by its matrix
  exponential, computed once.

Temperatures are in °C, losses in W, thermal resistances in K/W, capacities in J/K.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

__all__ = [
    "COPPER_ALPHA",
    "Cauer",
    "Foster",
    "expm",
    "resistance_at",
]

#: temperature coefficient of copper's resistance at 20 °C, 1/K (annealed copper: 0.393 %/K)
COPPER_ALPHA = 0.00393


def resistance_at(r_ref: float, t: float, t_ref: float, alpha: float) -> float:
    """A resistance ``r_ref`` (Ω at ``t_ref`` °C) at ``t`` °C: r_ref·(1 + α(t - t_ref)). The same
    law, with a negative α, is a magnet's remanence (its flux linkage) against temperature."""
    return r_ref * (1.0 + alpha * (t - t_ref))


class Foster:
    """Foster networks of several dies at once, advanced every ``step`` s: die d's rise above
    its case after its losses P_d, Σ_i R_di (1 - e^{-t/τ_di}) for a step of P_d. ``r`` and
    ``tau``: each die's terms (K/W, s); dies with fewer terms are padded with empty ones."""

    def __init__(self, r: Sequence[Sequence[float]], tau: Sequence[Sequence[float]], step: float):
        width = max(len(x) for x in r)
        rr = np.zeros((len(r), width))
        decay = np.ones((len(r), width))
        for d, (ri, ti) in enumerate(zip(r, tau)):
            rr[d, : len(ri)] = ri
            decay[d, : len(ti)] = np.exp(-step / np.asarray(ti))
        self.step = step
        self.decay = decay  #: e^{-step/τ}
        self.gain = rr * (1.0 - decay)  #: R (1 - e^{-step/τ}), K/W
        self.rises = np.zeros_like(rr)  #: each term's rise, K

    def advance(self, losses: np.ndarray) -> np.ndarray:
        """Each die's rise above its case (K) after one step at ``losses`` (W, one per die)."""
        r = self.rises
        r *= self.decay
        r += self.gain * losses[:, None]
        out: np.ndarray = r.sum(axis=1)
        return out

    def impedance(self, t: float) -> np.ndarray:
        """Z_th(t) of each die, K/W (the closed form the steps follow)."""
        tau = -self.step / np.log(self.decay)
        r = self.gain / (1.0 - self.decay)
        out: np.ndarray = (r * (1.0 - np.exp(-t / tau))).sum(axis=1)
        return out


class Cauer:
    """A network of physical nodes: node n has heat capacity ``capacities[n]`` (J/K) and the
    ``links`` (a, b, R) join node a to node b (None: the coolant at ``coolant`` °C) through R
    K/W. Every node starts at the coolant's temperature; :meth:`advance` takes each node's
    heat input (W) for one ``step`` s."""

    def __init__(
        self,
        capacities: Sequence[float],
        links: Sequence[tuple[int, int | None, float]],
        *,
        coolant: float,
        step: float,
    ) -> None:
        n = len(capacities)
        g = np.zeros((n, n))  # conductances, the coolant's on the diagonal only
        to_coolant = np.zeros(n)
        for a, b, r in links:
            if b is None:
                to_coolant[a] += 1.0 / r
            else:
                g[a, b] += 1.0 / r
                g[b, a] += 1.0 / r
        c = np.asarray(capacities, dtype=float)
        a_mat = (g - np.diag(g.sum(axis=1) + to_coolant)) / c[:, None]
        self.phi = expm(a_mat * step)
        #: per unit of heat input: ∫_0^h e^{As} ds · C⁻¹, from the rise a steady input reaches
        self.gamma = np.linalg.solve(a_mat, self.phi - np.eye(n)) / c[None, :]
        self.coolant = coolant
        self.step = step
        self._phi = self.phi.tolist()  # a few nodes: plain floats are faster than numpy
        self._gamma = self.gamma.tolist()
        self._rises = [0.0] * n  #: each node above the coolant, K
        self._a = a_mat
        self._c = c

    def advance(self, heat: Sequence[float]) -> list[float]:
        """Each node's temperature (°C) after one step with ``heat`` (W) into each node."""
        rises, phi, gamma = self._rises, self._phi, self._gamma
        n = len(rises)
        self._rises = [
            sum(phi[a][b] * rises[b] + gamma[a][b] * heat[b] for b in range(n)) for a in range(n)
        ]
        return [r + self.coolant for r in self._rises]

    @property
    def temperatures(self) -> list[float]:
        """Each node's temperature, °C."""
        return [r + self.coolant for r in self._rises]

    def steady(self, heat: Sequence[float]) -> np.ndarray:
        """The temperatures a constant ``heat`` settles to, °C (-A⁻¹·C⁻¹·P)."""
        out: np.ndarray = -np.linalg.solve(self._a, np.asarray(heat) / self._c) + self.coolant
        return out


def expm(a: np.ndarray) -> np.ndarray:
    """e^A of a small square matrix: Taylor series to 18 terms after scaling A below norm 0.5,
    squared back (exact to rounding for a thermal network's few nodes)."""
    norm = float(np.abs(a).sum(axis=1).max()) if a.size else 0.0
    s = max(0, math.ceil(math.log2(norm / 0.5))) if norm > 0.5 else 0
    x = a / (2.0**s)
    term = np.eye(len(a))
    out = term.copy()
    for k in range(1, 19):
        term = term @ x / k
        out = out + term
    for _ in range(s):
        out = out @ out
    return out
