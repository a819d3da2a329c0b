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

from .devices import Device, EnergyTable, Grid, Part, grid_value
from .fields import check_fields, choice, flag, quantity
from .signals import DEVICES, LOSS_FIELDS
from .thermal import Cauer, Foster
from .trace import Trace

__all__ = ["LOSS_NAN", "Ledger", "LossParams", "Overheat", "overheats"]

#: the state's loss fields of a plant without losses
LOSS_NAN: tuple[float, ...] = (math.nan,) * len(LOSS_FIELDS)
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
    file) for its leg voltages, calls :meth:`book` at every segment's start and :meth:`close`
    at every period's end, and publishes :attr:`fields`."""

    def __init__(
        self,
        params: LossParams,
        device: Device | None,
        *,
        ts: float,
        u_dc: float,
        drop: float,
        heat: Callable[[float, float], tuple[float, float]],
        rotor: bool,
        held: bool,
    ) -> None:
        """``heat(t_winding, t_rotor)``: sets the plant's parameters for these temperatures and
        returns its (R_s, R_r) (Ω; R_r 0 for a machine without rotor copper: ``rotor``). ``held``:
        a load machine holds the speed (the power into it is T_e·ω_m)."""
        self.params = params
        self.device = device
        self.ts = ts
        self.u_dc = u_dc
        self._heat = heat
        self._rotor = rotor
        self._held = held
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
        self._e_dc = self._e_cu = self._e_cur = self._e_te = 0.0
        self._acc_cu_s = self._acc_cu_r = 0.0
        # the segment open: its length (s), phase currents and current vectors at its start,
        # per leg its level, device and on-state voltage against the current
        self._open: tuple[Any, ...] = (
            0.0, (0.0, 0.0, 0.0), 0j, 0j, 0.0, [False] * 3, [_D_LO, _D_LO + 4, _D_LO + 8],
            [0.0] * 3,
        )  # fmt: skip
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
        #: the state's loss fields (:data:`~.signals.LOSS_FIELDS`) of the last period
        self.fields: tuple[float, ...] = ((0.0,) * (9 + _N)) + self._temperatures

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

    # -- per segment --------------------------------------------------------------------------
    def book(
        self,
        h: float,
        currents: tuple[float, float, float],
        i_s: complex,
        i_r: complex,
        te: float,
        highs: list[bool],
        devs: list[int],
        drops: list[float],
    ) -> None:
        """A segment of ``h`` s starts with these phase currents (A), stator and rotor current
        vectors (αβ, A), torque (N·m; used where the load machine holds the speed) and, per leg,
        its level, conducting device and on-state voltage against the current (V): the segment
        before it is booked, and each leg whose level changes commutates."""
        hp, a, s0, q0, te0, old, dev, drop = self._open
        if hp:
            hh = 0.5 * hp
            b0, b1, b2 = currents
            q_0, q_1, q_2 = hh * (a[0] + b0), hh * (a[1] + b1), hh * (a[2] + b2)  # ∫i, linear
            e = self._e_cond
            e[dev[0]] += drop[0] * q_0
            e[dev[1]] += drop[1] * q_1
            e[dev[2]] += drop[2] * q_2
            # ∫|i|² = h(a² + ab + b²)/3 for a current linear from a to b (× 1.5 R at the close)
            ar, ai, br, bi = s0.real, s0.imag, i_s.real, i_s.imag
            cu = hp * (ar * (ar + br) + ai * (ai + bi) + br * br + bi * bi)
            if self._rotor:
                ar, ai, br, bi = q0.real, q0.imag, i_r.real, i_r.imag
                self._e_cur += hp * (ar * (ar + br) + ai * (ai + bi) + br * br + bi * bi)
            self._e_cu += cu
            self._e_dc += old[0] * q_0 + old[1] * q_1 + old[2] * q_2
            self._e_te += hh * (te0 + te)
        if highs != old and self._tables:
            for leg in (0, 1, 2):
                if highs[leg] != old[leg]:
                    self._commutate(leg, dev[leg] & 3, devs[leg] & 3, currents[leg])
        self._open = (h, currents, i_s, i_r, te, highs, devs, drops)

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

    # -- per period ---------------------------------------------------------------------------
    def close(
        self,
        currents: tuple[float, float, float],
        i_s: complex,
        i_r: complex,
        te: float,
        psi: complex,
        omega: tuple[float, float],
        turned: float,
        load: float,
        friction: float,
    ) -> None:
        """The period ends with these currents, torque and stator flux ψ_s (αβ); ``omega``: the
        speed at its start and end, ``turned`` the shaft's angle over it, ``load`` the load
        torque, ``friction`` the viscous coefficient in the equations. Its powers, every
        :attr:`every` periods the temperatures, and :attr:`fields`."""
        _, _, _, _, _, highs, devs, drops = self._open
        self.book(0.0, currents, i_s, i_r, te, highs, devs, drops)
        inv = 1.0 / self.ts
        w0, w1 = omega
        p_fe = 0.0
        last, self._psi = self._psi, psi
        if self._iron and last is not None:
            p = self.params
            cross = last.real * psi.imag - last.imag * psi.real
            dot = last.real * psi.real + last.imag * psi.imag
            f = abs(math.atan2(cross, dot)) * inv / (2.0 * math.pi)  # the flux's frequency
            p_fe = (p.iron_hysteresis * f + p.iron_eddy * f * f) * (abs(last) + abs(psi)) ** 2 / 4
        cu_s = 0.5 * self.r_s * self._e_cu * inv
        cu_r = 0.5 * self.r_r * self._e_cur * inv
        e_cond, e_sw = self._e_cond, self._e_sw
        per_device = [(c + w) * inv for c, w in zip(e_cond, e_sw)]
        e_dc, e_te = self._e_dc, self._e_te
        self._acc = [a + b for a, b in zip(self._acc, per_device)]
        self._acc_cu_s += cu_s + p_fe
        self._acc_cu_r += cu_r
        self._e_cond = [0.0] * _N
        self._e_sw = [0.0] * _N
        self._e_dc = self._e_cu = self._e_cur = self._e_te = 0.0
        self._periods += 1
        if self._periods == self.every:
            self._advance()
        self.fields = (
            self.u_dc * e_dc * inv,
            e_te * inv * w1 if self._held else load * turned * inv,
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
    if device is None:
        return []
    out = []
    for name in DEVICES:
        tj = trace.col("state", f"tj_{name}")
        rated = (device.switch if name.startswith("t") else device.diode).t_j_max
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
