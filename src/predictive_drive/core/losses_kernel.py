"""The ledger's booking compiled (docs/physics.md#losses-and-temperature): the periods of a
thermal step booked at once by a numba kernel, where CPython spends a few microseconds on each
segment's dozen float operations.

The one part of the losses that is not numpy and the standard library: numba is optional
(``pip install 'predictive_drive[fast]'``) and imported here only, the first time the kernel is
asked for. :meth:`~.losses.Ledger.close`'s per-period booking stays the reference: :func:`book`
does the same arithmetic in the same order — each segment's conduction energy per device, the DC
link's and the copper's, the switching energies at each change of a leg's level, then the
period's powers — so its rows are the reference's, bit for bit
(``test_the_compiled_booking_is_the_reference_bit_for_bit``). :func:`book` is plain Python that
numba compiles as it is; run uncompiled it is the same function (the tests run it so where numba
is not installed), only slow.

A segment is a row of numbers: its length h (s), the stator current α, β at its start (A; the
phase currents are its inverse Clarke transform, as the plant takes them), and each leg's
conducting device (:data:`~.signals.DEVICES` index, leg a's + 16 × leg b's + 256 × leg c's: its
place in the leg says the leg's level, the upper transistor or diode high) — :data:`SEG_WIDTH`
numbers; then, where the machine has rotor copper or a load machine holds the speed
(:data:`SEG_WIDTH_FULL`), an induction motor's stator flux α, β at its start (Wb; else 0) and
the torque at its start (N·m; else 0). Each device's on-state voltage against the current is the
plant's, sign(i)·(v0 + r·|i|) at the current at the segment's start. A segment
ends where the next begins: the last of a period where the next period's first begins, the last
of the last period at ``tail`` (a segment's row of the state the periods end at). A period is a
row of :data:`PERIOD_WIDTH`: its number of segments, the speed at its start and end (rad/s),
the shaft's angle over it (rad), the load torque (N·m), the viscous coefficient (N·m·s), and
the stator flux α, β at its end (Wb).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import cache
from typing import Any

import numpy as np

from .control.kernels import kernel_unavailable

__all__ = [
    "PERIOD_WIDTH",
    "SEG_WIDTH",
    "SEG_WIDTH_FULL",
    "book",
    "compiled_booking",
    "compiled_thermal",
    "kernel_unavailable",
    "thermal",
]

SEG_WIDTH = 4  #: numbers per segment (see the module's docstring)
SEG_WIDTH_FULL = 7  #: numbers per segment of a machine with rotor copper or a held speed
PERIOD_WIDTH = 8  #: numbers per period
FIELDS = 21  #: the powers a period books: p_dc … p_sw_d and the 12 devices' (W)


def book(
    segs: np.ndarray,
    periods: np.ndarray,
    tail: np.ndarray,
    grids: np.ndarray,
    grid_info: np.ndarray,
    lines: np.ndarray,
    last: np.ndarray,
    psi_prev: np.ndarray,
    params: np.ndarray,
    out: np.ndarray,
    acc: np.ndarray,
) -> None:
    """Book ``periods`` (their ``segs`` one after another) into ``out`` (per period a row
    whose first :data:`FIELDS` numbers are its powers), adding each period's per-device powers to ``acc[:12]``
    and its copper (stator and iron, rotor) to ``acc[12]``, ``acc[13]``.

    ``grids[d, j, n]``: device d's switching energy j (a transistor's E_on, E_off; a diode's
    E_rr twice) at its n-th temperature on the uniform current grid; ``grid_info[d, j]``:
    (1/step, the upper temperature's weight at the device's T_j, the DC link's scale, present,
    the lower and the upper temperature's n). ``lines``: each device's on-state line v0, r (V,
    Ω) at its T_j. ``last``: each leg's level and device at the end
    of the period before (updated); ``psi_prev``: the stator flux α, β at that end and whether
    there is one (updated).
    ``params``: Ts, U_dc, R_s, R_r, L_s and 1/L_m of a machine with rotor copper (L_s = 0:
    none), whether a load machine holds the speed, k_h and k_e of the iron losses (0: none),
    whether the devices have switching energies, √3/2 (as the plant's inverse Clarke transform
    has it)."""
    ts, u_dc, r_s, r_r = params[0], params[1], params[2], params[3]
    l_s, inv_l_m, held = params[4], params[5], params[6] != 0.0
    k_h, k_e, switching = params[7], params[8], params[9] != 0.0
    half_sqrt3 = params[10]  # inverse_clarke's
    iron = k_h != 0.0 or k_e != 0.0
    rotor = l_s != 0.0
    inv = 1.0 / ts
    e = np.zeros(12)
    sw = np.zeros(12)
    hits = np.zeros(3, np.int64)
    kinds = np.zeros(3, np.int64)
    s0 = 0
    for p in range(periods.shape[0]):
        n = int(periods[p, 0])
        for d in range(12):
            e[d] = 0.0
            sw[d] = 0.0
        e_dc = 0.0
        e_cu = 0.0
        e_cur = 0.0
        e_te = 0.0
        for j in range(n):
            s = segs[s0 + j]
            nx = segs[s0 + j + 1] if s0 + j + 1 < segs.shape[0] else tail
            ar, ai, br, bi = s[1], s[2], nx[1], nx[2]
            a0, b0 = ar, br  # the phase currents: inverse_clarke of the stator current's
            a1, a2 = -0.5 * ar + half_sqrt3 * ai, -0.5 * ar - half_sqrt3 * ai
            b1, b2 = -0.5 * br + half_sqrt3 * bi, -0.5 * br - half_sqrt3 * bi
            packed = int(s[3])
            d0, d1, d2 = packed & 15, (packed >> 4) & 15, (packed >> 8) & 15
            h = s[0]
            if switching:  # Ledger._commutate at each change of a leg's level
                for leg in range(3):
                    dev = (packed >> (4 * leg)) & 15
                    if (1.0 if (dev & 3) < 2 else 0.0) == last[leg]:
                        continue
                    base, cur = 4 * leg, (a0 if leg == 0 else a1 if leg == 1 else a2)
                    old, new = int(last[3 + leg]) & 3, dev & 3
                    booked = 0  # the energies booked: E_off of the old, E_on of the new, E_rr
                    if (old == 0 and cur > 0.0) or (old == 2 and cur < 0.0):
                        hits[0], kinds[0], booked = base + old, 1, 1
                    if (new == 0 and cur > 0.0) or (new == 2 and cur < 0.0):
                        hits[booked], kinds[booked] = base + new, 0
                        hits[booked + 1], kinds[booked + 1] = base + (3 if new == 0 else 1), 0
                        booked += 2
                    for t in range(booked):  # devices.grid_value
                        d, g = hits[t], kinds[t]
                        if grid_info[d, g, 3] == 0.0:
                            continue
                        lo = grids[d, g, int(grid_info[d, g, 4])]
                        hi = grids[d, g, int(grid_info[d, g, 5])]
                        x = abs(cur) * grid_info[d, g, 0]
                        k = int(x)
                        if k > lo.shape[0] - 2:
                            k = lo.shape[0] - 2
                        f = x - k
                        v = lo[k] + f * (lo[k + 1] - lo[k])
                        v = (v + grid_info[d, g, 1] * (hi[k] + f * (hi[k + 1] - hi[k]) - v)) * (
                            grid_info[d, g, 2]
                        )
                        sw[d] += v if v > 0.0 else 0.0
            hh = 0.5 * h
            q0, q1, q2 = hh * (a0 + b0), hh * (a1 + b1), hh * (a2 + b2)
            # each device's on-state voltage against its current, as the plant's legs drop it
            n0 = 1.0 if a0 > 0.0 else (-1.0 if a0 < 0.0 else 0.0)  # the current's sign
            n1 = 1.0 if a1 > 0.0 else (-1.0 if a1 < 0.0 else 0.0)
            n2 = 1.0 if a2 > 0.0 else (-1.0 if a2 < 0.0 else 0.0)
            v0 = n0 * (lines[d0, 0] + lines[d0, 1] * abs(a0))
            v1 = n1 * (lines[d1, 0] + lines[d1, 1] * abs(a1))
            v2 = n2 * (lines[d2, 0] + lines[d2, 1] * abs(a2))
            e[d0] += v0 * q0
            e[d1] += v1 * q1
            e[d2] += v2 * q2
            g0 = 1.0 if (d0 & 3) < 2 else 0.0  # the leg's level: high on the upper device
            g1 = 1.0 if (d1 & 3) < 2 else 0.0
            g2 = 1.0 if (d2 & 3) < 2 else 0.0
            e_dc += g0 * q0 + g1 * q1 + g2 * q2
            e_cu += h * (ar * (ar + br) + ai * (ai + bi) + br * br + bi * bi)
            last[0], last[1], last[2] = g0, g1, g2
            last[3], last[4], last[5] = d0, d1, d2
        if rotor:  # an induction motor's rotor current (ψ_s - L_s i_s)/L_m
            for j in range(n):
                s = segs[s0 + j]
                nx = segs[s0 + j + 1] if s0 + j + 1 < segs.shape[0] else tail
                psi_r, psi_i, i_r, i_i = nx[4], nx[5], nx[1], nx[2]
                ar = (s[4] - l_s * s[1]) * inv_l_m
                ai = (s[5] - l_s * s[2]) * inv_l_m
                br = (psi_r - l_s * i_r) * inv_l_m
                bi = (psi_i - l_s * i_i) * inv_l_m
                e_cur += s[0] * (ar * (ar + br) + ai * (ai + bi) + br * br + bi * bi)
        if held:  # the torque a load machine holding the speed takes
            for j in range(n):
                t1 = segs[s0 + j + 1, 6] if s0 + j + 1 < segs.shape[0] else tail[6]
                e_te += 0.5 * segs[s0 + j, 0] * (segs[s0 + j, 6] + t1)
        s0 += n
        w0, w1 = periods[p, 1], periods[p, 2]
        pr, pi = periods[p, 6], periods[p, 7]
        p_fe = 0.0
        if iron and psi_prev[2] != 0.0:
            br, bi = psi_prev[0], psi_prev[1]
            cross = br * pi - bi * pr
            dot = br * pr + bi * pi
            f = abs(math.atan2(cross, dot)) * inv / (2.0 * math.pi)
            m = abs(complex(br, bi)) + abs(complex(pr, pi))  # hypot as abs() has it
            p_fe = (k_h * f + k_e * f * f) * (m * m) / 4
        psi_prev[0], psi_prev[1], psi_prev[2] = pr, pi, 1.0
        cu_s = 0.5 * r_s * e_cu * inv
        cu_r = 0.5 * r_r * e_cur * inv
        row = out[p]
        row[0] = u_dc * e_dc * inv
        row[1] = e_te * inv * w1 if held else periods[p, 4] * periods[p, 3] * inv
        row[2] = cu_s + cu_r
        row[3] = p_fe
        row[4] = periods[p, 5] * (w0 * w0 + w0 * w1 + w1 * w1) / 3.0
        row[5] = (e[0] + e[2] + e[4] + e[6] + e[8] + e[10]) * inv
        row[6] = (e[1] + e[3] + e[5] + e[7] + e[9] + e[11]) * inv
        row[7] = (sw[0] + sw[2] + sw[4] + sw[6] + sw[8] + sw[10]) * inv
        row[8] = (sw[1] + sw[3] + sw[5] + sw[7] + sw[9] + sw[11]) * inv
        for d in range(12):
            power = (e[d] + sw[d]) * inv
            row[9 + d] = power
            acc[d] = acc[d] + power
        acc[12] += cu_s + p_fe
        acc[13] += cu_r


def thermal(
    acc: np.ndarray,
    periods: float,
    decay: np.ndarray,
    gain: np.ndarray,
    rises: np.ndarray,
    die_of: np.ndarray,
    sink: np.ndarray,
    line_t: np.ndarray,
    line_v0: np.ndarray,
    line_r: np.ndarray,
    energy_t: np.ndarray,
    grid_info: np.ndarray,
    lines: np.ndarray,
    tj: np.ndarray,
) -> None:
    """:meth:`~.losses.Ledger._advance`'s devices: one thermal step with the mean of the
    per-device powers ``acc[:12]`` over ``periods`` periods — each die's Foster network
    (``rises`` advanced in place by ``decay``, ``gain``; die ``die_of[d]`` of device d), the
    heatsink's node (``sink``: Φ, Γ, its rise over the coolant (updated), the coolant, the case
    to heatsink resistance; its temperature out in ``sink[5]``) — and at each device's new T_j
    (``tj``, out) its on-state line (``lines``, out; the lines ``line_v0``, ``line_r`` at the
    temperatures ``line_t``, NaN-padded) and where T_j falls between its energies' curves
    (``grid_info[d, j, 1, 4, 5]``, out; ``energy_t[d, j]`` their temperatures, NaN-padded)."""

    def bracket(temps: np.ndarray, t: float) -> tuple[int, int, float]:
        """:func:`~.devices.bracket` of ``t`` among the ascending ``temps`` (NaN-padded)."""
        n = 0
        while n < temps.shape[0] and temps[n] == temps[n]:
            n += 1
        if n == 1 or t <= temps[0]:
            return 0, 0, 0.0
        if t >= temps[n - 1]:
            return n - 1, n - 1, 0.0
        hi = 0
        while temps[hi] < t:  # bisect_left
            hi += 1
        lo = hi - 1
        return lo, hi, (t - temps[lo]) / (temps[hi] - temps[lo])

    mean = np.empty(12)
    total = 0.0
    for d in range(12):
        mean[d] = acc[d] / periods
        total += mean[d]
    dies = rises.shape[0]
    rise = np.zeros(dies)
    for k in range(dies):
        if dies == 6:  # a body diode on its transistor's die
            loss = mean[2 * k] + mean[2 * k + 1]
        else:
            loss = mean[k]
        r = 0.0
        for i in range(rises.shape[1]):
            rises[k, i] *= decay[k, i]
        for i in range(rises.shape[1]):
            rises[k, i] += gain[k, i] * loss
        for i in range(rises.shape[1]):
            r += rises[k, i]
        rise[k] = r
    sink[2] = sink[0] * sink[2] + sink[1] * total
    t_sink = sink[2] + sink[3]
    sink[5] = t_sink
    for d in range(12):
        k = d // 2
        case = t_sink + sink[4] * (mean[2 * k] + mean[2 * k + 1])
        t = case + rise[int(die_of[d])]
        tj[d] = t
        lo, hi, w = bracket(line_t[d], t)
        lines[d, 0] = line_v0[d, lo] + w * (line_v0[d, hi] - line_v0[d, lo])
        lines[d, 1] = line_r[d, lo] + w * (line_r[d, hi] - line_r[d, lo])
        for j in range(2):
            if grid_info[d, j, 3] != 0.0:
                lo, hi, w = bracket(energy_t[d, j], t)
                grid_info[d, j, 1], grid_info[d, j, 4], grid_info[d, j, 5] = w, lo, hi


@cache
def _compiled(kernel: Callable[..., None]) -> Callable[..., None] | None:
    """``kernel`` compiled (None without numba)."""
    if kernel_unavailable() is not None:
        return None
    from numba import njit

    jit: Any = njit(cache=True)
    compiled: Callable[..., None] = jit(kernel)
    return compiled


def compiled_booking() -> Callable[..., None] | None:
    """:func:`book` compiled (None without numba)."""
    return _compiled(book)


def compiled_thermal() -> Callable[..., None] | None:
    """:func:`thermal` compiled (None without numba)."""
    return _compiled(thermal)
