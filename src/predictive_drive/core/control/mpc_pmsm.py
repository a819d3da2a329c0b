"""Direct model predictive current control of the PMSM with sphere decoding — the controller
family ``mpc_pmsm``, strategy ``direct_mpc`` (docs/physics.md#long-horizons; T. Geyer, D. E.
Quevedo, "Multistep finite control set model predictive control for power electronics", IEEE
TPEL 29(12), 2014).

A family of its own: its law chooses the inverter's switch positions directly over a horizon of
N periods (no modulator), where field-oriented control's laws choose a current angle for a PI
loop and SVPWM. It takes its current references as ``foc_pmsm`` does — the speed PI's T* as an
amplitude I_s = |T*|/k_t, the MTPA angle of paper 002 eq 10 (or i_d = 0) — and minimises

    J = Σ_{ℓ=0}^{N-1} ‖(i* - i(ℓ+1))/I_b‖² + λ_u ‖u(ℓ) - u(ℓ-1)‖²

over the switch positions u(ℓ) ∈ {0, 1}³ of the three legs (000 and 111 apart: ‖Δu‖² counts
commutations), I_b the rated current (rated torque / k_t): J is per unit. The model is the
family's own: the dq currents stepped by forward Euler at the speed of the sample, the rotor
turning ω_e·Ts a period, each period's voltage turned into dq at its middle (``prediction:
rotor_motion``: each period solved exactly at that speed,
docs/physics.md#predicting-the-pmsm-over-a-period) — linear,
i(ℓ+1) = A i(ℓ) + B_ℓ u(ℓ) + c — so J is, up to a constant, (U - U_unc)ᵀ H (U - U_unc) with
H = ΥᵀΥ + λ_u SᵀS over the stacked U. With H = VᵀV (V upper triangular, from the Cholesky
factor) it is the integer least-squares problem min ‖V·U_unc - V·U‖², solved exactly by
:func:`~.search.sphere_decode`, the last optimum shifted as its first radius. Of the sequences
that apply the optimum's voltages (000 and 111 exchanged), the fewest commutations and then the
lexicographically smallest is taken (:func:`smallest_of_equal_cost`: exact ties, which the
decoder's rounded distance cannot order). The first three components are applied for the whole
period; ``cal`` is the decoder's node count.
"""

from __future__ import annotations

import cmath
import math
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cache
from typing import Any

import numpy as np

from ...errors import ConfigError
from ..fields import check_fields, choice, quantity
from ..inverter import park, state_to_vector
from ..machines import Machine
from ..machines.pmsm import PMSM, PMSMCoefficients, PMSMStep, pmsm_exact_step
from ..signals import Command, PhasePulses, Reference, State, new_record
from .base import (
    Controller,
    check_horizon,
    delay_compensation,
    horizon_field,
    pmsm_predicted,
    prediction_field,
)
from .kernels import compiled_sphere_decoder, kernel_unavailable
from .mtpa import formula_angle
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
#: which sphere decoder runs (:mod:`.kernels`)
DECODERS = ("auto", "compiled", "python")
#: (S_a, S_b, S_c) → u_αβ per volt of U_dc: (2/3)(S_a + a S_b + a² S_c), as two real rows
_LEGS = np.array(
    [[2.0 / 3.0, -1.0 / 3.0, -1.0 / 3.0], [0.0, 1.0 / math.sqrt(3.0), -1.0 / math.sqrt(3.0)]]
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
    decoder: str = choice(
        "the sphere decoder: compiled (numba), python (the reference), or auto (compiled where "
        "numba is installed); every one decides the same, bit for bit", DECODERS,
        default="auto",
    )  # fmt: skip
    prediction: str = prediction_field()
    delay_compensation: bool = delay_compensation()

    def __post_init__(self) -> None:
        check_fields(self)
        check_horizon(self, HORIZON_STRATEGIES)


@dataclass(frozen=True)
class QuadraticProblem:
    """One decision's integer least-squares problem (see the module's text): V (upper
    triangular) and ū = V·U_unc, and the constant the cost differs from ‖ū - V·U‖² by."""

    v: np.ndarray
    ubar: np.ndarray
    constant: float


@cache
def _structure(n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What a horizon of n periods fixes: for block (ℓ, m) of Υ the power ℓ - m of A it takes
    (clipped), the block's input m and whether it is below the diagonal; S (the differences of
    the stacked inputs) and SᵀS."""
    lag = np.arange(n)[:, None] - np.arange(n)[None, :]
    m = np.broadcast_to(np.arange(n)[None, :], (n, n))
    s = np.eye(3 * n) - np.eye(3 * n, k=-3)
    return np.clip(lag, 0, None), m, (lag >= 0)[..., None, None], s, s.T @ s


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
    n = horizon
    lag, cols, below, s, sts = _structure(n)
    # A = I + Ts·F (forward Euler, ω frozen) and c, as plain floats: n powers and the free
    # response are n small products, cheaper in Python than in numpy calls
    if exact is None:
        a11, a12 = 1.0 - ts * c.r_s * c.inv_l_d, ts * w_e * c.l_q * c.inv_l_d
        a21, a22 = -ts * w_e * c.l_d * c.inv_l_q, 1.0 - ts * c.r_s * c.inv_l_q
        cd, cq = 0.0, -ts * w_e * c.psi_f * c.inv_l_q
    else:
        a11, a12, a21, a22, *_, cd, cq = exact
    powers = [(1.0, 0.0, 0.0, 1.0)]
    free: list[float] = []
    x, y = i_dq.real, i_dq.imag
    for _ in range(n):
        p11, p12, p21, p22 = powers[-1]
        powers.append(
            (
                a11 * p11 + a12 * p21,
                a11 * p12 + a12 * p22,
                a21 * p11 + a22 * p21,
                a21 * p12 + a22 * p22,
            )
        )
        x, y = a11 * x + a12 * y + cd, a21 * x + a22 * y + cq
        free += (x, y)
    pw = np.array(powers[:n]).reshape(n, 2, 2)
    l0, l1 = _LEGS
    if exact is None:
        # B_ℓ = Ts·diag(1/L_d, 1/L_q)·Park(θ at the period's middle)·U_dc·legs
        mid = theta_e + (np.arange(n) + 0.5) * (w_e * ts)
        co, si = np.cos(mid)[:, None], np.sin(mid)[:, None]
        gd, gq = ts * u_dc * c.inv_l_d, ts * u_dc * c.inv_l_q
        b = np.stack([gd * (co * l0 + si * l1), gq * (co * l1 - si * l0)], 1)  # (n, 2, 3)
    else:
        # B_ℓ = G·Park(θ at the period's start)·U_dc·legs
        start = theta_e + np.arange(n) * (w_e * ts)
        co, si = np.cos(start)[:, None], np.sin(start)[:, None]
        ud, uq = u_dc * (co * l0 + si * l1), u_dc * (co * l1 - si * l0)
        g = exact
        b = np.stack([g.g11 * ud + g.g12 * uq, g.g21 * ud + g.g22 * uq], 1)
    blocks = (pw[:, None] @ b[None])[lag, cols] * below  # block (ℓ, m) = A^{ℓ-m} B_m
    ups = blocks.transpose(0, 2, 1, 3).reshape(2 * n, 3 * n) / i_base
    e0 = (np.tile([i_ref.real, i_ref.imag], n) - np.array(free)) / i_base
    prev = np.zeros(3 * n)
    prev[:3] = u_prev
    h = ups.T @ ups + lambda_u * sts
    f = ups.T @ e0 + lambda_u * (s.T @ prev)
    v = np.linalg.cholesky(h).T
    u_unc = np.linalg.solve(h, f)
    constant = float(e0 @ e0 + lambda_u * (prev @ prev) - f @ u_unc)
    return QuadraticProblem(v, v @ u_unc, constant)


#: the two zero vectors: the same voltage, so the same currents
_ZEROS = ((0, 0, 0), (1, 1, 1))


def _commutations(a: tuple[int, ...], b: tuple[int, ...]) -> int:
    return (a[0] != b[0]) + (a[1] != b[1]) + (a[2] != b[2])


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
    periods = [sequence[i : i + 3] for i in range(0, len(sequence), 3)]
    options = [_ZEROS if p in _ZEROS else (p,) for p in periods]
    if all(len(o) == 1 for o in options):
        return sequence
    to_go: list[dict[tuple[int, ...], int]] = [{} for _ in periods]
    to_go[-1] = {x: 0 for x in options[-1]}
    for ell in range(len(periods) - 2, -1, -1):
        after = to_go[ell + 1]
        to_go[ell] = {
            x: min(_commutations(x, y) + n for y, n in after.items()) for x in options[ell]
        }
    out: list[int] = []
    last: tuple[int, ...] = u_prev
    for ell, choices in enumerate(options):
        costs = [_commutations(last, x) + to_go[ell][x] for x in choices]
        last = choices[costs.index(min(costs))]
        out += last
    return tuple(out)


def _decoder(name: str) -> Any:
    """The sphere decoder ``name`` asks for (:data:`DECODERS`); ConfigError for ``compiled``
    where numba is missing."""
    if name != "python":
        reason = kernel_unavailable()
        if reason is None:
            return compiled_sphere_decoder()
        if name == "compiled":
            raise ConfigError(f"torque_controller.decoder: compiled, but {reason}")

    def reference(v: Any, ubar: Any, guess: tuple[int, ...]) -> SearchResult:
        return sphere_decode(v.tolist(), ubar.tolist(), guess)

    return reference


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
        self.theta = 0.0
        self._nodes = 0
        self.est_torque = self.est_flux = self.est_flux_angle = 0.0
        self._decode = _decoder(params.decoder)
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

    def _decide(self, state: State, ref: Reference) -> tuple[int, int, int]:
        c, law = self._coef, self.strategy
        i_s = abs(ref.torque_ref) / self._k_t
        sign = 1.0 if ref.torque_ref >= 0.0 else -1.0
        formula = self.params.mtpa == "formula"
        theta = formula_angle(i_s, c.psi_f, c.l_d, c.l_q) if formula else 0.0
        self.theta = theta
        self.i_ref = complex(-i_s * math.sin(theta), sign * i_s * math.cos(theta))
        w_e = c.p * state.omega_m
        problem = current_problem(
            c,
            ts=self.ts,
            i_dq=self.i_dq,
            theta_e=state.theta_e,
            w_e=w_e,
            u_dc=state.u_dc,
            i_ref=self.i_ref,
            i_base=self._i_base,
            lambda_u=self.params.lambda_u,
            u_prev=self.switches,
            horizon=self.horizon,
            exact=pmsm_exact_step(c, self.ts, w_e) if self._rotor_motion else None,
        )
        plan = law.plan
        guess = (*plan[3:], *plan[-3:]) if len(plan) == 3 * self.horizon else ()
        found = self._decode(problem.v, problem.ubar, guess)
        law.plan = smallest_of_equal_cost(found.sequence, self.switches)
        self._nodes = found.nodes
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
        return self.command(state, pulses, diagnostics, compute_ns)
