"""Paper 000: model predictive torque control of the induction motor — MPTC, MPTC-DB, DB-MPTC
(docs/physics.md#mptc-of-the-induction-motor), the controller family ``mptc_im``.

The controller owns what every strategy shares — the stator-flux estimate
(docs/physics.md#what-the-controller-sees), the soft start, the zero-vector choice and the command
format — and asks its strategy for (vector, duty) each step. Strategies are plain objects with
``decide(prediction, torque_ref, flux_ref) -> Decision``; :data:`IM_STRATEGIES` lists them in
registry order.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..devices import Device
from ..fields import check_fields, choice, quantity
from ..machines import Machine
from ..machines.induction import InductionCoefficients, InductionMotor
from ..signals import Reference, State, new_record
from .base import (
    AFTER,
    AFTER_TABLE,
    NO_EFFORT,
    NO_EFFORT_TABLE,
    NODE_BUDGET,
    Decision,
    SwitchingEffort,
    VectorController,
    budget_field,
    check_horizon,
    compiled,
    delay_compensation,
    horizon_field,
    lambda_sw_field,
    rows,
    search_field,
)
from .energy import (
    SwitchingEnergy,
    check_energy,
    device_field,
    device_tj_field,
    lambda_e_field,
    switching_energy,
)
from .kernels import IM_STAGE, BranchAndBound, compiled_branch_and_bound
from .search import Expand, SearchResult, branch_and_bound

__all__ = [
    "A0_FORMS",
    "DBMPTC",
    "IM_STRATEGIES",
    "MPTC",
    "MPTCDB",
    "IMPrediction",
    "InductionController",
    "InductionControllerParams",
]

INF = math.inf
NAN = math.nan
TWO_PI = 2.0 * math.pi

#: how a_0 of the torque derivative is formed: ``derived`` (correct, default) or ``paper_printed``
#: (paper 000 eq 10 as printed, wrong sign on the ω_r·Re(conj(ψ_s)·i_s) term; for reproduction only)
A0_FORMS = ("derived", "paper_printed")


class IMPrediction:
    """One step's forward-Euler prediction of the IM (docs/physics.md#induction-motor) from the
    controller's view.

    Precomputes everything that does not depend on the candidate vector, so each candidate costs a
    few complex operations: i(k+1) = i_free + Ts/(σL_s)·u, ψ(k+1) = ψ_free + Ts·u.
    """

    __slots__ = (
        "c",
        "ts",
        "lam",
        "a0_printed",
        "i",
        "psi",
        "te",
        "a0",
        "i_free",
        "psi_free",
        "gain_i",
        "volts",
        "active",
        "_z",
        "effort",
        "energy",
        "code",
        "sw",
        "sw_zero",
        "horizon",
        "budget",
        "compiled",
        "volt_rows",
        "effort_table",
        "wr",
    )

    def __init__(
        self,
        c: InductionCoefficients,
        ts: float,
        lam: float,
        a0_printed: bool,
        effort: SwitchingEffort | None = None,
        energy: SwitchingEnergy | None = None,
    ) -> None:
        self.c = c
        self.ts = ts
        self.lam = lam
        self.a0_printed = a0_printed
        self.volts: tuple[complex, ...] = ()
        #: the switching effort (None: λ_sw = 0) and, per candidate, its cost from the state in
        #: force (``code``): ``sw`` for the whole period, ``sw_zero`` then the zero vector
        self.effort = effort
        #: the loss-aware cost (None: λ_e = 0): each candidate's predicted switching energy,
        #: added to ``sw`` and ``sw_zero`` by :meth:`switching` at the current ``i``
        self.energy = energy
        self.i = 0j
        self.horizon = 1  #: N: periods mptc's cost sums over (docs/physics.md#long-horizons)
        self.budget = 0  #: stage costs a search may evaluate (0: no limit)
        #: the compiled branch and bound (None: search.branch_and_bound), with V0..V6 and the
        #: switching effort's costs as it takes them
        self.compiled: BranchAndBound | None = None
        self.volt_rows = np.zeros((7, 2))
        self.effort_table = NO_EFFORT_TABLE if effort is None else np.array(effort.full)
        self.code = 0
        self.sw: tuple[float, ...] = NO_EFFORT
        self.sw_zero: tuple[float, ...] = NO_EFFORT
        self.switching((0, 0, 0))

    def switching(self, switches: tuple[int, int, int]) -> None:
        """The switching state in force (the one the candidates' commutations count from); with
        the loss-aware cost, after :meth:`prepare` (the commutations carry its current)."""
        e = self.effort
        if e is None and self.energy is None:
            self.code = 0
            self.sw = self.sw_zero = NO_EFFORT
            return
        self.code = code = SwitchingEffort.code(switches)
        if e is not None:
            self.sw, self.sw_zero = e.full[code], e.then_zero[code]
        else:
            self.sw = self.sw_zero = NO_EFFORT
        if self.energy is not None:
            spent = self.energy.full(code, self.i)
            self.sw = tuple(a + b for a, b in zip(self.sw, spent))
            self.sw_zero = tuple(a + b for a, b in zip(self.sw_zero, spent))

    def current_at(self, u: complex, t_u: float) -> complex:
        """The current (A, αβ) predicted ``t_u`` s into the period under ``u`` (V): the
        forward-Euler step's straight line, where a vector applied for part of the period
        returns to the zero vector."""
        return self.i + (t_u / self.ts) * (self.i_free - self.i + self.gain_i * u)

    def prepare(self, i: complex, psi: complex, omega_m: float, volts: tuple[complex, ...]) -> None:
        a_ii, b_ip, cw, rs, p, tk, _, _ = self.c
        ts = self.ts
        wr = p * omega_m
        self.wr = wr
        self.i = i
        self.psi = psi
        if volts is not self.volts:
            self.volts = volts
            self.volt_rows = rows(volts)
            #: (n, V_n, Re V_n, Im V_n) of the active vectors
            self.active = tuple((n, v, v.real, v.imag) for n, v in enumerate(volts) if n)
        pr, pi, ir, ii = psi.real, psi.imag, i.real, i.imag
        cross = pr * ii - pi * ir  # Im(conj(ψ) i)
        dot = pr * ir + pi * ii  # Re(conj(ψ) i)
        self.te = tk * cross
        re_sign = -1.0 if self.a0_printed else 1.0
        self.a0 = tk * (a_ii * cross + re_sign * wr * dot - wr * (pr * pr + pi * pi) * cw)
        self.i_free = i + ts * (complex(a_ii, wr) * i + complex(b_ip, -wr * cw) * psi)
        self.psi_free = psi - ts * rs * i
        self.gain_i = ts * cw
        self._z = i - cw * psi

    def root(self) -> tuple[complex, complex, int]:
        """The search's root (:func:`horizon_stages`): the state the law decides from."""
        return self.i, self.psi, self.code

    def a_u(self, u: complex) -> float:
        """Voltage-dependent part of dT_e/dt, N·m/s per applied vector u (paper 000 eq 10)."""
        z = self._z
        return self.c.torque_k * (u.real * z.imag - u.imag * z.real)

    def deadbeat_time(self, u: complex, torque_ref: float) -> float:
        """t_u = (T* - T_e(k) - Ts·a_0)/a_u, s (paper 000 eq 13); ±inf when a_u = 0."""
        num = torque_ref - self.te - self.ts * self.a0
        au = self.a_u(u)
        if au == 0.0:
            return math.copysign(INF, num) if num else INF
        return num / au


class MPTC:
    """Conventional FCS-MPTC: 7 vectors, g = |T* - T(k+1)| + λ·|ψ* - |ψ(k+1)||, argmin for Ts.
    Over a horizon of N > 1 periods the stage costs of a sequence of vectors are summed and the
    first vector of the best sequence is applied, found by branch and bound (:mod:`.search`),
    the last optimum shifted as its first bound (``plan``)."""

    name = "mptc"

    def __init__(self) -> None:
        self.plan: tuple[int, ...] = ()
        self.found = SearchResult((), INF, 0)  #: the last search's result

    def decide(self, m: IMPrediction, torque_ref: float, flux_ref: float) -> Decision:
        if m.horizon == 1:
            return _FULL_PERIOD[_argmin_full_period(m, torque_ref, flux_ref)]
        guess = (*self.plan[1:], self.plan[-1]) if self.plan else ()
        if m.compiled is not None:
            i, psi, code = m.root()
            found = m.compiled(
                IM_STAGE, np.array(stage_constants(m, torque_ref, flux_ref)),
                np.array((i.real, i.imag, psi.real, psi.imag)), code, m.volt_rows,
                m.effort_table, AFTER_TABLE, m.volt_rows, m.horizon, guess, m.budget,
            )  # fmt: skip
        else:
            stages = horizon_stages(m, torque_ref, flux_ref)
            found = branch_and_bound(stages, m.root(), m.horizon, guess, m.budget)
        self.plan, self.found = found.sequence, found
        suboptimal = 0.0 if found.complete else 1.0
        return new_record(Decision, (found.sequence[0], 1.0, NAN, found.nodes, suboptimal))


class MPTCDB:
    """MPTC, then a deadbeat duty for the chosen vector (paper 000 §2, eq 9-14). With a switching
    effort, each candidate's cost counts the commutations of the duty it would be given."""

    name = "mptc_db"

    def decide(self, m: IMPrediction, torque_ref: float, flux_ref: float) -> Decision:
        if m.effort is None and m.energy is None:
            n = _argmin_full_period(m, torque_ref, flux_ref)
            if n == 0:
                return _FULL_PERIOD[0]
            t_u = m.deadbeat_time(m.volts[n], torque_ref)
        else:
            n, t_u = _argmin_with_duty(m, torque_ref, flux_ref)
            if n == 0:
                return _FULL_PERIOD[0]
        return new_record(Decision, (n, min(max(t_u / m.ts, 0.0), 1.0), t_u, 7, NAN))


class DBMPTC:
    """Deadbeat time per vector first, then MPTC on the scaled vectors (paper 000 §3, eq 15-16)."""

    name = "db_mptc"

    def decide(self, m: IMPrediction, torque_ref: float, flux_ref: float) -> Decision:
        ts = m.ts
        lam = m.lam
        te = m.te
        a0ts = ts * m.a0
        psi_free = m.psi_free
        num = torque_ref - te - a0ts
        tk = m.c.torque_k
        z = m._z
        zr, zi = z.real, z.imag
        sw, sw_zero, energy = m.sw, m.sw_zero, m.energy
        # V0: applied for the whole period, t_u = Ts
        best = abs(torque_ref - (te + a0ts)) + lam * abs(flux_ref - abs(psi_free)) + sw[0]
        best_n, best_t = 0, ts
        raw_best = ts
        cal = 1
        for n, u, ur, ui in m.active:
            au = tk * (ur * zi - ui * zr)  # m.a_u(u), inlined
            t_raw = num / au if au != 0.0 else (math.copysign(INF, num) if num else INF)
            if t_raw < 0.0:
                continue  # drives the torque the wrong way: discarded, not predicted
            t_u = t_raw if t_raw < ts else ts
            cal += 1
            t1 = te + t_u * au + a0ts
            p1 = psi_free + t_u * u
            # the commutations: the whole period, none of it (t_u = 0: zero vector), or the
            # vector and then the zero vector (+ 0.0 when λ_sw = 0: the same cost, bit for bit)
            g = abs(torque_ref - t1) + lam * abs(flux_ref - abs(p1))
            g += sw[n] if t_u >= ts else sw_zero[n] if t_u > 0.0 else sw[0]
            if energy is not None and 0.0 < t_u < ts:  # its return to zero, at t_u's current
                g += energy.back(n, m.current_at(u, t_u))
            if g < best:
                best, best_n, best_t, raw_best = g, n, t_u, t_raw
        return new_record(Decision, (best_n, best_t / ts, raw_best, cal, NAN))


#: the decision of a full-period vector chosen among all 7, by vector
_FULL_PERIOD = tuple(Decision(n, 1.0, NAN, 7) for n in range(7))


#: the largest horizon mptc takes (its tree has 7^N leaves), and the laws that take one
MAX_HORIZON = 6
HORIZON_STRATEGIES = ("mptc",)


def stage_constants(
    m: IMPrediction, torque_ref: float, flux_ref: float
) -> tuple[float, float, float, float, float, float, float, float, float, float, float]:
    """What :func:`horizon_stages` computes with, as the compiled search takes it: a = a_ii +
    jω_r, b = b_iψ - jω_r c_w (paper 000 eq 4-6), Ts, R_s, Ts·c_w, 1.5p, λ_ψ, T*, ψ*."""
    a_ii, b_ip, cw, rs, p, tk, _, _ = m.c
    return (a_ii, m.wr, b_ip, -m.wr * cw, m.ts, rs, m.ts * cw, tk, m.lam, torque_ref, flux_ref)


def horizon_stages(m: IMPrediction, torque_ref: float, flux_ref: float) -> Expand:
    """mptc's stage over a horizon (:data:`~.search.Expand`): from a node (i_s, ψ_s, code of
    the switching state in force) each vector's predicted node one period on — the one-step
    law's forward Euler with ω frozen, the same arithmetic — and its stage cost
    |T* - T| + λ_ψ |ψ* - |ψ|| + λ_sw × commutations (+ λ_e × their switching energy at the
    node's current, the loss-aware cost)."""
    ar, ai, br, bi, ts, rs, gain_i, tk, lam, _, _ = stage_constants(m, torque_ref, flux_ref)
    volts = m.volts
    a = complex(ar, ai)
    b = complex(br, bi)
    full = m.effort.full if m.effort is not None else (NO_EFFORT,) * 8
    energy = m.energy

    def expand(node: tuple[complex, complex, int]) -> list[tuple[float, int, Any]]:
        i, psi, code = node
        i_free = i + ts * (a * i + b * psi)
        psi_free = psi - ts * rs * i
        sw, after = full[code], AFTER[code]
        if energy is not None:
            sw = tuple(x + y for x, y in zip(sw, energy.full(code, i)))
        out = []
        for n, u in enumerate(volts):
            i1 = i_free + gain_i * u
            p1 = psi_free + ts * u
            t1 = tk * (p1.real * i1.imag - p1.imag * i1.real)
            g = abs(torque_ref - t1) + lam * abs(flux_ref - abs(p1)) + sw[n]
            out.append((g, n, (i1, p1, after[n])))
        return out

    return expand


def _argmin_full_period(m: IMPrediction, torque_ref: float, flux_ref: float) -> int:
    """First strict minimum over V0..V6 of the full-period cost (with the switching effort of
    each vector for the whole period)."""
    tk = m.c.torque_k
    lam = m.lam
    i_free, psi_free, gain_i, ts, sw = m.i_free, m.psi_free, m.gain_i, m.ts, m.sw
    best = INF
    best_n = 0
    for n, u in enumerate(m.volts):
        i1 = i_free + gain_i * u
        p1 = psi_free + ts * u
        t1 = tk * (p1.real * i1.imag - p1.imag * i1.real)
        g = abs(torque_ref - t1) + lam * abs(flux_ref - abs(p1)) + sw[n]
        if g < best:
            best, best_n = g, n
    return best_n


def _argmin_with_duty(m: IMPrediction, torque_ref: float, flux_ref: float) -> tuple[int, float]:
    """MPTC-DB's choice with a switching effort or the loss-aware cost: first strict minimum
    over V0..V6 of the full-period cost plus the commutations of the duty each vector would be
    given (and their energy, the return to zero at the current of its instant); the chosen
    vector and its raw t_u (s)."""
    tk, lam, sw, sw_zero, energy = m.c.torque_k, m.lam, m.sw, m.sw_zero, m.energy
    i_free, psi_free, gain_i, ts = m.i_free, m.psi_free, m.gain_i, m.ts
    best, best_n, best_t = INF, 0, NAN
    for n, u in enumerate(m.volts):
        i1 = i_free + gain_i * u
        p1 = psi_free + ts * u
        t1 = tk * (p1.real * i1.imag - p1.imag * i1.real)
        t_u = m.deadbeat_time(u, torque_ref) if n else ts
        f = t_u / ts
        g = abs(torque_ref - t1) + lam * abs(flux_ref - abs(p1))
        g += sw[0] if n == 0 or f <= 0.0 else sw[n] if f >= 1.0 else sw_zero[n]
        if energy is not None and n and 0.0 < f < 1.0:
            g += energy.back(n, m.current_at(u, t_u))
        if g < best:
            best, best_n, best_t = g, n, t_u
    return best_n, best_t


#: strategy name → class; registry order is the ``strategy`` index in commands
IM_STRATEGIES: Mapping[str, type] = {"mptc": MPTC, "mptc_db": MPTCDB, "db_mptc": DBMPTC}


@dataclass(frozen=True)
class InductionControllerParams:
    """Controller settings for the IM (paper 000 §4).

    ``motor`` is the controller's own model (may differ from the plant's: parameter mismatch).
    lambda_psi: λ of the cost, N·m/Wb (17.5, no normalisation); soft_start_flux in Wb and
    soft_start_current in A (paper 000 §4: 0.65 Wb, 6.5 A); a0_form one of :data:`A0_FORMS`.
    """

    motor: InductionMotor
    strategy: str = choice("control law; switchable at run time", tuple(IM_STRATEGIES))
    lambda_psi: float = quantity("flux weight λ of the cost", "N·m/Wb", ge=0, default=17.5)
    lambda_sw: float = lambda_sw_field("N·m")
    lambda_e: float = lambda_e_field("N·m/J")
    device: str = device_field()
    device_tj: float = device_tj_field()
    horizon: int = horizon_field("mptc", MAX_HORIZON)
    node_budget: int = budget_field("stage costs", NODE_BUDGET)
    search: str = search_field("mptc's branch and bound over a horizon")
    soft_start_flux: float = quantity(
        "soft start until the flux estimate first reaches this", "Wb", ge=0, default=0.65
    )
    soft_start_current: float = quantity(
        "soft start: zero vector above this current", "A", ge=0, default=6.5
    )
    a0_form: str = choice(
        "a_0 of the torque derivative: derived, or paper 000 eq 10 as printed (sign error)",
        A0_FORMS,
        default="derived",
    )
    delay_compensation: bool = delay_compensation()

    def __post_init__(self) -> None:
        check_fields(self)
        check_horizon(self, HORIZON_STRATEGIES)
        check_energy(self)


class InductionController(VectorController):
    """Predictive torque controller for the IM: ``step(state k, reference k) -> command k``.

    Estimates the stator flux by integrating ψ̂(k+1) = ψ̂(k) + Ts(u(k) - R_s i(k)) with the voltage
    it actually applied (docs/physics.md#what-the-controller-sees); soft start at start-up only
    (docs/physics.md#mptc-of-the-induction-motor).
    """

    family = "mptc_im"
    machine = Machine.INDUCTION
    params_type = InductionControllerParams
    strategies = IM_STRATEGIES
    horizon_strategies = HORIZON_STRATEGIES
    max_horizon = MAX_HORIZON

    def __init__(
        self, params: InductionControllerParams, *, ts: float, device: Device | None = None
    ) -> None:
        c = InductionCoefficients.of(params.motor)
        self._coef = c
        effort = SwitchingEffort(params.lambda_sw) if params.lambda_sw > 0 else None
        energy = switching_energy(params, device)
        self._pred = IMPrediction(
            c, ts, params.lambda_psi, params.a0_form == "paper_printed", effort, energy
        )
        self._pred.budget = params.node_budget
        if energy is None:  # the loss-aware cost's horizons search in Python
            self._pred.compiled = compiled(params.search, "search", compiled_branch_and_bound)
        super().__init__(params, ts=ts)
        self.psi_hat = 0j
        self._psi_next = 0j  #: delay compensation: ψ̂ at k+1 under the voltage in force
        self.soft_start = params.soft_start_flux > 0

    def _dc_link(self, u_dc: float) -> None:
        super()._dc_link(u_dc)
        if self._pred.energy is not None:
            self._pred.energy.dc_link(u_dc)

    def _observe(self, state: State) -> None:
        psi = self.psi_hat
        mag = abs(psi)
        if self.soft_start and mag >= self.params.soft_start_flux:
            self.soft_start = (
                False  # latched off for good (docs/physics.md#mptc-of-the-induction-motor)
            )
        self.est_flux = mag
        self.est_flux_angle = math.atan2(psi.imag, psi.real) % TWO_PI

    def _predict(self, state: State, u_ab: complex) -> State:
        a_ii, b_ip, cw, rs = self._coef[:4]
        ts = self.ts
        wr = self._coef.p * state.omega_m
        i = complex(state.i_alpha, state.i_beta)
        psi = self.psi_hat
        i1 = i + ts * (complex(a_ii, wr) * i + complex(b_ip, -wr * cw) * psi + cw * u_ab)
        self._psi_next = psi + ts * (u_ab - rs * i)
        return state._replace(i_alpha=i1.real, i_beta=i1.imag)

    def _decide(self, state: State, ref: Reference) -> Decision:
        # the IM's free response (i_free, ψ_free, a_0) is the prediction model: part of the law
        i = complex(state.i_alpha, state.i_beta)
        m = self._pred
        psi = self._psi_next if self._compensate else self.psi_hat
        m.prepare(i, psi, state.omega_m, self._volts)  # keeps i for _applied
        m.horizon = self.horizon
        if m.effort is not None or m.energy is not None:
            m.switching(self.switches)
        self.est_torque = m.te
        if self.soft_start:
            return Decision(0 if abs(i) > self.params.soft_start_current else 1, 1.0, NAN, 0)
        d: Decision = self.strategy.decide(m, ref.torque_ref, ref.flux_ref)
        return d

    def _applied(self, d: Decision, state: State) -> None:
        if self._compensate:  # ψ̂ follows the voltage that acts, not the one just decided
            self.psi_hat = self._psi_next
            return
        u_avg = d.fraction * self._volts[d.vector]
        self.psi_hat = self.psi_hat + self.ts * (u_avg - self._coef.r_s * self._pred.i)
