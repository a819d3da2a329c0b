"""Losses and temperatures of a drive, booked where the plant integrates its segments
(docs/physics.md#losses-and-temperature).

The plant splits each period at every switching edge and dead-time end; each segment's leg
voltages are U_dc·S minus the conducting device's on-state voltage v0 + r·|i| against its
current (:mod:`.devices`: the transistor's, or the diode's, as dead time and the current's sign
decide). :class:`Ledger` books, from the phase currents at each segment's ends (taken as linear
between them):

- conduction: the energy the on-state voltage takes, per device — the same voltage the plant's
  equations contain, one model of a conducting device;
- the DC link's energy Σ S_x·U_dc·∫i_x, and the copper losses 1.5·R·∫|i|² (the machine's R at
  its temperature);
- switching: at every change of a leg's level, E_off of a transistor that carried the current
  forward, E_on of one that takes it forward plus E_rr of the other position's diode, at the
  commutated current, the DC link's voltage and the device's T_j;
- per period the iron losses (from the stator flux: not in the plant's equations), friction
  and the power into the load.

Where numba is installed (the ``[fast]`` extra) the periods of a thermal step are booked at
once, at its end, by a compiled kernel (:mod:`.losses_kernel`) that does the reference's
arithmetic in its order; the rows of the periods are then ready when the step ends, or whenever
they are asked for (:meth:`Ledger.flush`).

Every ``thermal_step`` the mean losses advance the thermal networks (:mod:`.thermal`): a
Foster network per die, a case-to-heatsink resistance per switch position, a heatsink node to
the coolant; the machine's winding and rotor nodes. The new T_j set the devices' on-state
voltages and switching energies, the new winding and rotor temperatures the plant's R_s, R_r
and ψ_f (the controller keeps its own nominal parameters).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from .devices import Device, EnergyTable, Grid, Part, bracket, grid_value
from .fields import check_fields, choice, flag, quantity
from .losses_kernel import (
    FIELDS,
    PERIOD_WIDTH,
    SEG_WIDTH,
    SEG_WIDTH_FULL,
    compiled_booking,
    compiled_thermal,
)
from .signals import DEVICES, LOSS_FIELDS
from .thermal import Cauer, Foster
from .trace import Trace

__all__ = ["Ledger", "LossParams", "Overheat", "overheats"]

#: √3/2 as core.inverter.inverse_clarke has it (the same expression: the same double)
_HALF_SQRT3 = 0.5 * math.sqrt(3.0)
_N = len(DEVICES)  #: 12: per leg the upper transistor and diode, the lower transistor and diode
_T_HI, _D_HI, _T_LO, _D_LO = range(4)  #: a device's place in its leg


@dataclass(frozen=True)
class LossParams:
    """``plant.losses``: what a drive loses and how hot it gets; everything off by default (the
    plant then runs as without this section, bit for bit)."""

    device: str = choice(
        "the inverter's devices: a file in config/devices (its name) or a path; their on-state "
        "voltages replace device_drop ('': no inverter losses)",
        default="",
    )
    machine: bool = flag(
        "the machine's losses and temperatures: iron losses, a winding and a rotor node, R_s, "
        "R_r and psi_f following them"
    )
    coolant: float = quantity(
        "coolant (or ambient) temperature; every node starts at it", "°C", ge=-40, le=150,
        default=40.0,
    )  # fmt: skip
    thermal_step: float = quantity(
        "the thermal networks advance and feed T_j back every this long (whole periods, at "
        "least one)", "s", ge=0, default=1e-3,
    )  # fmt: skip
    mounting_r_th: float = quantity(
        "case to heatsink of one switch position besides the device file's r_th_cs", "K/W",
        ge=0, default=0.0,
    )  # fmt: skip
    heatsink_r_th: float = quantity("heatsink to coolant, whole inverter", "K/W", gt=0, default=0.3)
    heatsink_tau: float = quantity("heatsink time constant", "s", gt=0, default=120.0)
    motor_temperature: float = quantity(
        "the temperature at which the motor parameters (and the controller's) hold", "°C",
        ge=-40, le=200, default=20.0,
    )  # fmt: skip
    winding_r_th: float = quantity("winding to coolant", "K/W", gt=0, default=0.3)
    winding_tau: float = quantity("winding time constant (its capacity × winding_r_th)", "s",
                                  gt=0, default=120.0)  # fmt: skip
    rotor_r_th: float = quantity("rotor to winding (across the air gap)", "K/W", gt=0, default=0.5)
    rotor_tau: float = quantity("rotor time constant (its capacity × rotor_r_th)", "s", gt=0,
                                default=600.0)  # fmt: skip
    iron_hysteresis: float = quantity(
        "iron losses per Hz of the flux's frequency at 1 Wb (P = (k_h f + k_e f²)·|psi_s|²)",
        "W/(Hz·Wb²)", ge=0, default=0.0,
    )  # fmt: skip
    iron_eddy: float = quantity(
        "iron losses per Hz² at 1 Wb (see iron_hysteresis)", "W/(Hz²·Wb²)", ge=0, default=0.0
    )
    cage_alpha: float = quantity(
        "temperature coefficient of an induction motor's rotor cage (R_r)", "1/K", ge=0, le=0.01,
        default=0.0039,
    )  # fmt: skip
    magnet_alpha: float = quantity(
        "temperature coefficient of a PMSM's magnet flux psi_f (NdFeB: -0.1 to -0.12 %/K)", "1/K",
        ge=-0.01, le=0, default=-0.0011,
    )  # fmt: skip

    def __post_init__(self) -> None:
        check_fields(self)

    @property
    def on(self) -> bool:
        """Any loss is booked (a device file, or the machine's)."""
        return bool(self.device) or self.machine


class Ledger:
    """The losses of one plant (see the module's docstring). The plant reads the on-state lines
    :attr:`v0` and :attr:`r` (per device, at its T_j; a constant ``drop`` without a device
    file) for its leg voltages, hands :meth:`close` each period's segments at its end (one
    call a period), and takes the periods' rows with :meth:`take` (:attr:`fields`, the last
    period's, after :meth:`flush`). ``compiled``: book with the kernel (None: where numba is
    installed; False: the per-period reference in Python)."""

    def __init__(
        self,
        params: LossParams,
        device: Device | None,
        *,
        ts: float,
        u_dc: float,
        drop: float,
        heat: Callable[[float, float], tuple[float, float]],
        rotor: tuple[int, int, float, float] | None = None,
        torque: Callable[[tuple[Any, ...]], float] | None = None,
        compiled: bool | None = None,
    ) -> None:
        """``heat(t_winding, t_rotor)``: sets the plant's parameters for these temperatures and
        returns its (R_s, R_r) (Ω). ``rotor``: a machine with rotor copper (an induction
        motor's), where its state holds ψ_s and i_s, and L_s, 1/L_m: the rotor current is
        (ψ_s - L_s i_s)/L_m. ``torque(x)``: where a load machine holds the speed, the torque of
        state x (the power into the load is T_e·ω_m)."""
        self.params = params
        self.device = device
        self.ts = ts
        self.u_dc = u_dc
        self._heat = heat
        self._rotor_of = rotor
        self._torque_of = torque
        self._iron = params.machine and bool(params.iron_hysteresis or params.iron_eddy)
        #: the thermal networks advance every this many periods
        self.every = max(1, round(params.thermal_step / ts)) if params.thermal_step else 1
        self._periods = 0
        #: per device: on-state v = v0 + r·|i| (V, Ω) at its T_j
        self.v0 = [drop] * _N
        self.r = [0.0] * _N
        self.reverse = device is not None and device.reverse_conducting
        self._e_cond = [0.0] * _N
        self._e_sw = [0.0] * _N
        self._acc = [0.0] * _N  #: each device's energy since the last thermal step
        self._acc_cu_s = self._acc_cu_r = 0.0
        # the segment open: its length (s), phase currents and current vectors at its start,
        # per leg its level, device and on-state voltage against the current
        #: the levels and devices of the legs at the end of the last period
        self._last: tuple[list[bool], list[int]] = ([False] * 3, [_D_LO, _D_LO + 4, _D_LO + 8])
        self._psi: complex | None = None
        t0 = params.coolant
        self._tj = [math.nan] * _N
        self._t_sink = math.nan
        self._t_machine = (math.nan, math.nan)
        self.r_s, self.r_r = (
            heat(t0, t0)
            if params.machine
            else heat(params.motor_temperature, params.motor_temperature)
        )
        self._foster: Foster | None = None
        self._sink: Cauer | None = None
        self._machine: Cauer | None = None
        self._tables: list[tuple[Grid | None, Grid | None]] = []
        step = self.every * ts
        self._shared = device is not None and device.shared_die
        #: the die of each device (a body diode's is its transistor's)
        self._die = [d // 2 if self._shared else d for d in range(_N)]
        if device is not None:
            dies = 6 if device.shared_die else _N
            parts = [device.switch, device.diode] * 2
            self._parts: list[Part] = [parts[d % 4] for d in range(_N)]
            #: per device: its switching energies (a transistor's E_on, E_off; a diode's E_rr
            #: twice) and their scales to the DC link, (U_dc/V_ref)^K_v
            self._energy_tables = [
                _scaled(p, ("e_on", "e_off") if d % 2 == 0 else ("e_rr", "e_rr"), u_dc)
                for d, p in enumerate(self._parts)
            ]
            r = [self._die_part(d).r_th for d in range(dies)]
            tau = [self._die_part(d).tau for d in range(dies)]
            self._foster = Foster(r, tau, step)
            self._sink = Cauer(
                [params.heatsink_tau / params.heatsink_r_th],
                [(0, None, params.heatsink_r_th)],
                coolant=t0,
                step=step,
            )
            self._r_cs = device.r_th_cs + params.mounting_r_th
            self._set_junctions([t0] * _N)
            self._t_sink = t0
        if params.machine:
            p = params
            self._machine = Cauer(
                [p.winding_tau / p.winding_r_th, p.rotor_tau / p.rotor_r_th],
                [(0, None, p.winding_r_th), (1, 0, p.rotor_r_th)],
                coolant=t0,
                step=step,
            )
            self._t_machine = (t0, t0)
        self._temperatures = (*self._tj, self._t_sink, *self._t_machine)
        #: the losses' fields after k and t (:data:`~.signals.LOSS_FIELDS`) of the last period
        self.fields: tuple[float, ...] = ((0.0,) * (9 + _N)) + self._temperatures
        #: the periods' rows not taken yet (fields tuples, or arrays of them), from step 0
        self._rows: list[Any] = [self.fields]
        self._book = None if compiled is False else compiled_booking()
        if compiled and self._book is None:
            raise RuntimeError("the compiled booking needs numba (predictive_drive[fast])")
        if self._book is not None:
            self._start_batches()

    # -- the compiled booking ----------------------------------------------------------------
    def _start_batches(self) -> None:
        """The kernel's inputs: the periods since the last booking, each segment's and each
        period's numbers (:mod:`.losses_kernel`); the state it carries from one to the next;
        the rows it books, kept until taken (the first: step 0's)."""
        self._buf = np.empty((1024, len(LOSS_FIELDS)))
        self._buf[0] = self._rows.pop()
        self._filled = 1
        self._segs: list[float] = []
        self._per: list[float] = []
        #: where the plant puts each segment's numbers (see :mod:`.losses_kernel`)
        self.capture = self._segs.extend
        #: the plant's state the periods kept end at, as a segment's numbers (set by the plant)
        self.tail: Callable[[], tuple[float, ...]] = lambda: (0.0,) * SEG_WIDTH_FULL
        held = self._torque_of is not None
        rotor = self._rotor_of
        self._params = np.array([
            self.ts, self.u_dc, self.r_s, self.r_r,
            rotor[2] if rotor else 0.0, rotor[3] if rotor else 0.0, float(held),
            self.params.iron_hysteresis if self._iron else 0.0,
            self.params.iron_eddy if self._iron else 0.0, float(bool(self._tables)), _HALF_SQRT3,
        ])  # fmt: skip
        self._state = np.array([0.0, 0.0, 0.0, _D_LO, _D_LO + 4, _D_LO + 8])  # levels, devices
        self._psi_prev = np.zeros(3)  #: the stator flux at the last period's end, and if any
        self._acc_k = np.zeros(_N + 2)  #: _acc and the machine's heat, as the kernel adds them
        self._lines = np.array((self.v0, self.r), dtype=float).T.copy()  #: v0, r a device
        self._grids()
        self._thermal = compiled_thermal() if self._foster is not None else None
        if self._thermal is not None:
            assert self._sink is not None
            (phi,), (gamma,) = self._sink._phi, self._sink._gamma
            #: the heatsink node: Φ, Γ, its rise, the coolant, case to heatsink, its temperature
            self._sink_k = np.array([phi[0], gamma[0], 0.0, self._sink.coolant, self._r_cs, 0.0])
            self._die_of = np.array(self._die, dtype=float)
            self._tj_k = np.zeros(_N)
            width = max(len(p.lines) for p in self._parts)
            self._line_t, self._line_v0, self._line_r = (
                np.full((_N, width), np.nan) for _ in "tvr"
            )
            for d, part in enumerate(self._parts):
                for i, line in enumerate(part.lines):
                    self._line_t[d, i], self._line_v0[d, i], self._line_r[d, i] = (
                        line.t_j, line.v0, line.r,
                    )  # fmt: skip
            temps = self._grid.shape[2]
            self._energy_t = np.full((_N, 2, temps), np.nan)
            for d, (on, off, _, _) in enumerate(self._energy_tables):
                for j, table in enumerate((on, off)):
                    if table is not None:
                        self._energy_t[d, j, : len(table.t_j)] = table.t_j

    def _grids(self) -> None:
        """The switching energies as the kernel reads them: every curve of every device once
        (``_grid[d, j, n]``: device d's energy j at its n-th temperature), and at each thermal
        step where each device's T_j falls between them (``_grid_info``, see
        :func:`~.losses_kernel.book`)."""
        tables = [(on, off) for on, off, _, _ in getattr(self, "_energy_tables", [])]
        present = [t for pair in tables for t in pair if t is not None]
        temps = max((len(t.t_j) for t in present), default=1)
        size = max((len(t.values[0]) for t in present), default=2)
        self._grid = np.zeros((_N, 2, temps, size))
        self._grid_info = np.zeros((_N, 2, 6))
        for d, pair in enumerate(tables):
            for j, t in enumerate(pair):
                if t is not None:
                    self._grid[d, j, : len(t.t_j)] = t.values
        # where each device's T_j falls between its curves (the thermal kernel moves it on)
        for d, (on, off, scale_on, scale_off) in enumerate(getattr(self, "_energy_tables", [])):
            for j, (table, scale) in enumerate(((on, scale_on), (off, scale_off))):
                if table is not None:
                    lo, hi, w = bracket(table.t_j, self._tj[d])
                    self._grid_info[d, j] = (1.0 / table.step, w, scale, 1.0, lo, hi)

    @property
    def wants_flux(self) -> bool:
        """The stator flux at each period's end is booked (the iron losses)."""
        return self._iron

    @property
    def batched(self) -> bool:
        """The kernel books the periods: the plant hands each segment to :attr:`capture` and
        each period to :meth:`end_period` (else its trail to :meth:`close`)."""
        return self._book is not None

    def end_period(
        self, segments: int, omega: tuple[float, float], turned: float, load: float,
        friction: float, psi: complex,
    ) -> None:  # fmt: skip
        """A period of ``segments`` segments (each given to :attr:`capture`) ends: the speed at
        its start and end, the shaft's angle over it, the load torque, the viscous coefficient,
        the stator flux at its end (see :meth:`close`)."""
        w0, w1 = omega
        self._per.extend((segments, w0, w1, turned, load, friction, psi.real, psi.imag))
        self._periods += 1
        if self._periods == self.every:
            self._book_batch(advance=True)

    def _book_batch(self, *, advance: bool = False) -> None:
        """Book the periods kept (then, with ``advance``, one thermal step)."""
        if not self._per:
            return
        per = np.fromiter(self._per, float, len(self._per)).reshape(-1, PERIOD_WIDTH)
        width = SEG_WIDTH if self._rotor_of is None and self._torque_of is None else SEG_WIDTH_FULL
        segs = np.fromiter(self._segs, float, len(self._segs)).reshape(-1, width)
        tail = np.fromiter(self.tail(), float, width)
        del self._segs[:], self._per[:]  # in place: the plant holds capture
        n, at = len(per), self._filled
        if at + n > len(self._buf):  # the rows' room, grown as a run is long between takes
            self._buf = np.concatenate([self._buf[:at], np.empty((at + n + 512, len(LOSS_FIELDS)))])
        rows = self._buf[at : at + n]  # the kernel fills the powers
        self._params[2], self._params[3] = self.r_s, self.r_r
        assert self._book is not None
        self._book(
            segs, per, tail, self._grid, self._grid_info, self._lines, self._state,
            self._psi_prev, self._params, rows, self._acc_k,
        )  # fmt: skip
        rows[:, FIELDS:] = self._temperatures
        if advance:
            self._advance_batched()
            rows[-1, FIELDS:] = self._temperatures
        self._filled = at + n

    def _advance_batched(self) -> None:
        """:meth:`_advance` of the sums the kernel made: the devices' networks, lines and
        energies by the thermal kernel, the machine's as the reference does."""
        acc = self._acc_k
        if self._thermal is None:  # no device: the machine's only
            self._acc = acc[:_N].tolist()
            self._acc_cu_s, self._acc_cu_r = float(acc[_N]), float(acc[_N + 1])
            self._advance()
        else:
            n = float(self._periods)
            assert self._foster is not None and self._sink is not None
            self._thermal(
                acc, n, self._foster.decay, self._foster.gain, self._foster.rises, self._die_of,
                self._sink_k, self._line_t, self._line_v0, self._line_r, self._energy_t,
                self._grid_info, self._lines, self._tj_k,
            )  # fmt: skip
            self._tj = self._tj_k.tolist()
            self.v0[:] = self._lines[:, 0].tolist()
            self.r[:] = self._lines[:, 1].tolist()
            self._t_sink = float(self._sink_k[5])
            self._sink._rises = [float(self._sink_k[2])]
            if self._machine is not None:
                t = self._machine.advance([float(acc[_N]) / n, float(acc[_N + 1]) / n])
                self._t_machine = (t[0], t[1])
                self.r_s, self.r_r = self._heat(*self._t_machine)
            self._temperatures = (*self._tj, self._t_sink, *self._t_machine)
            self._periods = 0
        acc[:] = 0.0

    def flush(self) -> None:
        """Book the periods kept so far (the thermal networks advance at their steps only), so
        that :attr:`fields` and :meth:`take` hold every period closed."""
        if self._book is not None:
            self._book_batch()
            if self._filled:
                self.fields = tuple(self._buf[self._filled - 1].tolist())

    def take(self) -> np.ndarray:
        """The rows (:data:`~.signals.LOSS_FIELDS`) of the periods closed since the last take,
        one a step from step 0 (its zeros and the starting temperatures)."""
        self.flush()
        if self._book is None:  # the reference's rows: a tuple a period
            rows, self._rows = self._rows, []
            return np.array(rows, dtype=float).reshape(-1, len(LOSS_FIELDS))
        out = self._buf[: self._filled].copy()
        self._filled = 0
        return out

    def _die_part(self, die: int) -> Part:
        """The part whose Foster network die ``die`` has: with a shared die, die n is the
        transistor of switch position n (a leg's upper, then lower)."""
        assert self.device is not None
        if self.device.shared_die:
            return self.device.switch
        return self._parts[die]

    def _set_junctions(self, tj: list[float]) -> None:
        """Each device's on-state line and switching energies at its new junction temperature."""
        tables = []
        v0, r = self.v0, self.r
        for d, (part, (on, off, scale_on, scale_off), t) in enumerate(
            zip(self._parts, self._energy_tables, tj)
        ):
            v0[d], r[d] = part.line(t)
            tables.append((
                None if on is None else on.at_temperature(t, scale_on),
                None if off is None else off.at_temperature(t, scale_off),
            ))  # fmt: skip
        self._tables = tables
        self._tj = tj

    # -- per period ---------------------------------------------------------------------------
    def close(
        self,
        trail: list[tuple[Any, ...]],
        x: tuple[Any, ...],
        i_s: complex,
        currents: tuple[float, float, float],
        psi: complex,
        omega: tuple[float, float],
        turned: float,
        load: float,
        friction: float,
    ) -> None:
        """The period's segments in order, each ``(h, x, i_s, currents, highs, devs, drops)``:
        its length (s), the state, stator current (αβ) and phase currents at its start and, per
        leg, its level, conducting device and on-state voltage against the current (V); then the
        state, currents and stator flux ψ_s (αβ) at the period's end, ``omega`` the speed at its
        start and end, ``turned`` the shaft's angle over it, ``load`` the load torque,
        ``friction`` the viscous coefficient in the equations. Books each segment (its currents
        linear between its ends) and each leg's change of level, the period's powers, every
        :attr:`every` periods the temperatures; sets :attr:`fields`."""
        e = self._e_cond
        tables = self._tables
        rotor, torque = self._rotor_of, self._torque_of
        old, dev = self._last
        e_dc = e_cu = e_cur = e_te = 0.0
        ends = [(seg[1], seg[2], seg[3]) for seg in trail[1:]]
        ends.append((x, i_s, currents))
        for (h, _, sa, a, highs, devs, drops), (_, sb, b) in zip(trail, ends):
            if highs != old and tables:
                for leg in (0, 1, 2):
                    if highs[leg] != old[leg]:
                        self._commutate(leg, dev[leg] & 3, devs[leg] & 3, a[leg])
            hh = 0.5 * h
            a0, a1, a2 = a
            b0, b1, b2 = b
            q0, q1, q2 = hh * (a0 + b0), hh * (a1 + b1), hh * (a2 + b2)  # ∫i, linear
            d0, d1, d2 = devs
            v0, v1, v2 = drops
            e[d0] += v0 * q0
            e[d1] += v1 * q1
            e[d2] += v2 * q2
            g0, g1, g2 = highs
            e_dc += g0 * q0 + g1 * q1 + g2 * q2
            # ∫|i|² = h(a² + ab + b²)/3 for a current linear from a to b (× 1.5 R below)
            ar, ai, br, bi = sa.real, sa.imag, sb.real, sb.imag
            e_cu += h * (ar * (ar + br) + ai * (ai + bi) + br * br + bi * bi)
            old, dev = highs, devs
        if rotor is not None:  # an induction motor's rotor current (ψ_s - L_s i_s)/L_m
            k_psi, k_i, l_s, inv_l_m = rotor
            r1 = (trail[0][1][k_psi] - l_s * trail[0][1][k_i]) * inv_l_m if trail else 0j
            for (h, *_), (xb, _, _) in zip(trail, ends):
                r0, r1 = r1, (xb[k_psi] - l_s * xb[k_i]) * inv_l_m
                ar, ai, br, bi = r0.real, r0.imag, r1.real, r1.imag
                e_cur += h * (ar * (ar + br) + ai * (ai + bi) + br * br + bi * bi)
        if torque is not None:  # the torque a load machine holding the speed takes
            t1 = torque(trail[0][1]) if trail else 0.0
            for (h, *_), (xb, _, _) in zip(trail, ends):
                t0, t1 = t1, torque(xb)
                e_te += 0.5 * h * (t0 + t1)
        self._last = (old, dev)
        inv = 1.0 / self.ts
        w0, w1 = omega
        p_fe = 0.0
        before, self._psi = self._psi, psi
        if self._iron and before is not None:
            p = self.params
            cross = before.real * psi.imag - before.imag * psi.real
            dot = before.real * psi.real + before.imag * psi.imag
            f = abs(math.atan2(cross, dot)) * inv / (2.0 * math.pi)  # the flux's frequency
            m = abs(before) + abs(psi)  # squared as m·m: the kernel's (C's pow(m, 2) may differ)
            p_fe = (p.iron_hysteresis * f + p.iron_eddy * f * f) * (m * m) / 4
        cu_s = 0.5 * self.r_s * e_cu * inv
        cu_r = 0.5 * self.r_r * e_cur * inv
        e_cond, e_sw = e, self._e_sw
        per_device = [(c + w) * inv for c, w in zip(e_cond, e_sw)]
        self._acc = [a + b for a, b in zip(self._acc, per_device)]
        self._acc_cu_s += cu_s + p_fe
        self._acc_cu_r += cu_r
        self._e_cond = [0.0] * _N
        self._e_sw = [0.0] * _N
        self._periods += 1
        if self._periods == self.every:
            self._advance()
        self.fields = (
            self.u_dc * e_dc * inv,
            e_te * inv * w1 if self._torque_of is not None else load * turned * inv,
            cu_s + cu_r,
            p_fe,
            friction * (w0 * w0 + w0 * w1 + w1 * w1) / 3.0,
            (e_cond[0] + e_cond[2] + e_cond[4] + e_cond[6] + e_cond[8] + e_cond[10]) * inv,
            (e_cond[1] + e_cond[3] + e_cond[5] + e_cond[7] + e_cond[9] + e_cond[11]) * inv,
            (e_sw[0] + e_sw[2] + e_sw[4] + e_sw[6] + e_sw[8] + e_sw[10]) * inv,
            (e_sw[1] + e_sw[3] + e_sw[5] + e_sw[7] + e_sw[9] + e_sw[11]) * inv,
            *per_device,
            *self._temperatures,
        )
        self._rows.append(self.fields)

    def _commutate(self, leg: int, old: int, new: int, current: float) -> None:
        """Leg ``leg`` changes level with ``current`` flowing out of it: E_off of a transistor
        that carried it forward, E_on of one taking it forward and E_rr of the other position's
        diode."""
        base = 4 * leg
        sw, tables = self._e_sw, self._tables
        if (old == _T_HI and current > 0.0) or (old == _T_LO and current < 0.0):
            sw[base + old] += grid_value(tables[base + old][1], current)
        if (new == _T_HI and current > 0.0) or (new == _T_LO and current < 0.0):
            sw[base + new] += grid_value(tables[base + new][0], current)
            diode = base + (_D_LO if new == _T_HI else _D_HI)
            sw[diode] += grid_value(tables[diode][0], current)

    def _advance(self) -> None:
        """One thermal step with the mean losses since the last one."""
        n = float(self._periods)
        mean = [a / n for a in self._acc]
        if self._foster is not None and self._sink is not None:
            if self._shared:
                die = np.add(mean[0::2], mean[1::2])
            else:
                die = np.array(mean)
            rises = self._foster.advance(die).tolist()
            sink = self._sink.advance([sum(mean)])[0]
            cases = [sink + self._r_cs * (mean[2 * k] + mean[2 * k + 1]) for k in range(6)]
            self._t_sink = sink
            self._set_junctions([cases[d // 2] + rises[self._die[d]] for d in range(_N)])
        if self._machine is not None:
            t = self._machine.advance([self._acc_cu_s / n, self._acc_cu_r / n])
            self._t_machine = (t[0], t[1])
            self.r_s, self.r_r = self._heat(*self._t_machine)
        self._temperatures = (*self._tj, self._t_sink, *self._t_machine)
        self._acc = [0.0] * _N
        self._acc_cu_s = self._acc_cu_r = 0.0
        self._periods = 0


@dataclass(frozen=True)
class Overheat:
    """A device whose junction went above its rated temperature: from ``t_first`` (s) on, up to
    ``tj_max`` (°C, at ``t_max`` s), rated ``rated`` (°C, the datasheet's T_j max)."""

    device: str
    rated: float
    t_first: float
    tj_max: float
    t_max: float


def overheats(trace: Trace, device: Device | None) -> list[Overheat]:
    """The devices of a run whose junction temperature exceeded the device file's rating, in
    the order they first did (none without losses or a device)."""
    if device is None or not trace.has_losses:
        return []
    out = []
    for name in DEVICES:
        tj = trace.col("losses", f"tj_{name}")
        rated = device.rated_tj(name)
        over = np.flatnonzero(tj > rated)
        if len(over):
            k = int(np.nanargmax(tj))
            out.append(Overheat(name, rated, int(over[0]) * trace.ts, float(tj[k]), k * trace.ts))
    return sorted(out, key=lambda o: o.t_first)


def _scaled(
    part: Part, names: tuple[str, str], u_dc: float
) -> tuple[EnergyTable | None, EnergyTable | None, float, float]:
    """The two energy tables ``names`` of ``part`` and their scales to ``u_dc``."""
    a, b = (part.energies.get(n) for n in names)
    k = part.voltage_exponent
    return (
        a, b,
        1.0 if a is None else (u_dc / a.v_ref) ** k,
        1.0 if b is None else (u_dc / b.v_ref) ** k,
    )  # fmt: skip
