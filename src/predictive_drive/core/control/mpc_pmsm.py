"""Direct model predictive current control of the PMSM with sphere decoding — the controller
family ``mpc_pmsm``, strategy ``direct_mpc`` (docs/physics.md#long-horizons; T. Geyer, D. E.
Quevedo, "Multistep finite control set model predictive control for power electronics", IEEE
TPEL 29(12), 2014).

A family of its own: its law chooses the inverter's switch positions directly over a horizon of
N periods (no modulator), where field-oriented control's laws choose a current angle for a PI
loop and SVPWM. It takes its current references as ``foc_pmsm`` does — the speed PI's T* as the
amplitude that makes T* at the MTPA angle of paper 002 eq 10, the reluctance torque counted
(:func:`~.mtpa.mtpa_current`), or I_s = |T*|/k_t at i_d = 0 — and minimises

    J = Σ_{ℓ=0}^{N-1} ‖(i* - i(ℓ+1))/I_b‖² + λ_u ‖u(ℓ) - u(ℓ-1)‖²

over the switch positions u(ℓ) ∈ {0, 1}³ of the three legs (000 and 111 apart: ‖Δu‖² counts
commutations), I_b the rated current (rated torque / k_t): J is per unit. The model is the
family's own: the dq currents stepped by forward Euler at the speed of the sample, the rotor
turning ω_e·Ts a period, each period's voltage turned into dq at its middle (``prediction:
rotor_motion``: each period solved exactly at that speed,
docs/physics.md#predicting-the-pmsm-over-a-period) — linear,
i(ℓ+1) = A i(ℓ) + B_ℓ u(ℓ) + c — so J is, up to a constant, (U - U_unc)ᵀ H (U - U_unc) with
H = ΥᵀΥ + λ_u SᵀS over the stacked U (in reverse order of time, so the decoder decides the
first period first). With H = VᵀV (V upper triangular, from the Cholesky factor) it is the
integer least-squares problem min ‖V·U_unc - V·U‖², solved exactly by
:func:`~.search.sphere_decode`, the last optimum shifted as its first radius, within
``node_budget`` nodes (docs/physics.md#a-budget-per-step). Of the sequences that apply the
optimum's voltages (000 and 111 exchanged), the fewest commutations and then the
lexicographically smallest is taken (:func:`smallest_of_equal_cost`: exact ties, which the
decoder's rounded distance cannot order). The first three components are applied for the whole
period; ``cal`` is the decoder's node count. :func:`solve` is the decision in plain Python,
the reference :func:`~.kernels.compiled_direct_mpc` is held to bit for bit.
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..fields import check_fields, choice, quantity
from ..inverter import park, state_to_vector
from ..machines import Machine
from ..machines.pmsm import PMSM, PMSMCoefficients, PMSMStep, pmsm_exact_step
from ..signals import Command, PhasePulses, Reference, State, new_record
from .base import (
    NODE_BUDGET,
    Controller,
    budget_field,
    check_horizon,
    compiled,
    delay_compensation,
    horizon_field,
    pmsm_predicted,
    prediction_field,
    search_field,
)
from .kernels import compiled_direct_mpc
from .mtpa import formula_angle, mtpa_current
from .search import SearchResult, sphere_decode

__all__ = [
    "DIRECT_MPC_STRATEGIES",
    "DirectMPC",
    "MAX_HORIZON",
    "MPCController",
    "MPCParams",
    "MTPA_LAWS",
    "QuadraticProblem",
    "current_problem",
    "smallest_of_equal_cost",
]

NAN = math.nan
TWO_PI = 2.0 * math.pi
#: the largest horizon: 3N binary unknowns
MAX_HORIZON = 12
#: the current references' angle: paper 002 eq 10's MTPA, or i_d = 0
MTPA_LAWS = ("formula", "zero_d")
#: (S_a, S_b, S_c) → u_αβ per volt of U_dc: (2/3)(S_a + a S_b + a² S_c), as two real rows
_LEGS_ROWS = (
    (2.0 / 3.0, -1.0 / 3.0, -1.0 / 3.0),
    (0.0, 1.0 / math.sqrt(3.0), -1.0 / math.sqrt(3.0)),
)


class DirectMPC:
    """``direct_mpc``: the switch positions over N periods by sphere decoding."""

    name = "direct_mpc"

    def __init__(self) -> None:
        self.plan: tuple[int, ...] = ()


#: strategy name → class; registry order is the ``strategy`` index in commands
DIRECT_MPC_STRATEGIES: Mapping[str, type] = {"direct_mpc": DirectMPC}
HORIZON_STRATEGIES = ("direct_mpc",)


@dataclass(frozen=True)
class MPCParams:
    """Controller settings of direct model predictive current control of the PMSM.

    ``motor`` is the controller's own model. lambda_u weighs one commutation against a current
    error of the rated current (both squared, per unit).
    """

    motor: PMSM
    strategy: str = choice("control law", tuple(DIRECT_MPC_STRATEGIES), default="direct_mpc")
    horizon: int = horizon_field("direct_mpc", MAX_HORIZON)
    lambda_u: float = quantity(
        "switching weight λ_u: cost of one commutation against a current error of the rated "
        "current, per unit squared",
        gt=0,
        default=0.01,
    )
    mtpa: str = choice(
        "current angle of the references: formula (paper 002 eq 10) or zero_d", MTPA_LAWS,
        default="formula",
    )  # fmt: skip
    decoder: str = search_field("the sphere decoder")
    prediction: str = prediction_field()
    node_budget: int = budget_field("tree nodes", NODE_BUDGET)
    delay_compensation: bool = delay_compensation()

    def __post_init__(self) -> None:
        check_fields(self)
        check_horizon(self, HORIZON_STRATEGIES)


@dataclass(frozen=True)
class QuadraticProblem:
    """One decision's integer least-squares problem (see the module's text): V (upper
    triangular) and ū = V·U_unc, and the constant the cost differs from ‖ū - V·U‖² by.

    U stacks the switch positions in reverse order of time — u(N-1)_c, u(N-1)_b, u(N-1)_a, …,
    u(0)_c, u(0)_b, u(0)_a — so the decoder, which fixes the last component first, decides
    the first period first (:meth:`in_time` turns a solution back)."""

    v: np.ndarray
    ubar: np.ndarray
    constant: float

    @staticmethod
    def in_time(sequence: tuple[int, ...]) -> tuple[int, ...]:
        """A solution U as switch positions in order of time: u(0)_a, u(0)_b, u(0)_c, …"""
        return sequence[::-1]


#: (A: a11, a12, a21, a22; c: c_d, c_q; G: g11, g12, g21, g22; the share of the period at
#: whose angle the voltage is turned into dq): the model of one period,
#: i(ℓ+1) = A·i(ℓ) + G·u_dq(ℓ) + c (:func:`period_model`)
Model = tuple[float, float, float, float, float, float, float, float, float, float, float]
#: (i_d, i_q, θ_e, the rotor's turn a period ω_e·Ts, U_dc, i_d*, i_q*): where a decision starts
Start = tuple[float, float, float, float, float, float, float]


def period_model(c: PMSMCoefficients, ts: float, w_e: float, exact: PMSMStep | None) -> Model:
    """The model of one period at electrical speed ``w_e``: forward Euler in dq (A = I + Ts·F,
    G = Ts·diag(1/L_d, 1/L_q), the voltage at the period's middle angle), or the exact period
    ``exact`` (the voltage at its start angle)."""
    if exact is None:
        return (
            1.0 - ts * c.r_s * c.inv_l_d,
            ts * w_e * c.l_q * c.inv_l_d,
            -ts * w_e * c.l_d * c.inv_l_q,
            1.0 - ts * c.r_s * c.inv_l_q,
            0.0,
            -ts * w_e * c.psi_f * c.inv_l_q,
            ts * c.inv_l_d,
            0.0,
            0.0,
            ts * c.inv_l_q,
            0.5,
        )
    x = exact
    return (x.a11, x.a12, x.a21, x.a22, x.f_d, x.f_q, x.g11, x.g12, x.g21, x.g22, 0.0)


def current_problem(
    c: PMSMCoefficients,
    *,
    ts: float,
    i_dq: complex,
    theta_e: float,
    w_e: float,
    u_dc: float,
    i_ref: complex,
    i_base: float,
    lambda_u: float,
    u_prev: tuple[int, int, int],
    horizon: int,
    exact: PMSMStep | None = None,
) -> QuadraticProblem:
    """The cost J over ``horizon`` periods from the dq current ``i_dq`` (A) at rotor angle
    ``theta_e`` (rad) and electrical speed ``w_e`` (rad/s) as an integer least-squares problem:
    the model forward Euler in dq, or ``exact`` (:func:`~..machines.pmsm.pmsm_exact_step` at
    ``w_e``: the rotor's motion through each period)."""
    model = period_model(c, ts, w_e, exact)
    state = (i_dq.real, i_dq.imag, theta_e, w_e * ts, u_dc, i_ref.real, i_ref.imag)
    v, ubar, constant = problem(model, horizon, state, i_base, lambda_u, u_prev)
    return QuadraticProblem(np.array(v), np.array(ubar), constant)


def problem(
    model: Model, n: int, state: Start, i_base: float, lam: float, prev: tuple[int, int, int]
) -> tuple[list[list[float]], list[float], float]:
    """(V, ū, constant) of :class:`QuadraticProblem` over ``n`` periods from ``state`` (see
    :data:`Start`), in plain floats: the reference the compiled kernel (:mod:`.kernels`)
    repeats operation for operation."""
    a11, a12, a21, a22, cd, cq, g11, g12, g21, g22, share = model
    i_d, i_q, theta, turn, u_dc, r_d, r_q = state
    size = 3 * n
    l0, l1 = _LEGS_ROWS
    # A^k, k < n; the free response's error e0 = (i* - i_free)/I_b, rows 2ℓ (d) and 2ℓ+1 (q)
    pw = [(1.0, 0.0, 0.0, 1.0)]
    for _ in range(n - 1):
        p11, p12, p21, p22 = pw[-1]
        pw.append((a11 * p11 + a12 * p21, a11 * p12 + a12 * p22,
                   a21 * p11 + a22 * p21, a21 * p12 + a22 * p22))  # fmt: skip
    e0 = [0.0] * (2 * n)
    x, y = i_d, i_q
    for ell in range(n):
        x, y = a11 * x + a12 * y + cd, a21 * x + a22 * y + cq
        e0[2 * ell] = (r_d - x) / i_base
        e0[2 * ell + 1] = (r_q - y) / i_base
    # Υ: current ℓ+1 (rows) per switch position of period m ≤ ℓ (columns, in U's order)
    ups = [[0.0] * size for _ in range(2 * n)]
    for m in range(n):
        angle = theta + (m + share) * turn
        co, si = math.cos(angle), math.sin(angle)
        for j in range(3):
            ud = u_dc * (co * l0[j] + si * l1[j])
            uq = u_dc * (co * l1[j] - si * l0[j])
            bd = (g11 * ud + g12 * uq) / i_base
            bq = (g21 * ud + g22 * uq) / i_base
            col = size - 1 - (3 * m + j)
            for ell in range(m, n):
                p11, p12, p21, p22 = pw[ell - m]
                ups[2 * ell][col] = p11 * bd + p12 * bq
                ups[2 * ell + 1][col] = p21 * bd + p22 * bq
    # H = ΥᵀΥ + λ SᵀS and f = Υᵀe0 + λ Sᵀ[u_prev, 0, …]: each sum over the rows where both
    # columns can be non-zero (from period max(m_i, m_k) on), in order
    h = [[0.0] * size for _ in range(size)]
    f = [0.0] * size
    for i in range(size):
        ti = size - 1 - i
        mi = ti // 3
        acc = 0.0
        for r in range(2 * mi, 2 * n):
            acc += ups[r][i] * e0[r]
        f[i] = acc + lam * prev[ti] if mi == 0 else acc
        for k in range(i, size):
            tk = size - 1 - k
            mk = tk // 3
            acc = 0.0
            for r in range(2 * (mi if mi > mk else mk), 2 * n):
                acc += ups[r][i] * ups[r][k]
            if ti == tk:
                acc += lam * (1.0 if mi == n - 1 else 2.0)
            elif ti - tk == 3 or tk - ti == 3:
                acc -= lam
            h[i][k] = h[k][i] = acc
    # H = VᵀV (V upper triangular), ū = V⁻ᵀ f
    v = [[0.0] * size for _ in range(size)]
    ubar = [0.0] * size
    for j in range(size):
        acc = h[j][j]
        for k in range(j):
            acc -= v[k][j] * v[k][j]
        d = math.sqrt(acc)
        v[j][j] = d
        for i in range(j + 1, size):
            acc = h[j][i]
            for k in range(j):
                acc -= v[k][j] * v[k][i]
            v[j][i] = acc / d
        acc = f[j]
        for k in range(j):
            acc -= v[k][j] * ubar[k]
        ubar[j] = acc / d
    constant = 0.0
    for r in range(2 * n):
        constant += e0[r] * e0[r]
    constant += lam * (prev[0] * prev[0] + prev[1] * prev[1] + prev[2] * prev[2])
    for j in range(size):
        constant -= ubar[j] * ubar[j]
    return v, ubar, constant


#: commutations between the switching states of codes a and b (S_a·4 + S_b·2 + S_c)
_HAMMING = tuple(tuple(bin(a ^ b).count("1") for b in range(8)) for a in range(8))
_STATES = tuple(((c >> 2) & 1, (c >> 1) & 1, c & 1) for c in range(8))


def smallest_of_equal_cost(
    sequence: tuple[int, ...], u_prev: tuple[int, int, int]
) -> tuple[int, ...]:
    """The tie rule made exact (docs/physics.md#long-horizons): of the sequences that apply the
    voltages of ``sequence`` (000 and 111 exchanged where it holds a zero vector) the one with
    the fewest commutations from ``u_prev``, the lexicographically smallest of those.

    Their currents are the same, so their costs differ by λ_u × commutations, integers: an
    exact tie where the counts are equal, which the decoder's distance (the same cost by
    another road, rounded otherwise for each) cannot tell apart. Backwards, the fewest
    commutations to the horizon's end from each choice; forwards, the first choice (000 before
    111) that keeps to them."""
    codes = [a * 4 + b * 2 + c for a, b, c in zip(sequence[::3], sequence[1::3], sequence[2::3])]
    if 0 not in codes and 7 not in codes:
        return sequence
    h = _HAMMING
    # per period its two choices (the same code twice where it holds an active vector) and the
    # fewest commutations after it for each
    choices = [(0, 7) if c == 0 or c == 7 else (c, c) for c in codes]
    to_go = [(0, 0)] * len(codes)
    for ell in range(len(codes) - 2, -1, -1):
        (na, nb), (ta, tb) = choices[ell + 1], to_go[ell + 1]
        a, b = choices[ell]
        to_go[ell] = (min(h[a][na] + ta, h[a][nb] + tb), min(h[b][na] + ta, h[b][nb] + tb))
    out: list[int] = []
    last = u_prev[0] * 4 + u_prev[1] * 2 + u_prev[2]
    for (a, b), (ta, tb) in zip(choices, to_go):
        last = a if h[last][a] + ta <= h[last][b] + tb else b
        out += _STATES[last]
    return tuple(out)


def solve(
    model: Model,
    n: int,
    state: Start,
    i_base: float,
    lam: float,
    prev: tuple[int, int, int],
    guess: tuple[int, ...],
    budget: int,
) -> SearchResult:
    """One decision: :func:`problem` decoded from ``guess`` (in U's order, or none) within
    ``budget`` nodes (0: no limit), its sequence in order of time and of the equal-cost ones
    the smallest (:func:`smallest_of_equal_cost`) — the reference the compiled kernel is held
    to."""
    v, ubar, _ = problem(model, n, state, i_base, lam, prev)
    found = sphere_decode(v, ubar, guess, budget=budget)
    return found._replace(sequence=smallest_of_equal_cost(found.sequence[::-1], prev))


class MPCController(Controller):
    """Direct model predictive current control of the PMSM: ``step(state k, reference k) ->
    command k``."""

    family = "mpc_pmsm"
    machine = Machine.PMSM
    params_type = MPCParams
    strategies = DIRECT_MPC_STRATEGIES
    horizon_strategies = HORIZON_STRATEGIES
    max_horizon = MAX_HORIZON

    def __init__(self, params: MPCParams, *, ts: float) -> None:
        m = params.motor
        self._coef = PMSMCoefficients.of(m)
        self._k_t = 1.5 * m.p * m.psi_f
        self._i_base = m.rated_torque / self._k_t  #: the rated current, A
        self.switches = (0, 0, 0)  #: the switch positions in force
        self.i_dq = 0j
        self.i_ref = 0j
        self._made = (0.0, 0.0)  #: (|T*|, I_s) of the last amplitude searched
        self.theta = 0.0
        self._nodes = 0
        self.est_torque = self.est_flux = self.est_flux_angle = 0.0
        self._solve = compiled(params.decoder, "decoder", compiled_direct_mpc) or solve
        self._complete = True
        self._rotor_motion = params.prediction == "rotor_motion"
        super().__init__(params, ts=ts)

    def _predict(self, state: State, u_ab: complex) -> State:
        return pmsm_predicted(self._coef, self.ts, state, u_ab, rotor_motion=self._rotor_motion)

    def _observe(self, state: State) -> None:
        c = self._coef
        i_dq = park(complex(state.i_alpha, state.i_beta), state.theta_e)
        self.i_dq = i_dq
        psi = complex(c.l_d * i_dq.real + c.psi_f, c.l_q * i_dq.imag)
        self.est_torque = c.torque_k * (psi.real * i_dq.imag - psi.imag * i_dq.real)
        self.est_flux = abs(psi)
        self.est_flux_angle = (state.theta_e + cmath.phase(psi)) % TWO_PI

    def _amplitude(self, torque: float) -> float:
        """The current amplitude that makes ``torque`` (N·m) at the MTPA angle, the reluctance
        torque counted (was |T*|/k_t: +2 to +3 % of torque on paper 001's IPMSM), searched
        only when T* changes."""
        if torque != self._made[0]:
            c = self._coef
            i_s = mtpa_current(
                torque, p=c.p, psi_f=c.psi_f, l_d=c.l_d, l_q=c.l_q, start=self._made[1]
            )
            self._made = (torque, i_s)
        return self._made[1]

    def _decide(self, state: State, ref: Reference) -> tuple[int, int, int]:
        c, law = self._coef, self.strategy
        sign = 1.0 if ref.torque_ref >= 0.0 else -1.0
        formula = self.params.mtpa == "formula"
        i_s = self._amplitude(abs(ref.torque_ref)) if formula else abs(ref.torque_ref) / self._k_t
        theta = formula_angle(i_s, c.psi_f, c.l_d, c.l_q) if formula else 0.0
        self.theta = theta
        self.i_ref = complex(-i_s * math.sin(theta), sign * i_s * math.cos(theta))
        ts, w_e, n = self.ts, c.p * state.omega_m, self.horizon
        model = period_model(
            c, ts, w_e, pmsm_exact_step(c, ts, w_e) if self._rotor_motion else None
        )
        i, r = self.i_dq, self.i_ref
        plan = law.plan
        # the last plan shifted, in U's order (time reversed)
        guess = (*plan[3:], *plan[-3:])[::-1] if len(plan) == 3 * n else ()
        found = self._solve(
            model, n, (i.real, i.imag, state.theta_e, w_e * ts, state.u_dc, r.real, r.imag),
            self._i_base, self.params.lambda_u, self.switches, guess, self.params.node_budget,
        )  # fmt: skip
        law.plan = found.sequence
        self._nodes = found.nodes
        self._complete = found.complete
        u = law.plan[:3]
        return (u[0], u[1], u[2])

    def _horizon_set(self) -> None:
        strategy = getattr(self, "strategy", None)
        if strategy is not None:
            strategy.plan = ()

    def _command(self, u: tuple[int, int, int], state: State, compute_ns: float) -> Command:
        self.switches = u
        pulses: PhasePulses = new_record(PhasePulses, (0.0, 0.0, 0.0, *map(float, u)))
        vector = state_to_vector(u) % 7  # 111 is the zero vector too
        diagnostics: tuple[Any, ...] = (
            float(vector),
            1.0,
            NAN,  # t_u
            float(self._nodes),
            self.law_horizon,
            self.est_torque,
            self.est_flux,
            self.est_flux_angle,
            self.theta,
            self.i_ref.real,
            self.i_ref.imag,
            NAN,  # mtpa_gradient
        )
        return self.command(state, pulses, diagnostics, compute_ns, 0.0 if self._complete else 1.0)
