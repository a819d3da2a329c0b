"""Magnetic models of a saturating PMSM: the stator current as a function of the flux linkage in
the rotor frame, i_dq = i(ψ_dq), what the plant integrates (docs/physics.md#saturation); and the
flux map ψ_dq(i_dq) on a grid, what a controller that knows the saturation reads
(:class:`FluxMap`).

Kept apart from the machine's equations (:mod:`.saturated`), as the separation of magnetics and
dynamics in motulator's ``drive/model``. Three forms, all a :class:`PMSMSaturation`:

- ``algebraic``: the current as explicit functions of the flux (the algebraic model of
  Hinkkanen et al., IEEE TIA 2017: self- and cross-saturation of a synchronous reluctance
  machine), with the bridge term of Lelli, Hinkkanen and Giulii Capponi (ICEM 2024) for a PM
  machine's magnet and iron bridges and an optional d-axis flux offset (the magnet of the
  papers' machines). Conservative by construction: i = ∇W(ψ) for a magnetic energy W.
- ``curve``: the papers' machines with an assumed q-axis saturation, an algebraic model whose
  coefficients follow from the controller-side data (L_d, L_q, ψ_f, rated torque) and the share
  ``lq_drop`` by which L_q falls at rated current.
- ``table``: a measured flux map ψ_d(i_d, i_q), ψ_q(i_d, i_q) on a rectangular grid, checked on
  load (monotonic, conservative: ∂ψ_d/∂i_q = ∂ψ_q/∂i_d cell by cell) and inverted once onto a
  flux grid the plant interpolates bilinearly.

Beyond the range a map holds (the table's grid; ``max_current`` of an algebraic model) the model
is not known: the plant stops with an error naming the step and the current
(:class:`~predictive_drive.errors.ConfigError`).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from ...errors import ConfigError
from ..fields import check_fields, choice, quantity
from .pmsm import PMSM

__all__ = [
    "CONSERVATIVE_TOLERANCE",
    "FluxMap",
    "MAGNETICS",
    "MagneticModel",
    "PMSMSaturation",
    "magnetic_model",
]

#: the models a PMSM plant's ``saturation.model`` names ("none": the linear plant)
MAGNETICS = ("none", "curve", "algebraic", "table")
#: a table cell is conservative when |∂ψ_d/∂i_q - ∂ψ_q/∂i_d| is at most this share of its
#: smaller incremental self-inductance (a measured map's noise; a sampled exact map's
#: discretisation is far below)
CONSERVATIVE_TOLERANCE = 0.05
#: grid points per axis of the flux maps derived from an algebraic model (and of a table's
#: inverse): bilinear interpolation between them
GRID_POINTS = 81

Currents = Callable[[float, float], tuple[float, float]]


def _exponent(text: str) -> Any:
    return quantity(text, ge=0, default=1.0)


def _coefficient(text: str, unit: str) -> Any:
    return quantity(text, unit, ge=0, default=0.0)


@dataclass(frozen=True)
class PMSMSaturation:
    """A PMSM's magnetic saturation (docs/physics.md#saturation); ``model`` none: the linear
    machine of ``motor`` (L_d, L_q, ψ_f), today's plant.

    The algebraic model (Hinkkanen et al. 2017; Lelli et al. 2024 for the bridge), x =
    ψ_d - psi_offset, y = ψ_q:
    i_d = (a_d0 + a_dd|x|^S + a_dq/(V+2)·|x|^U·|y|^(V+2))·x + G_b·(ψ_d - psi_n),
    i_q = (a_q0 + a_qq|y|^T + a_dq/(U+2)·|x|^(U+2)·|y|^V)·y + k_q·G_b·y,
    G_b = a_b·r^W/(1 + a_bp·r^W), r = sqrt((ψ_d - psi_n)² + k_q·y²).
    """

    model: str = choice("magnetic model of the machine (none: linear)", MAGNETICS, default="none")
    lq_drop: float = quantity(
        "curve: share by which L_q falls at the q-axis current of rated torque", ge=0, le=0.9,
        default=0.0,
    )  # fmt: skip
    lq_exponent: float = quantity(
        "curve: exponent T of the q-axis saturation (steeper above rated as it grows)", gt=0,
        default=2.0,
    )  # fmt: skip
    psi_offset: float = quantity(
        "algebraic: d-axis flux at which the self- and cross-terms vanish (a magnet's flux)",
        "Wb", ge=0, default=0.0,
    )  # fmt: skip
    a_d0: float = _coefficient("algebraic: unsaturated d-axis inverse inductance", "1/H")
    a_dd: float = _coefficient("algebraic: d-axis self-saturation", "A/Wb^(S+1)")
    s: float = _exponent("algebraic: exponent S of the d-axis self-saturation")
    a_q0: float = _coefficient("algebraic: unsaturated q-axis inverse inductance", "1/H")
    a_qq: float = _coefficient("algebraic: q-axis self-saturation", "A/Wb^(T+1)")
    t: float = _exponent("algebraic: exponent T of the q-axis self-saturation")
    a_dq: float = _coefficient("algebraic: cross-saturation", "A/Wb^(U+V+3)")
    u: float = _exponent("algebraic: d-flux exponent U of the cross-saturation")
    v: float = quantity("algebraic: q-flux exponent V of the cross-saturation", ge=0, default=0.0)
    psi_n: float = quantity("algebraic: the magnet's flux in the bridge term", "Wb", default=0.0)
    a_b: float = _coefficient("algebraic: bridge inverse inductance", "A/Wb^(W+1)")
    a_bp: float = _coefficient("algebraic: bridge saturation", "1/Wb^W")
    w: float = _exponent("algebraic: exponent W of the bridge")
    k_q: float = _coefficient("algebraic: q-axis share of the bridge flux", "")
    max_current: float = quantity(
        "curve, algebraic: the current amplitude up to which the model holds (its fit's range)",
        "A", gt=0, default=100.0,
    )  # fmt: skip
    i_d: tuple[float, ...] = quantity("table: d-axis currents of the grid, rising", "A", default=())
    i_q: tuple[float, ...] = quantity("table: q-axis currents of the grid, rising", "A", default=())
    psi_d: tuple[float, ...] = quantity(
        "table: ψ_d at the grid points, row by row (one row per i_d)", "Wb", default=()
    )
    psi_q: tuple[float, ...] = quantity(
        "table: ψ_q at the grid points, row by row (one row per i_d)", "Wb", default=()
    )

    def __post_init__(self) -> None:
        check_fields(self)
        if self.model == "table":
            _check_table(self)
        elif self.model == "algebraic" and (self.a_d0 <= 0.0 or self.a_q0 <= 0.0):
            raise ConfigError(
                f"saturation.a_d0, saturation.a_q0: an algebraic model needs both > 0 "
                f"(the unsaturated inverse inductances), got {self.a_d0:g}, {self.a_q0:g} 1/H"
            )

    @property
    def on(self) -> bool:
        """The machine saturates (a model other than ``none``)."""
        return self.model != "none"


def _grid(sat: PMSMSaturation) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    i_d, i_q = np.asarray(sat.i_d), np.asarray(sat.i_q)
    shape = (len(i_d), len(i_q))
    return i_d, i_q, np.reshape(sat.psi_d, shape), np.reshape(sat.psi_q, shape)


def _check_table(sat: PMSMSaturation) -> None:
    """A measured map: its grid, monotonic and conservative; ConfigError names the key and the
    cell."""
    n_d, n_q = len(sat.i_d), len(sat.i_q)
    if n_d < 2 or n_q < 2:
        raise ConfigError(
            f"saturation.i_d, saturation.i_q: a table needs at least 2 currents per axis, got "
            f"{n_d} and {n_q}"
        )
    for key, axis in (("i_d", sat.i_d), ("i_q", sat.i_q)):
        if any(b <= a for a, b in zip(axis, axis[1:])):
            raise ConfigError(f"saturation.{key}: the grid's currents must rise, got {list(axis)}")
        if not axis[0] <= 0.0 <= axis[-1]:
            raise ConfigError(
                f"saturation.{key}: the grid {axis[0]:g}..{axis[-1]:g} A must hold 0 A (the "
                f"machine starts without current)"
            )
    for key in ("psi_d", "psi_q"):
        got = len(getattr(sat, key))
        if got != n_d * n_q:
            raise ConfigError(
                f"saturation.{key}: {got} values; the grid of {n_d} i_d × {n_q} i_q needs "
                f"{n_d * n_q} (row by row, one row per i_d)"
            )
    i_d, i_q, pd, pq = _grid(sat)
    l_dd = np.diff(pd, axis=0) / np.diff(i_d)[:, None]  # ∂ψ_d/∂i_d between rows
    l_qq = np.diff(pq, axis=1) / np.diff(i_q)[None, :]
    for key, slope, along in (("psi_d", l_dd, "i_d"), ("psi_q", l_qq, "i_q")):
        bad = np.argwhere(~(slope > 0.0))
        if len(bad):
            j, k = bad[0]
            raise ConfigError(
                f"saturation.{key}: not monotonic: it must rise with {along} (a positive "
                f"incremental inductance), but falls or stays between the grid points "
                f"{_cell(i_d, i_q, j, k, along)}"
            )
    # per cell: the mixed slopes, each the mean of the cell's two edges
    l_dq = 0.5 * (np.diff(pd[:-1], axis=1) + np.diff(pd[1:], axis=1)) / np.diff(i_q)[None, :]
    l_qd = 0.5 * (np.diff(pq[:, :-1], axis=0) + np.diff(pq[:, 1:], axis=0)) / np.diff(i_d)[:, None]
    own = np.minimum(0.5 * (l_dd[:, :-1] + l_dd[:, 1:]), 0.5 * (l_qq[:-1] + l_qq[1:]))
    gap = np.abs(l_dq - l_qd) / own
    j, k = np.unravel_index(int(np.argmax(gap)), gap.shape)
    if gap[j, k] > CONSERVATIVE_TOLERANCE:
        raise ConfigError(
            f"saturation.psi_d, saturation.psi_q: the map is not conservative (no magnetic "
            f"energy has it: ∂ψ_d/∂i_q must equal ∂ψ_q/∂i_d): in the cell i_d "
            f"{i_d[j]:g}..{i_d[j + 1]:g} A, i_q {i_q[k]:g}..{i_q[k + 1]:g} A, ∂ψ_d/∂i_q = "
            f"{l_dq[j, k] * 1e3:.4g} mH but ∂ψ_q/∂i_d = {l_qd[j, k] * 1e3:.4g} mH, "
            f"{gap[j, k]:.1%} of the smaller self-inductance (at most "
            f"{CONSERVATIVE_TOLERANCE:.0%})"
        )
    det = l_dd[:, :-1] * l_qq[:-1] - l_dq * l_qd
    if np.any(det <= 0.0):
        j, k = np.argwhere(det <= 0.0)[0]
        raise ConfigError(
            f"saturation.psi_d, saturation.psi_q: the incremental inductance matrix is not "
            f"positive definite in the cell i_d {i_d[j]:g}..{i_d[j + 1]:g} A, i_q "
            f"{i_q[k]:g}..{i_q[k + 1]:g} A: the currents are not a function of the flux there"
        )


def _cell(i_d: np.ndarray, i_q: np.ndarray, j: int, k: int, along: str) -> str:
    if along == "i_d":
        return f"i_d {i_d[j]:g} and {i_d[j + 1]:g} A at i_q {i_q[k]:g} A"
    return f"i_q {i_q[k]:g} and {i_q[k + 1]:g} A at i_d {i_d[j]:g} A"


class MagneticModel:
    """A saturating PMSM's magnetics at run time: :attr:`current` (ψ_d, ψ_q) → (i_d, i_q), the
    flux at zero current :attr:`psi0`, the range it holds (:meth:`covers`) and its flux map
    (:attr:`flux_map`)."""

    def __init__(
        self,
        current: Currents,
        *,
        bounds: tuple[float, float, float, float],
        max_current: float,
        what: str,
        forward: FluxMap | None = None,
    ) -> None:
        self.current = current
        #: i_d from, i_d to, i_q from, i_q to: the box the model holds (A)
        self.bounds = bounds
        self.max_current = max_current  #: A, the amplitude it holds (inf: the box alone)
        self.what = what  #: the model in words, for errors
        self._forward = forward
        self.psi0 = self.flux(0.0, 0.0)  #: ψ_dq at zero current (the magnet's), Wb

    def covers(self, i_d: float, i_q: float) -> bool:
        lo_d, hi_d, lo_q, hi_q = self.bounds
        return (
            lo_d <= i_d <= hi_d and lo_q <= i_q <= hi_q and i_d * i_d + i_q * i_q
            <= self.max_current * self.max_current
        )  # fmt: skip

    def range_text(self) -> str:
        lo_d, hi_d, lo_q, hi_q = self.bounds
        text = f"i_d {lo_d:g}..{hi_d:g} A, i_q {lo_q:g}..{hi_q:g} A"
        if math.isfinite(self.max_current):
            text = f"|i_s| <= {self.max_current:g} A"
        return f"{self.what} holds {text}"

    def flux(self, i_d: float, i_q: float) -> tuple[float, float]:
        """ψ_dq (Wb) at the currents (A): a table's own map, else Newton on :attr:`current`."""
        if self._forward is not None:
            return self._forward.flux(i_d, i_q)
        psi = _solve(self.current, np.array([float(i_d)]), np.array([float(i_q)]))
        return float(psi[0][0]), float(psi[1][0])

    @cached_property
    def flux_map(self) -> FluxMap:
        """ψ_dq on a current grid over the range the model holds (a table's own)."""
        if self._forward is not None:
            return self._forward
        lo_d, hi_d, lo_q, hi_q = self.bounds
        i_d = np.linspace(lo_d, hi_d, GRID_POINTS)
        i_q = np.linspace(lo_q, hi_q, GRID_POINTS)
        dd, qq = np.meshgrid(i_d, i_q, indexing="ij")
        pd, pq = _solve(self.current, dd.ravel(), qq.ravel())
        shape = dd.shape
        return FluxMap(i_d, i_q, pd.reshape(shape), pq.reshape(shape))


def _solve(current: Currents, i_d: np.ndarray, i_q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """ψ with current(ψ) = i, every point at once (an algebraic model's currents take arrays):
    Newton from the inverse inductances at the flux's origin, the Jacobian by central
    differences. ConfigError where it does not converge (the model is not invertible there)."""
    gd, gq = current(1e-3, 0.0), current(0.0, 1e-3)
    z = current(0.0, 0.0)
    k_d = max((gd[0] - z[0]) / 1e-3, 1e-9)
    k_q = max((gq[1] - z[1]) / 1e-3, 1e-9)
    pd, pq = (i_d - z[0]) / k_d, (i_q - z[1]) / k_q
    h = 1e-7
    scale = np.maximum(np.abs(i_d) + np.abs(i_q), 1.0)
    for _ in range(100):
        cd, cq = current(pd, pq)  # type: ignore[arg-type]
        ed, eq = np.asarray(cd) - i_d, np.asarray(cq) - i_q
        if np.all(np.abs(ed) + np.abs(eq) <= 1e-10 * scale):
            return pd, pq
        a1, b1 = current(pd + h, pq)  # type: ignore[arg-type]
        a0, b0 = current(pd - h, pq)  # type: ignore[arg-type]
        c1, d1 = current(pd, pq + h)  # type: ignore[arg-type]
        c0, d0 = current(pd, pq - h)  # type: ignore[arg-type]
        j11, j21 = (np.asarray(a1) - a0) / (2 * h), (np.asarray(b1) - b0) / (2 * h)
        j12, j22 = (np.asarray(c1) - c0) / (2 * h), (np.asarray(d1) - d0) / (2 * h)
        det = j11 * j22 - j12 * j21
        step_d = (j22 * ed - j12 * eq) / det
        step_q = (j11 * eq - j21 * ed) / det
        pd, pq = pd - step_d, pq - step_q
    bad = int(np.argmax(np.abs(np.asarray(current(pd, pq)[0]) - i_d)))  # type: ignore[arg-type]
    raise ConfigError(
        f"saturation: the flux for i_d = {i_d[bad]:g} A, i_q = {i_q[bad]:g} A was not found (the "
        f"model's currents are not a monotonic function of the flux there)"
    )


class FluxMap:
    """ψ_d(i_d, i_q), ψ_q(i_d, i_q) on a rectangular grid, interpolated bilinearly: what a
    controller that knows the saturation reads at the measured current."""

    def __init__(self, i_d: np.ndarray, i_q: np.ndarray, psi_d: np.ndarray, psi_q: np.ndarray):
        self.i_d, self.i_q = np.asarray(i_d, float), np.asarray(i_q, float)
        self.psi_d, self.psi_q = np.asarray(psi_d, float), np.asarray(psi_q, float)
        self._d = self.i_d.tolist()
        self._q = self.i_q.tolist()
        self._pd = self.psi_d.tolist()
        self._pq = self.psi_q.tolist()

    def flux(self, i_d: float, i_q: float) -> tuple[float, float]:
        """ψ_dq (Wb) at the currents (A), bilinear; held at the grid's edge beyond it."""
        j, a = _locate(self._d, i_d)
        k, b = _locate(self._q, i_q)
        pd, pq = self._pd, self._pq
        return _bilinear(pd, j, k, a, b), _bilinear(pq, j, k, a, b)

    def incremental(self, i_d: float, i_q: float) -> tuple[float, float, float]:
        """(∂ψ_d/∂i_d, ∂ψ_q/∂i_q, ∂ψ_d/∂i_q), H, of the grid cell holding the currents."""
        j, a = _locate(self._d, i_d)
        k, b = _locate(self._q, i_q)
        dd, dq = self._d[j + 1] - self._d[j], self._q[k + 1] - self._q[k]
        pd, pq = self._pd, self._pq
        l_dd = ((1 - b) * (pd[j + 1][k] - pd[j][k]) + b * (pd[j + 1][k + 1] - pd[j][k + 1])) / dd
        l_qq = ((1 - a) * (pq[j][k + 1] - pq[j][k]) + a * (pq[j + 1][k + 1] - pq[j + 1][k])) / dq
        l_dq = ((1 - a) * (pd[j][k + 1] - pd[j][k]) + a * (pd[j + 1][k + 1] - pd[j + 1][k])) / dq
        return l_dd, l_qq, l_dq

    def many(self, i_d: np.ndarray, i_q: np.ndarray) -> tuple[np.ndarray, ...]:
        """(ψ_d, ψ_q, ∂ψ_d/∂i_d, ∂ψ_q/∂i_q, ∂ψ_d/∂i_q, ∂ψ_q/∂i_d) at many currents at once,
        bilinear in each grid cell (clamped to the grid)."""
        j, a = _cells(self.i_d, i_d)
        k, b = _cells(self.i_q, i_q)
        dd = self.i_d[j + 1] - self.i_d[j]
        dq = self.i_q[k + 1] - self.i_q[k]
        out: list[np.ndarray] = []
        for t in (self.psi_d, self.psi_q):
            t00, t01, t10, t11 = t[j, k], t[j, k + 1], t[j + 1, k], t[j + 1, k + 1]
            out.append((1 - a) * ((1 - b) * t00 + b * t01) + a * ((1 - b) * t10 + b * t11))
            out.append(((1 - b) * (t10 - t00) + b * (t11 - t01)) / dd)  # along i_d
            out.append(((1 - a) * (t01 - t00) + a * (t11 - t10)) / dq)  # along i_q
        psi_d, d_dd, d_dq, psi_q, q_dd, q_dq = out
        return psi_d, psi_q, d_dd, q_dq, d_dq, q_dd

    def torque(self, i_d: float, i_q: float, p: int) -> float:
        """T_e = 1.5 p (ψ_d i_q - ψ_q i_d), N·m, on the map."""
        pd, pq = self.flux(i_d, i_q)
        return 1.5 * p * (pd * i_q - pq * i_d)


def _locate(axis: list[float], x: float) -> tuple[int, float]:
    """The cell of a rising grid that holds x and x's share across it (clamped at the ends)."""
    n = len(axis) - 1
    lo, hi = 0, n
    if x <= axis[0]:
        return 0, 0.0
    if x >= axis[n]:
        return n - 1, 1.0
    while hi - lo > 1:
        mid = (lo + hi) >> 1
        if axis[mid] <= x:
            lo = mid
        else:
            hi = mid
    return lo, (x - axis[lo]) / (axis[lo + 1] - axis[lo])


def _cells(axis: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_locate` for many points at once."""
    j = np.clip(np.searchsorted(axis, x, side="right") - 1, 0, len(axis) - 2)
    a = np.clip((x - axis[j]) / (axis[j + 1] - axis[j]), 0.0, 1.0)
    return j, a


def _bilinear(t: list[list[float]], j: int, k: int, a: float, b: float) -> float:
    return (1 - a) * ((1 - b) * t[j][k] + b * t[j][k + 1]) + a * (
        (1 - b) * t[j + 1][k] + b * t[j + 1][k + 1]
    )


def algebraic_currents(sat: PMSMSaturation) -> Currents:
    """i_dq(ψ_dq) of the algebraic model (see :class:`PMSMSaturation`); floats or numpy arrays."""
    a_d0, a_dd, s, a_q0, a_qq, t = sat.a_d0, sat.a_dd, sat.s, sat.a_q0, sat.a_qq, sat.t
    c_d, c_q, u, v = sat.a_dq / (sat.v + 2.0), sat.a_dq / (sat.u + 2.0), sat.u, sat.v
    off, psi_n, a_b, a_bp, w, k_q = sat.psi_offset, sat.psi_n, sat.a_b, sat.a_bp, sat.w, sat.k_q

    def current(psi_d: float, psi_q: float) -> tuple[float, float]:
        x = psi_d - off
        ax, ay = abs(x), abs(psi_q)
        i_d = (a_d0 + a_dd * ax**s + c_d * ax**u * ay ** (v + 2.0)) * x
        i_q = (a_q0 + a_qq * ay**t + c_q * ax ** (u + 2.0) * ay**v) * psi_q
        if a_b:
            b = psi_d - psi_n
            rw = (b * b + k_q * psi_q * psi_q) ** (0.5 * w)
            g_b = a_b * rw / (1.0 + a_bp * rw)
            i_d = i_d + g_b * b
            i_q = i_q + k_q * g_b * psi_q
        return i_d, i_q

    return current


def curve_saturation(motor: PMSM, sat: PMSMSaturation) -> PMSMSaturation:
    """The algebraic model of ``curve``: the motor's linear machine (a_d0 = 1/L_d, a_q0 = 1/L_q,
    the magnet a d-axis offset ψ_f) with q-axis self-saturation i_q = ψ_q/L_q·(1 + c·|ψ_q/ψ_qr|^T):
    its apparent L_q = ψ_q/i_q is L_q·(1 - lq_drop) at i_qr = T_r/(1.5 p ψ_f), the q-axis current
    of rated torque (ψ_qr = L_q·i_qr; c = lq_drop/(1 - lq_drop)^(T+1) makes it so)."""
    i_qr = motor.rated_torque / (1.5 * motor.p * motor.psi_f)
    psi_qr = motor.l_q * i_qr
    t = sat.lq_exponent
    c = sat.lq_drop / (1.0 - sat.lq_drop) ** (t + 1.0)
    return PMSMSaturation(
        model="algebraic",
        psi_offset=motor.psi_f,
        a_d0=1.0 / motor.l_d,
        a_q0=1.0 / motor.l_q,
        a_qq=c / (motor.l_q * psi_qr**t),
        t=t,
        max_current=sat.max_current,
    )


def magnetic_model(motor: PMSM, sat: PMSMSaturation) -> MagneticModel:
    """The run-time model of a saturation section (``model`` other than none)."""
    if sat.model == "curve":
        alg = curve_saturation(motor, sat)
        return MagneticModel(
            algebraic_currents(alg),
            bounds=(-sat.max_current, sat.max_current, -sat.max_current, sat.max_current),
            max_current=sat.max_current,
            what=f"the assumed curve (L_q -{sat.lq_drop:.0%} at rated current)",
        )
    if sat.model == "algebraic":
        return MagneticModel(
            algebraic_currents(sat),
            bounds=(-sat.max_current, sat.max_current, -sat.max_current, sat.max_current),
            max_current=sat.max_current,
            what="the algebraic model",
        )
    if sat.model == "table":
        i_d, i_q, pd, pq = _grid(sat)
        forward = FluxMap(i_d, i_q, pd, pq)
        return MagneticModel(
            _inverse_table(forward),
            bounds=(float(i_d[0]), float(i_d[-1]), float(i_q[0]), float(i_q[-1])),
            max_current=math.inf,
            what="the flux map",
            forward=forward,
        )
    raise ValueError(f"saturation.model {sat.model!r}: no magnetic model (linear machine)")


class OutsideMap(ArithmeticError):
    """The flux lies outside the region a table's inverse covers."""


def _inverse_table(forward: FluxMap) -> Currents:
    """i_dq(ψ_dq) of a flux map: the map inverted once onto a regular flux grid (Newton on the
    bilinear map), interpolated bilinearly; :class:`OutsideMap` beyond the fluxes the map
    reaches."""
    pd_axis = np.linspace(forward.psi_d.min(), forward.psi_d.max(), GRID_POINTS)
    pq_axis = np.linspace(forward.psi_q.min(), forward.psi_q.max(), GRID_POINTS)
    gd, gq = np.meshgrid(pd_axis, pq_axis, indexing="ij")
    # Newton for i with flux(i) = ψ, vectorised over the grid, from the map's mean inductances
    # about its zero-current flux
    p0 = forward.flux(0.0, 0.0)
    ld = float(np.mean(np.diff(forward.psi_d, axis=0)) / np.mean(np.diff(forward.i_d)))
    lq = float(np.mean(np.diff(forward.psi_q, axis=1)) / np.mean(np.diff(forward.i_q)))
    i_d, i_q = (gd - p0[0]) / ld, (gq - p0[1]) / lq
    lo_d, hi_d = forward.i_d[0], forward.i_d[-1]
    lo_q, hi_q = forward.i_q[0], forward.i_q[-1]
    for _ in range(60):
        i_d, i_q = np.clip(i_d, lo_d, hi_d), np.clip(i_q, lo_q, hi_q)
        fd, fq, l_dd, l_qq, l_dq, l_qd = forward.many(i_d, i_q)
        ed, eq = fd - gd, fq - gq
        if np.max(np.abs(ed) + np.abs(eq)) < 1e-13:
            break
        det = l_dd * l_qq - l_dq * l_qd
        i_d = i_d - (l_qq * ed - l_dq * eq) / det
        i_q = i_q - (l_dd * eq - l_qd * ed) / det
    fd, fq = forward.many(np.clip(i_d, lo_d, hi_d), np.clip(i_q, lo_q, hi_q))[:2]
    inside = (
        (i_d >= lo_d) & (i_d <= hi_d) & (i_q >= lo_q) & (i_q <= hi_q)
        & (np.abs(fd - gd) + np.abs(fq - gq) <= 1e-9)
    )  # fmt: skip
    axis_d, axis_q = pd_axis.tolist(), pq_axis.tolist()
    table_d = np.where(inside, i_d, np.nan).tolist()
    table_q = np.where(inside, i_q, np.nan).tolist()

    def current(psi_d: float, psi_q: float) -> tuple[float, float]:
        if not (axis_d[0] <= psi_d <= axis_d[-1] and axis_q[0] <= psi_q <= axis_q[-1]):
            raise OutsideMap(psi_d, psi_q)
        j, a = _locate(axis_d, psi_d)
        k, b = _locate(axis_q, psi_q)
        i_d = _bilinear(table_d, j, k, a, b)
        if i_d != i_d:  # a corner of the cell lies beyond the map
            raise OutsideMap(psi_d, psi_q)
        return i_d, _bilinear(table_q, j, k, a, b)

    return current
