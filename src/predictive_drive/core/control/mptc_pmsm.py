"""Paper 001: predictive torque control of the PMSM — conventional MPTC and simplified strategies
1-3 (docs/physics.md#mptc-of-the-pmsm), the controller family ``mptc_pmsm``.

The controller sees the measured currents and rotor angle and forms the stator flux and torque with
its own L_d, L_q, ψ_f (docs/physics.md#what-the-controller-sees). Each candidate vector is predicted
with paper 001 eq 1-3 — the stator-flux frame, R_s neglected, the rotor frozen over Ts — and its
torque from the predicted flux with the saliency term (for L_d = L_q this is eq 2 exactly); with
``prediction: rotor_motion`` the torque is taken at the rotor's angle at the period's end
(docs/physics.md#predicting-the-pmsm-over-a-period). Cost eq
5, normalised; T* is guarded by T_floor because it crosses zero at every load reversal. Candidates
are evaluated in ascending vector order and the first strict minimum wins. The restricted candidate
sets of strategies 2 and 3 are data (:mod:`.candidates`) that ``predictive-drive analyze``
regenerates from a recording.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from math import asin, cos, sin, sqrt
from typing import Any

import numpy as np

from ..devices import Device
from ..fields import check_fields, choice, quantity
from ..machines import Machine
from ..machines.magnetics import PMSMSaturation
from ..machines.pmsm import PMSM, PMSMCoefficients
from ..signals import Reference, State
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
    pmsm_predicted,
    prediction_field,
    rows,
    search_field,
)
from .candidates import TABLES
from .energy import (
    SwitchingEnergy,
    check_energy,
    device_field,
    device_tj_field,
    lambda_e_field,
    switching_energy,
)
from .kernels import PMSM_STAGE, BranchAndBound, compiled_branch_and_bound
from .maps import ApparentModel, flux_map_of
from .search import Expand, SearchResult, branch_and_bound

__all__ = [
    "PMSM_STRATEGIES",
    "PMSMController",
    "PMSMControllerParams",
    "PMSMPrediction",
]

NAN = math.nan
INF = math.inf
TWO_PI = 2.0 * math.pi
#: angle of V1..V6 in αβ (V1 at 0°, 60° apart); index 0 unused (V0 has no direction)
VECTOR_ANGLES = (0.0, *(n * math.pi / 3.0 for n in range(6)))
ACTIVE_VECTORS = (1, 2, 3, 4, 5, 6)


def _classes(
    sets: list[tuple[int, ...]],
) -> tuple[tuple[tuple[int, ...], tuple[Decision, ...]], ...]:
    """Per class: the non-zero candidates (V0 is in every set, checked on load, and evaluated
    first) and the decision for each vector with this class's Cal."""
    return tuple((c[1:], tuple(Decision(n, 1.0, NAN, len(c)) for n in range(7))) for c in sets)


#: flat class index: 6-sector s + 6 if ΔT < 0
_SIX_CLASSES = _classes([c for row in TABLES.six for c in row])
#: flat class index: 12-sector s + 12 if Δψ < 0 + 24 if ΔT < 0
_TWELVE_CLASSES = _classes([c for t in TABLES.twelve for r in t for c in r])


class PMSMPrediction:
    """One step's view of the PMSM from the controller's model, and eq 1-3 per candidate.

    After :meth:`prepare`: ``te`` (N·m), ``psi`` (|ψ̂_s|, Wb), ``delta`` (torque angle: ψ̂_s from the
    rotor d-axis, rad), ``theta_psi`` (ψ̂_s in αβ, [0, 2π)), ``q`` (|V|·Ts/|ψ̂_s|, eq 3).

    ``rotor_motion``: the torque at the period's end is taken at the rotor's angle there, the
    rotor having turned ``turn`` = ω_e·Ts under the predicted flux; else (paper 001) at the
    angle of the period's start (docs/physics.md#predicting-the-pmsm-over-a-period).
    """

    __slots__ = (
        "c",
        "ts",
        "threshold",
        "t_floor",
        "te",
        "psi",
        "delta",
        "theta_psi",
        "q",
        "consts",
        "args",
        "effort",
        "energy",
        "sw",
        "code",
        "horizon",
        "theta_e",
        "w_e",
        "volts",
        "rotor_motion",
        "turn",
        "budget",
        "compiled",
        "effort_table",
    )

    def __init__(
        self,
        c: PMSMCoefficients,
        ts: float,
        threshold: float,
        t_floor: float,
        effort: SwitchingEffort | None = None,
        energy: SwitchingEnergy | None = None,
    ) -> None:
        self.c = c
        self.ts = ts
        self.threshold = threshold
        self.t_floor = t_floor
        #: the parameters the candidate loop needs
        self.consts = (c.psi_f, 1.0 / c.l_d, 1.0 / c.l_q, c.torque_k, c.l_d - c.l_q, t_floor)
        #: the switching effort (None: λ_sw = 0) and each vector's cost for the whole period
        #: from the state in force (:meth:`switching`)
        self.effort = effort
        #: the loss-aware cost (None: λ_e = 0): each vector's predicted switching energy,
        #: added to ``sw`` by :meth:`switching` at the period's current
        self.energy = energy
        self.sw: tuple[float, ...] | None = None
        self.code = 0  #: the switching state in force, S_a·4 + S_b·2 + S_c
        self.horizon = 1  #: N: periods mptc's cost sums over (docs/physics.md#long-horizons)
        self.budget = 0  #: stage costs a search may evaluate (0: no limit)
        #: the compiled branch and bound (None: search.branch_and_bound), and the switching
        #: effort's costs as it takes them
        self.compiled: BranchAndBound | None = None
        self.effort_table = NO_EFFORT_TABLE if effort is None else np.array(effort.full)
        self.theta_e = 0.0  #: rotor angle at the sample, rad
        self.w_e = 0.0  #: electrical speed, rad/s
        self.volts: tuple[complex, ...] = ()
        self.rotor_motion = False
        self.turn = 0.0  #: rad the rotor turns before the torque is evaluated

    def use(self, c: PMSMCoefficients) -> None:
        """Predict with the model ``c`` from now on (a flux map's apparent model, see
        :class:`.maps.ApparentModel`)."""
        self.c = c
        self.consts = (c.psi_f, 1.0 / c.l_d, 1.0 / c.l_q, c.torque_k, c.l_d - c.l_q, self.t_floor)

    def switching(self, switches: tuple[int, int, int], i: complex = 0j) -> None:
        """The switching state in force (the one the candidates' commutations count from) and,
        for the loss-aware cost, the current the commutations carry (A, αβ)."""
        self.code = code = SwitchingEffort.code(switches)
        effort = None if self.effort is None else self.effort.full[code]
        if self.energy is None:
            if effort is not None:
                self.sw = effort
            return
        spent = self.energy.full(code, i)
        self.sw = spent if effort is None else tuple(a + b for a, b in zip(effort, spent))

    def prepare(
        self, i_alpha: float, i_beta: float, theta_e: float, u_dc: float, w_e: float = 0.0
    ) -> None:
        """The estimate from the measured currents, rotor angle, DC link and (for
        ``rotor_motion``) electrical speed, rad/s."""
        c = self.c
        self.turn = w_e * self.ts if self.rotor_motion else 0.0
        co, si = math.cos(theta_e), math.sin(theta_e)
        i_d = i_alpha * co + i_beta * si
        i_q = i_beta * co - i_alpha * si
        psi_d = c.l_d * i_d + c.psi_f
        psi_q = c.l_q * i_q
        delta = math.atan2(psi_q, psi_d)
        self.set(
            c.torque_k * i_q * (c.psi_f + (c.l_d - c.l_q) * i_d),
            math.hypot(psi_d, psi_q),
            delta,
            (theta_e + delta) % TWO_PI,
            u_dc,
        )

    def set(self, te: float, psi: float, delta: float, theta_psi: float, u_dc: float) -> None:
        """Take an estimate as it is (:meth:`prepare` derives one; tests set one by hand)."""
        self.te = te
        self.psi = psi
        self.delta = delta
        self.theta_psi = theta_psi
        self.q = q = (2.0 / 3.0) * u_dc * self.ts / psi
        if self.rotor_motion:  # the flux's angle from the rotor at the period's end; V0's torque
            delta = delta - self.turn
            te = self._torque(psi, delta)
        #: what the candidate loop reads, in one tuple: one load per decision
        self.args = (*self.consts, psi, delta, theta_psi, q, te)

    def _torque(self, psi: float, delta: float) -> float:
        """The torque of flux linkage ``psi`` (Wb) at ``delta`` (rad) from the rotor's d axis."""
        c = self.c
        i_d = (psi * math.cos(delta) - c.psi_f) / c.l_d
        i_q = psi * math.sin(delta) / c.l_q
        return c.torque_k * i_q * (c.psi_f + (c.l_d - c.l_q) * i_d)

    def current(self, psi: complex, ell: int = 0) -> complex:
        """The current (A, αβ) of stator flux ``psi`` (Wb, αβ) at the start of period ``ell``
        of a horizon (the rotor at θ_e + ℓ·ω_e·Ts), by the model's L_d, L_q, ψ_f."""
        c = self.c
        rot = complex(math.cos(self.theta_e + ell * self.w_e * self.ts),
                      math.sin(self.theta_e + ell * self.w_e * self.ts))  # fmt: skip
        dq = psi / rot
        return complex((dq.real - c.psi_f) / c.l_d, dq.imag / c.l_q) * rot

    def predict(self, n: int) -> tuple[float, float]:
        """(T_e(k+1), |ψ_s(k+1)|) if vector ``n`` is applied for Ts (paper 001 eq 1-3).

        The readable form of one candidate; :func:`_argmin` inlines the same arithmetic in its
        loop (a call per candidate would be a third of the candidate's cost). Tests hold both to
        the independent vector form ψ(k+1) = ψ(k) + V·Ts."""
        if n == 0:
            r, d1 = 1.0, self.delta
        else:
            q = self.q
            a = VECTOR_ANGLES[n] - self.theta_psi
            r = math.sqrt(1.0 + q * q + 2.0 * q * math.cos(a))  # eq 1
            d1 = self.delta + math.asin(q * math.sin(a) / r)  # eq 2's angle
        psi1 = self.psi * r
        return self._torque(psi1, d1 - self.turn), psi1


def _argmin(m: PMSMPrediction, active: tuple[int, ...], t_ref: float, psi_ref: float) -> int:
    """First strict minimum of eq 5 over V0 and the non-zero vectors ``active`` (ascending). V0
    leaves ψ and δ as they are, so its prediction is T̂ itself. Without a switching effort the
    sqrt is dropped (it keeps the order); with one, each vector's effort adds to the cost
    itself."""
    sw = m.sw
    pf, ild, ilq, tk, dl, t_floor, psi, delta, th, q, te = m.args
    inv_t = 1.0 / (t_ref if t_ref > t_floor else -t_ref if -t_ref > t_floor else t_floor)
    inv_p = 1.0 / psi_ref
    e_t = (te - t_ref) * inv_t
    e_p = (psi - psi_ref) * inv_p
    best = e_t * e_t + e_p * e_p
    if sw is not None:
        best = sqrt(best) + sw[0]
    best_n = 0
    qq1 = 1.0 + q * q
    q2 = q + q
    angles = VECTOR_ANGLES
    for n in active:
        a = angles[n] - th
        r = sqrt(qq1 + q2 * cos(a))  # eq 1
        d1 = delta + asin(q * sin(a) / r)  # eq 2's angle
        psi1 = psi * r
        i_q1 = psi1 * sin(d1) * ilq
        e_t = (tk * i_q1 * (pf + dl * (psi1 * cos(d1) - pf) * ild) - t_ref) * inv_t
        e_p = (psi1 - psi_ref) * inv_p
        g = e_t * e_t + e_p * e_p
        if sw is not None:
            g = sqrt(g) + sw[n]
        if g < best:
            best = g
            best_n = n
    return best_n


_ZERO = Decision(0, 1.0, NAN, 0)
#: the largest horizon mptc takes (its tree has 7^N leaves), and the laws that take one
MAX_HORIZON = 6
HORIZON_STRATEGIES = ("mptc",)
#: the decisions a full-period strategy can return, by (predictions evaluated, vector): no per-step
#: allocation
_DECISIONS = {cal: tuple(Decision(n, 1.0, NAN, cal) for n in range(7)) for cal in range(1, 8)}
_SIX = TWO_PI / 6  #: sector widths, rad (divided by, as in sector(): exact at the boundaries)
_TWELVE = TWO_PI / 12


class MPTC:
    """Conventional MPTC (paper 001 §2): all 7 vectors, cost eq 5. Over a horizon of N > 1
    periods the stage costs of a sequence are summed (:func:`horizon_stages`) and the first
    vector of the best sequence applied, found by branch and bound (:mod:`.search`), the last
    optimum shifted as its first bound (``plan``)."""

    name = "mptc"

    def __init__(self) -> None:
        self.plan: tuple[int, ...] = ()
        self.found = SearchResult((), INF, 0)  #: the last search's result

    def decide(self, m: PMSMPrediction, torque_ref: float, flux_ref: float) -> Decision:
        if m.horizon == 1:
            return _DECISIONS[7][_argmin(m, ACTIVE_VECTORS, torque_ref, flux_ref)]
        guess = (*self.plan[1:], self.plan[-1]) if self.plan else ()
        root = (m.psi * complex(math.cos(m.theta_psi), math.sin(m.theta_psi)), 0, m.code)
        if m.compiled is not None:
            constants, steps, turn = stage_constants(m, torque_ref, flux_ref)
            psi = root[0]
            found = m.compiled(
                PMSM_STAGE, np.array(constants), np.array((psi.real, psi.imag, 0.0, 0.0)),
                m.code, rows(steps), m.effort_table, AFTER_TABLE, rows(turn), m.horizon,
                guess, m.budget,
            )  # fmt: skip
        else:
            stages = horizon_stages(m, torque_ref, flux_ref)
            found = branch_and_bound(stages, root, m.horizon, guess, m.budget)
        self.plan, self.found = found.sequence, found
        return Decision(found.sequence[0], 1.0, NAN, found.nodes, 0.0 if found.complete else 1.0)


def stage_constants(
    m: PMSMPrediction, torque_ref: float, flux_ref: float
) -> tuple[tuple[float, ...], list[complex], list[complex]]:
    """What :func:`horizon_stages` computes with, as the compiled search takes it: (ψ_f, 1/L_d,
    1/L_q, 1.5p, L_d - L_q, 1/T*, 1/ψ*, T*, ψ*), each vector's ψ step V·Ts, and each period's
    turn into the rotor frame e^{-jθ_e(ℓ)}."""
    pf, ild, ilq, tk, dl, t_floor = m.consts
    inv_t = 1.0 / (torque_ref if torque_ref > t_floor else -torque_ref if -torque_ref > t_floor
                   else t_floor)  # fmt: skip
    inv_p = 1.0 / flux_ref
    steps = [v * m.ts for v in m.volts]
    end = 1 if m.rotor_motion else 0
    turn = [complex(math.cos(-m.theta_e - (ell + end) * m.w_e * m.ts),
                    math.sin(-m.theta_e - (ell + end) * m.w_e * m.ts))
            for ell in range(m.horizon)]  # fmt: skip
    return (pf, ild, ilq, tk, dl, inv_t, inv_p, torque_ref, flux_ref), steps, turn


def horizon_stages(m: PMSMPrediction, torque_ref: float, flux_ref: float) -> Expand:
    """mptc's stage over a horizon (:data:`~.search.Expand`): from a node (ψ_s in αβ, the
    period ℓ it starts, the code of the switching state in force) each vector's ψ_s one period
    on by eq 1-3 in vector form, ψ + V·Ts (R_s neglected), its torque in the rotor frame at
    the rotor's angle of that period's start (frozen over it, as eq 1-3 take it:
    θ_e + ℓ·ω_e·Ts) or, with ``rotor_motion``, of its end (θ_e + (ℓ+1)·ω_e·Ts), and the stage
    cost sqrt(((T - T*)/T*)² + ((|ψ| - ψ*)/ψ*)²) + λ_sw × commutations (+ λ_e × their
    switching energy at the current of the node's ψ_s at the period's start, the loss-aware
    cost)."""
    (pf, ild, ilq, tk, dl, inv_t, inv_p, _, _), steps, turn = stage_constants(
        m, torque_ref, flux_ref
    )
    full = m.effort.full if m.effort is not None else (NO_EFFORT,) * 8
    energy = m.energy

    def expand(node: tuple[complex, int, int]) -> list[tuple[float, int, Any]]:
        psi, ell, code = node
        rot, sw, after = turn[ell], full[code], AFTER[code]
        if energy is not None:
            sw = tuple(x + y for x, y in zip(sw, energy.full(code, m.current(psi, ell))))
        out = []
        for n, step in enumerate(steps):
            p1 = psi + step
            dq = p1 * rot
            i_d = (dq.real - pf) * ild
            i_q = dq.imag * ilq
            e_t = (tk * i_q * (pf + dl * i_d) - torque_ref) * inv_t
            e_p = (abs(p1) - flux_ref) * inv_p
            out.append((sqrt(e_t * e_t + e_p * e_p) + sw[n], n, (p1, ell + 1, after[n])))
        return out

    return expand


class Simplified1:
    """Strategy 1 (paper 001 §3): |T* - T̂| ≤ threshold → the zero vector, nothing evaluated;
    otherwise conventional MPTC."""

    name = "simplified1"

    def decide(self, m: PMSMPrediction, torque_ref: float, flux_ref: float) -> Decision:
        if abs(torque_ref - m.te) <= m.threshold:
            return _ZERO
        return _DECISIONS[7][_argmin(m, ACTIVE_VECTORS, torque_ref, flux_ref)]


class Simplified2:
    """Strategy 2 (paper 001 §4): strategy 1 with 4 candidates above the threshold, chosen by the
    6-sector of ψ̂_s and the sign of the torque error (paper 001 Tables 3-4)."""

    name = "simplified2"

    def decide(self, m: PMSMPrediction, torque_ref: float, flux_ref: float) -> Decision:
        dt = torque_ref - m.te
        if abs(dt) <= m.threshold:
            return _ZERO
        # θ_ψ is in [0, 2π): sector(θ_ψ, 6), inlined
        active, decisions = _SIX_CLASSES[int(m.theta_psi / _SIX) % 6 + (6 if dt < 0.0 else 0)]
        return decisions[_argmin(m, active, torque_ref, flux_ref)]


class Simplified3:
    """Strategy 3 (paper 001 §5): 12 sectors of ψ̂_s, the torque-error sign and the flux-error sign
    (Δψ = ψ* - |ψ̂_s| ≥ 0 counts as positive); 3 or 4 candidates."""

    name = "simplified3"

    def decide(self, m: PMSMPrediction, torque_ref: float, flux_ref: float) -> Decision:
        dt = torque_ref - m.te
        if abs(dt) <= m.threshold:
            return _ZERO
        k = int(m.theta_psi / _TWELVE) % 12  # sector(θ_ψ, 12), inlined
        if dt < 0.0:
            k += 24
        if flux_ref < m.psi:
            k += 12
        active, decisions = _TWELVE_CLASSES[k]
        return decisions[_argmin(m, active, torque_ref, flux_ref)]


PMSM_STRATEGIES: Mapping[str, type] = {
    "mptc": MPTC,
    "simplified1": Simplified1,
    "simplified2": Simplified2,
    "simplified3": Simplified3,
}


@dataclass(frozen=True)
class PMSMControllerParams:
    """Controller settings for the PMSM (paper 001).

    ``motor`` is the controller's own model (may differ from the plant's: parameter mismatch).
    torque_threshold: N·m, |T* - T̂| at or below which strategies 1-3 output the zero vector (paper
    001 §3: 5 % of rated torque; NaN → 5 % of ``motor.rated_torque``). t_floor: N·m, the smallest
    |T*| the torque term of eq 5 is divided by (NaN → 1 % of rated torque).
    """

    motor: PMSM
    strategy: str = choice("control law; switchable at run time", tuple(PMSM_STRATEGIES))
    torque_threshold: float = quantity(
        "|T* - T̂| at or below which simplified1-3 output the zero vector",
        "N·m",
        ge=0,
        nan_default="5 % of rated torque",
        default=NAN,
    )
    t_floor: float = quantity(
        "smallest |T*| the torque term of the cost is divided by",
        "N·m",
        gt=0,
        nan_default="1 % of rated torque",
        default=NAN,
    )
    lambda_sw: float = lambda_sw_field("p.u. (eq 5's cost is normalised)")
    lambda_e: float = lambda_e_field("1/J (eq 5's cost is normalised)")
    device: str = device_field()
    device_tj: float = device_tj_field()
    horizon: int = horizon_field("mptc", MAX_HORIZON)
    node_budget: int = budget_field("stage costs", NODE_BUDGET)
    search: str = search_field("mptc's branch and bound over a horizon")
    prediction: str = prediction_field()
    delay_compensation: bool = delay_compensation()
    #: the controller's own flux map (docs/physics.md#saturation): with a model, it predicts
    #: with the map's apparent inductances at the measured current; none: its linear ``motor``
    saturation: PMSMSaturation = PMSMSaturation()

    def __post_init__(self) -> None:
        check_fields(self)
        check_horizon(self, HORIZON_STRATEGIES)
        check_energy(self)
        for name, share in (("torque_threshold", 0.05), ("t_floor", 0.01)):
            if math.isnan(getattr(self, name)):
                object.__setattr__(self, name, share * self.motor.rated_torque)


class PMSMController(VectorController):
    """Predictive torque controller for the PMSM: ``step(state k, reference k) -> command k``."""

    family = "mptc_pmsm"
    machine = Machine.PMSM
    params_type = PMSMControllerParams
    strategies = PMSM_STRATEGIES
    horizon_strategies = HORIZON_STRATEGIES
    max_horizon = MAX_HORIZON

    def __init__(
        self, params: PMSMControllerParams, *, ts: float, device: Device | None = None
    ) -> None:
        effort = SwitchingEffort(params.lambda_sw) if params.lambda_sw > 0 else None
        energy = switching_energy(params, device)
        self._pred = PMSMPrediction(
            PMSMCoefficients.of(params.motor), ts, params.torque_threshold, params.t_floor, effort,
            energy,
        )  # fmt: skip
        fm = flux_map_of(params.motor, params.saturation)
        self._apparent = None if fm is None else ApparentModel(fm, self._pred.c)
        self._pred.rotor_motion = params.prediction == "rotor_motion"
        self._pred.budget = params.node_budget
        if energy is None:  # the loss-aware cost's horizons search in Python
            self._pred.compiled = compiled(params.search, "search", compiled_branch_and_bound)
        super().__init__(params, ts=ts)

    def _dc_link(self, u_dc: float) -> None:
        super()._dc_link(u_dc)
        if self._pred.energy is not None:
            self._pred.energy.dc_link(u_dc)

    def _predict(self, state: State, u_ab: complex) -> State:
        p = self._pred
        return pmsm_predicted(p.c, self.ts, state, u_ab, rotor_motion=p.rotor_motion)

    def _observe(self, state: State) -> None:
        m = self._pred
        if self._apparent is not None:  # the map's model at this current
            m.use(self._apparent.at(state.i_alpha, state.i_beta, state.theta_e))
        w_e = m.c.p * state.omega_m
        m.prepare(state.i_alpha, state.i_beta, state.theta_e, state.u_dc, w_e)
        self.est_torque = m.te
        self.est_flux = m.psi
        self.est_flux_angle = m.theta_psi

    def _decide(self, state: State, ref: Reference) -> Decision:
        m = self._pred
        m.horizon = self.horizon
        if m.horizon > 1:
            m.theta_e, m.w_e, m.volts = state.theta_e, m.c.p * state.omega_m, self._volts
            m.switching(self.switches, complex(state.i_alpha, state.i_beta))
        elif m.effort is not None or m.energy is not None:  # the commutations carry i(k)
            m.switching(self.switches, complex(state.i_alpha, state.i_beta))
        d: Decision = self.strategy.decide(m, ref.torque_ref, ref.flux_ref)
        return d

    def decision_inputs(self, states: list[State]) -> list[PMSMPrediction]:
        p = self._pred
        out = []
        for s in states:
            m = PMSMPrediction(p.c, p.ts, p.threshold, p.t_floor)
            m.rotor_motion = p.rotor_motion
            m.prepare(s.i_alpha, s.i_beta, s.theta_e, s.u_dc, p.c.p * s.omega_m)
            out.append(m)
        return out
