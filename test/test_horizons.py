"""Long horizons (docs/physics.md#long-horizons): multi-step MPTC of both families decides as an
exhaustive enumeration of its cost written here independently (10,000 random states and
references for each N ≤ 3), the horizon is refused where it does not apply, and N = 1 is the
one-step law."""

from __future__ import annotations

import cmath
import dataclasses
import itertools
import math
import random

import numpy as np
import pytest

from predictive_drive.config import load_scenario
from predictive_drive.core.control import make_controller, make_strategy
from predictive_drive.core.control.base import SwitchingEffort
from predictive_drive.core.control.mptc_im import IMPrediction
from predictive_drive.core.control.mptc_pmsm import PMSMPrediction
from predictive_drive.core.inverter import (
    active_then_zero,
    clarke,
    segments,
    vector_voltages,
)
from predictive_drive.core.machines.induction import InductionCoefficients, induction_dynamics
from predictive_drive.core.machines.pmsm import PMSM, PMSMCoefficients, pmsm_predict_current
from predictive_drive.core.signals import Reference, State
from predictive_drive.errors import ConfigError

pytestmark = pytest.mark.core

TS = 5e-5
CASES = 10_000


def switching_tables():
    """By the switching state in force (0..7, S_a·4 + S_b·2 + S_c): each vector's leg
    commutations for the whole period and the state it leaves, from the plant's own segment
    count and the inverter's zero-vector rule — never from the controller's tables."""
    legs, after = [], []
    for c in range(8):
        prev = ((c >> 2) & 1, (c >> 1) & 1, c & 1)
        row_l, row_a = [], []
        for n in range(7):
            pulses, end = active_then_zero(n, 1.0, prev)
            row_l.append(segments(pulses, prev)[2] // 2)
            row_a.append(end[0] * 4 + end[1] * 2 + end[2])
        legs.append(row_l)
        after.append(row_a)
    return np.array(legs, dtype=float), np.array(after)


LEGS, AFTER = switching_tables()
#: the switching state of each code
STATE_OF = [((c >> 2) & 1, (c >> 1) & 1, c & 1) for c in range(8)]
SEQUENCES = {n: np.array(list(itertools.product(range(7), repeat=n))) for n in (1, 2, 3)}


def best_first(costs: np.ndarray, seqs: np.ndarray) -> set[int]:
    """The first vectors of the cheapest sequences: the lexicographically first minimum, and any
    other within the independent arithmetic's rounding (1e-9 relative) of it."""
    best = costs.min()
    close = costs <= best + 1e-9 * (1.0 + abs(best))
    return {int(seqs[i, 0]) for i in np.flatnonzero(close)}


def switching_cost(seqs: np.ndarray, code: int, lam_sw: float) -> np.ndarray:
    """λ_sw × commutations of each sequence, stage by stage (columns)."""
    out = np.zeros(seqs.shape, dtype=float)
    state = np.full(len(seqs), code)
    for ell in range(seqs.shape[1]):
        out[:, ell] = lam_sw * LEGS[state, seqs[:, ell]]
        state = AFTER[state, seqs[:, ell]]
    return out


@pytest.fixture(scope="module")
def im():
    sc = load_scenario("im_short")
    return InductionCoefficients.of(sc.controller.motor), sc.controller.lambda_psi


@pytest.mark.parametrize("horizon", [1, 2, 3])
def test_multistep_mptc_of_the_induction_motor_equals_exhaustive_enumeration(im, horizon):
    """Stage cost |T* - T| + λ_ψ |ψ* - |ψ|| + λ_sw × commutations, summed over N periods of the
    plant's own dynamics function stepped by forward Euler with ω frozen (the family's model,
    written here again), every one of the 7^N sequences: the controller's first vector is the
    first vector of the cheapest sequence (ties: the lexicographically smallest)."""
    coef, lam = im
    volts = np.array(vector_voltages(582.0))
    seqs = SEQUENCES[horizon]
    s = make_strategy("mptc_im", "mptc")
    rng = random.Random(horizon)
    for _ in range(CASES):
        psi = 0.71 * cmath.exp(1j * rng.uniform(-math.pi, math.pi)) * rng.uniform(0.95, 1.05)
        i = rng.uniform(0, 8) * cmath.exp(1j * rng.uniform(-math.pi, math.pi))
        w, t_ref = rng.uniform(-300, 300), rng.uniform(-7.5, 7.5)
        code, lam_sw = rng.randrange(8), rng.choice([0.0, 0.0, 0.05, 0.3])
        m = IMPrediction(coef, TS, lam, False, SwitchingEffort(lam_sw) if lam_sw else None)
        m.prepare(i, psi, w, tuple(volts))
        m.switching(STATE_OF[code])
        m.code = code  # the state in force whether or not an effort counts it
        m.horizon = horizon
        s.plan = ()
        got = s.decide(m, t_ref, 0.71).vector
        # the independent enumeration
        ii = np.full(len(seqs), i, dtype=complex)
        pp = np.full(len(seqs), psi, dtype=complex)
        cost = np.zeros(len(seqs))
        sw = switching_cost(seqs, code, lam_sw)
        for ell in range(horizon):
            di, dp, _, _ = induction_dynamics(
                0.0, (ii, pp, w, 0.0), (volts[seqs[:, ell]], 0.0), coef
            )
            ii, pp = ii + TS * di, pp + TS * dp
            te = 1.5 * coef.p * (pp.conj() * ii).imag
            cost = cost + (np.abs(t_ref - te) + lam * np.abs(0.71 - np.abs(pp)) + sw[:, ell])
        assert got in best_first(cost, seqs), (i, psi, w, t_ref, code, lam_sw)


def pmsm_costs(motor: PMSM, psi_ab, theta_e, w_e, t_ref, psi_ref, t_floor, seqs, sw, u_dc, end=0):
    """Each sequence's cost by eq 1-3 in vector form: ψ(ℓ+1) = ψ(ℓ) + V·Ts (R_s neglected), the
    rotor turning ω_e·Ts a period (frozen within it; ``end`` = 1: the torque at the period's
    end angle), torque from the flux in the rotor frame."""
    volts = np.array(vector_voltages(u_dc))
    psi = np.full(len(seqs), psi_ab, dtype=complex)
    norm_t = max(abs(t_ref), t_floor)
    cost = np.zeros(len(seqs))
    for ell in range(seqs.shape[1]):
        psi = psi + volts[seqs[:, ell]] * TS
        dq = psi * cmath.exp(-1j * (theta_e + (ell + end) * w_e * TS))
        i_d, i_q = (dq.real - motor.psi_f) / motor.l_d, dq.imag / motor.l_q
        te = 1.5 * motor.p * (motor.psi_f * i_q + (motor.l_d - motor.l_q) * i_d * i_q)
        e = np.hypot((te - t_ref) / norm_t, (np.abs(psi) - psi_ref) / psi_ref)
        cost = cost + (e + sw[:, ell])
    return cost


IPMSM = PMSM(0.25, 0.0033, 0.0073, 0.2264, 3, 0.001, 15.0, 1000.0)


@pytest.mark.parametrize("prediction", ["frozen_rotor", "rotor_motion"])
@pytest.mark.parametrize("horizon", [1, 2, 3])
def test_multistep_mptc_of_the_pmsm_equals_exhaustive_enumeration(horizon, prediction):
    c = PMSMCoefficients.of(IPMSM)
    seqs = SEQUENCES[horizon]
    s = make_strategy("mptc_pmsm", "mptc")
    rng = random.Random(10 + horizon)
    end = int(prediction == "rotor_motion")
    for _ in range(CASES if not end else CASES // 5):
        i = complex(rng.uniform(-8, 4), rng.uniform(-25, 25))
        theta = rng.uniform(0, 2 * math.pi)
        i_ab = i * cmath.exp(1j * theta)
        w_e, t_ref, psi_ref = rng.uniform(-400, 400), rng.uniform(-30, 30), rng.uniform(0.2, 0.3)
        code, lam_sw = rng.randrange(8), rng.choice([0.0, 0.0, 0.01, 0.05])
        m = PMSMPrediction(c, TS, 0.75, 0.15, SwitchingEffort(lam_sw) if lam_sw else None)
        m.rotor_motion = bool(end)
        m.prepare(i_ab.real, i_ab.imag, theta, 312.0, w_e)
        m.theta_e, m.w_e, m.volts, m.horizon = theta, w_e, vector_voltages(312.0), horizon
        m.switching(STATE_OF[code])
        s.plan = ()
        got = s.decide(m, t_ref, psi_ref).vector  # N = 1: the one-step law, eq 1-3 in polar form
        psi_ab = m.psi * cmath.exp(1j * m.theta_psi)
        sw = switching_cost(seqs, code, lam_sw)
        cost = pmsm_costs(IPMSM, psi_ab, theta, w_e, t_ref, psi_ref, 0.15, seqs, sw, 312.0, end)
        assert got in best_first(cost, seqs), (i, theta, w_e, t_ref, psi_ref, code, lam_sw)


def _with(scenario: str, **settings):
    sc = load_scenario(scenario)
    return dataclasses.replace(sc, controller=dataclasses.replace(sc.controller, **settings))


@pytest.mark.parametrize(
    ("scenario", "settings", "words"),
    [
        ("im_short", {"strategy": "mptc", "horizon": 0}, "horizon must be 1..6, got 0"),
        ("im_short", {"strategy": "mptc", "horizon": 7}, "horizon must be 1..6, got 7"),
        ("ipmsm_short", {"horizon": 2.5}, "horizon"),
        ("im_short", {"strategy": "db_mptc", "horizon": 3}, "db_mptc looks one period ahead"),
        ("ipmsm_short", {"strategy": "simplified2", "horizon": 2}, "simplified2 looks one"),
    ],
    ids=["zero", "above-max", "not-whole", "db_mptc", "simplified2"],
)
def test_a_horizon_is_refused_where_it_does_not_apply(scenario, settings, words):
    with pytest.raises(ConfigError, match=words):
        _with(scenario, **settings)


def test_a_live_switch_is_refused_with_the_reason_and_the_running_setting_stays():
    sc = _with("im_short", strategy="mptc", horizon=3)
    ctrl = make_controller(sc.family, sc.controller, ts=sc.ts)
    assert "db_mptc looks one period ahead" in ctrl.switch_refusal("strategy", "db_mptc")
    assert "horizon must be 1..6 (periods), got 9" in ctrl.switch_refusal("horizon", 9)
    assert "whole number of periods" in ctrl.switch_refusal("horizon", 2.0)
    with pytest.raises(ValueError, match="looks one period ahead"):
        ctrl.switch("strategy", "mptc_db")
    assert (ctrl.strategy.name, ctrl.horizon) == ("mptc", 3)
    ctrl.switch("horizon", 1)
    assert ctrl.switch_refusal("strategy", "db_mptc") is None
    ctrl.switch("strategy", "db_mptc")
    assert "db_mptc looks one period ahead" in ctrl.switch_refusal("horizon", 2)
    foc = load_scenario("ipmsm_mtpa_short")
    ctrl = make_controller(foc.family, foc.controller, ts=foc.ts)
    assert "has no horizon" in ctrl.switch_refusal("horizon", 2)


def test_a_run_switches_its_horizon_at_the_step_and_records_it(tmp_path):
    """--switch 0.01:horizon=3 in-process: the commands carry N = 1 before the step and 3 from
    it, report's spans say so, and the bag holds the parameter event a node would publish."""
    from predictive_drive.api.report import evaluate, strategies_of
    from predictive_drive.api.run import run
    from predictive_drive.readback import read_bag

    r = run("ipmsm_short", engine="inprocess", duration=0.02, out=tmp_path / "b",
            switches=[(0.01, "horizon=3")])  # fmt: skip
    tr, info = read_bag(r.bag)
    h = tr.col("command", "horizon")
    assert np.all(h[:200] == 1.0) and np.all(h[200:] == 3.0)
    assert tr.col("command", "cal")[200:].mean() > 7  # a tree searched, not 7 predictions
    spans = [(s.strategy, s.first, s.last) for s in strategies_of(evaluate(r.bag))]
    assert spans == [("mptc", 0, 199), ("mptc N=3", 200, 399)]
    changed = [p for _, e in info.events for p in e.changed]
    assert changed == [("horizon", 3)]


def test_switches_are_checked_in_order_before_anything_runs():
    from predictive_drive.api.run import switch_steps

    sc = load_scenario("im_short", strategy="mptc")
    assert switch_steps(sc, [(0.01, "horizon=3"), (0.02, "horizon=1"), (0.03, "db_mptc")]) == [
        (200, "horizon=3"), (400, "horizon=1"), (600, "db_mptc"),
    ]  # fmt: skip
    for switches, words in [
        ([(0.01, "db_mptc"), (0.02, "horizon=2")], "db_mptc looks one period ahead"),
        ([(0.01, "horizon=3"), (0.02, "mptc_db")], "mptc_db looks one period ahead"),
        ([(0.01, "horizon=x")], "horizon=N takes a whole number"),
        ([(0.01, "lambda_sw=1")], "a switch is a strategy's name or horizon=N"),
        ([(0.01, "horizon=1")], "1 is already the horizon then"),
    ]:
        with pytest.raises(ConfigError, match=words):
            switch_steps(sc, switches)


STATES8 = np.array([((c >> 2) & 1, (c >> 1) & 1, c & 1) for c in range(8)])
SWITCH_SEQUENCES = {n: np.array(list(itertools.product(range(8), repeat=n))) for n in (1, 2, 3)}


def direct_costs(motor, i_dq, theta, w_e, u_dc, i_ref, i_base, lam_u, prev, horizon, exact=None):
    """J of every switching sequence, simulated here step by step (complex dq arithmetic):
    Σ |(i* - i(ℓ+1))/I_b|² + λ_u ‖u(ℓ) - u(ℓ-1)‖²; the sequences (codes 0..7 per step). The
    model forward Euler in dq, the voltage at each period's middle angle; or ``exact`` (a
    PMSMStep): i(ℓ+1) = A·i + G·u + f, the voltage at each period's start angle."""
    seqs = SWITCH_SEQUENCES[horizon]
    a = cmath.exp(2j * math.pi / 3)
    u_ab = 2.0 / 3.0 * u_dc * (STATES8[:, 0] + a * STATES8[:, 1] + a * a * STATES8[:, 2])
    i = np.full(len(seqs), i_dq, dtype=complex)
    last = np.tile(np.asarray(prev), (len(seqs), 1))
    cost = np.zeros(len(seqs))
    for ell in range(horizon):
        code = seqs[:, ell]
        if exact is not None:
            x = exact
            u = u_ab[code] * cmath.exp(-1j * (theta + ell * w_e * TS))
            i_d = x.a11 * i.real + x.a12 * i.imag + x.g11 * u.real + x.g12 * u.imag + x.f_d
            i_q = x.a21 * i.real + x.a22 * i.imag + x.g21 * u.real + x.g22 * u.imag + x.f_q
        else:
            u = u_ab[code] * cmath.exp(-1j * (theta + (ell + 0.5) * w_e * TS))
            i_d = i.real + TS * (u.real - motor.r_s * i.real + w_e * motor.l_q * i.imag) / motor.l_d
            i_q = (
                i.imag
                + TS
                * (u.imag - motor.r_s * i.imag - w_e * (motor.l_d * i.real + motor.psi_f))
                / motor.l_q
            )
        i = i_d + 1j * i_q
        cost = cost + np.abs((i_ref - i) / i_base) ** 2
        cost = cost + lam_u * np.sum((STATES8[code] - last) ** 2, axis=1)
        last = STATES8[code]
    return seqs, cost


@pytest.mark.parametrize("prediction", ["frozen_rotor", "rotor_motion"])
@pytest.mark.parametrize("horizon", [1, 2, 3])
def test_direct_mpc_equals_exhaustive_enumeration(horizon, prediction):
    """The sphere decoder's first switch positions are the first of the cheapest of all 8^N
    sequences (10,000 random currents, angles, speeds, references, weights and switch states
    in force; 2,000 with the rotor's motion, the period's exact solution held to the plant's
    integrator in test_prediction.py); the compiled decoder, where numba is installed, decides
    the same, bit for bit."""
    from predictive_drive.core.control.kernels import compiled_sphere_decoder, kernel_unavailable
    from predictive_drive.core.control.mpc_pmsm import current_problem
    from predictive_drive.core.control.search import sphere_decode
    from predictive_drive.core.machines.pmsm import pmsm_exact_step

    compiled = compiled_sphere_decoder() if kernel_unavailable() is None else None
    c = PMSMCoefficients.of(IPMSM)
    i_base = 15.0 / (1.5 * 3 * 0.2264)
    rng = random.Random(20 + horizon)
    motion = prediction == "rotor_motion"
    for _ in range(CASES if not motion else CASES // 5):
        i = complex(rng.uniform(-10, 5), rng.uniform(-25, 25))
        ref = complex(rng.uniform(-10, 5), rng.uniform(-25, 25))
        theta, w_e = rng.uniform(0, 2 * math.pi), rng.uniform(-400, 400)
        lam_u, prev = rng.choice([0.001, 0.01, 0.1, 1.0]), tuple(STATES8[rng.randrange(8)])
        exact = pmsm_exact_step(c, TS, w_e) if motion else None
        problem = current_problem(
            c, ts=TS, i_dq=i, theta_e=theta, w_e=w_e, u_dc=312.0, i_ref=ref, i_base=i_base,
            lambda_u=lam_u, u_prev=prev, horizon=horizon, exact=exact,
        )  # fmt: skip
        found = sphere_decode(problem.v.tolist(), problem.ubar.tolist())
        seqs, cost = direct_costs(
            IPMSM, i, theta, w_e, 312.0, ref, i_base, lam_u, prev, horizon, exact
        )
        best = cost.min()
        near = np.flatnonzero(cost <= best + 1e-9 * (1.0 + best))
        firsts = {tuple(STATES8[seqs[j, 0]]) for j in near}
        assert problem.in_time(found.sequence)[:3] in firsts, (i, ref, theta, w_e, lam_u, prev)
        # the decoder's distance is the cost less the problem's constant
        assert found.cost + problem.constant == pytest.approx(best, rel=1e-7, abs=1e-9)
        if compiled is not None:
            assert compiled(problem.v, problem.ubar) == found


def _commutations(seq, prev):
    periods = [tuple(seq[i : i + 3]) for i in range(0, len(seq), 3)]
    return sum(sum(a != b for a, b in zip(x, y)) for x, y in zip([prev, *periods], periods))


def _same_voltages(seq):
    """Every sequence applying the voltages of ``seq``: 000 and 111 exchanged at its zeros."""
    periods = [tuple(seq[i : i + 3]) for i in range(0, len(seq), 3)]
    zero = ((0, 0, 0), (1, 1, 1))
    options = [zero if p in zero else (p,) for p in periods]
    return [sum(choice, ()) for choice in itertools.product(*options)]


def _pmsm_state(i_ab: complex, theta_e: float, omega_m: float) -> State:
    nan = math.nan
    values = dict.fromkeys(State._fields, nan)
    values.update(k=0.0, t=0.0, i_alpha=i_ab.real, i_beta=i_ab.imag, omega_m=omega_m,
                  theta_e=theta_e, u_dc=312.0)  # fmt: skip
    return State(**values)


@pytest.mark.parametrize(("horizon", "lam_u"), [(2, 1e-4), (3, 1e-4), (4, 0.01), (5, 0.01)])
def test_direct_mpc_breaks_exact_ties_to_the_smallest_sequence(horizon, lam_u):
    """Sequences that differ only in 000 against 111 give the same currents, so with equal
    commutation counts they cost exactly the same: the controller's plan is the smallest of
    them, every time (the decoder's distance, rounded differently for each, does not decide),
    and never one with more commutations than another of them. A closed loop of 600 periods on
    the controller's own model at 1000 r/min, T* = 15 N·m, where the zero vectors come often."""
    sc = load_scenario("ipmsm_steady_mpc")
    params = dataclasses.replace(sc.controller, horizon=horizon, lambda_u=lam_u)
    ctrl = make_controller("mpc_pmsm", params, ts=TS)
    c = PMSMCoefficients.of(params.motor)
    ref = Reference(0.0, 0.0, 15.0, 0.24, 0.0)
    i_ab, theta, w_m = 0j, 0.3, 1000 * math.pi / 30
    ties = 0
    for _ in range(600):
        prev = ctrl.switches
        cmd = ctrl.step(_pmsm_state(i_ab, theta % (2 * math.pi), w_m), ref)
        plan = ctrl.strategy.plan
        variants = _same_voltages(plan)
        fewest = min(_commutations(s, prev) for s in variants)
        tied = sorted(s for s in variants if _commutations(s, prev) == fewest)
        ties += len(tied) > 1
        assert plan == tied[0], (plan, tied)
        u_ab = 312.0 * clarke(cmd.duty_a, cmd.duty_b, cmd.duty_c)
        i_ab, theta = pmsm_predict_current(c, TS, i_ab, theta, w_m, u_ab)
    assert ties >= 5  # the rule was exercised


@pytest.mark.parametrize("horizon", [1, 2, 4, 7])
def test_compiled_direct_mpc_is_the_reference_bit_for_bit(horizon):
    """direct_mpc's decision compiled (kernels.compiled_direct_mpc: the problem and the
    decoder) against the reference (mpc_pmsm.solve: mpc_pmsm.problem in plain floats and
    search.sphere_decode), both predictions, with and without a guess (the shifted optimum),
    with budgets that stop it and one that does not: the same V and ū to the bit, the same
    sequence, distance, node count and completion."""
    kernels = pytest.importorskip("predictive_drive.core.control.kernels")
    if kernels.kernel_unavailable() is not None:
        pytest.skip(kernels.kernel_unavailable())
    from predictive_drive.core.control.mpc_pmsm import period_model, problem, solve
    from predictive_drive.core.machines.pmsm import pmsm_exact_step

    compiled, compiled_problem = kernels.compiled_direct_mpc(), kernels.compiled_problem()
    c = PMSMCoefficients.of(IPMSM)
    i_base = 15.0 / (1.5 * 3 * 0.2264)
    rng = random.Random(40 + horizon)
    stopped = 0
    for _ in range(150):
        w_e = rng.uniform(-400, 400)
        exact = pmsm_exact_step(c, TS, w_e) if rng.random() < 0.5 else None
        model = period_model(c, TS, w_e, exact)
        state = (rng.uniform(-10, 5), rng.uniform(-25, 25), rng.uniform(0, 2 * math.pi),
                 w_e * TS, 312.0, rng.uniform(-10, 5), rng.uniform(-25, 25))  # fmt: skip
        lam, prev = rng.choice([1e-4, 0.01, 0.1]), tuple(int(x) for x in STATES8[rng.randrange(8)])
        v, ubar, _ = problem(model, horizon, state, i_base, lam, prev)
        cv, cu = compiled_problem(model, horizon, state, i_base, lam, prev)
        assert np.array_equal(cv, np.array(v)) and np.array_equal(cu, np.array(ubar))
        first = solve(model, horizon, state, i_base, lam, prev, (), 0)
        shifted = first.sequence[3:] + first.sequence[:3]
        for guess in ((), shifted):
            for budget in (0, 3 * horizon + 2, 40):
                want = solve(model, horizon, state, i_base, lam, prev, guess, budget)
                got = compiled(model, horizon, state, i_base, lam, prev, guess, budget)
                assert got == want, (guess, budget)
                stopped += not want.complete
    assert stopped > 50 or horizon == 1  # the budgets were reached


def _im_prediction(rng, coef, lam, volts):
    psi = 0.71 * cmath.exp(1j * rng.uniform(-math.pi, math.pi)) * rng.uniform(0.95, 1.05)
    i = rng.uniform(0, 8) * cmath.exp(1j * rng.uniform(-math.pi, math.pi))
    lam_sw = rng.choice([0.0, 0.05, 0.3])
    m = IMPrediction(coef, TS, lam, False, SwitchingEffort(lam_sw) if lam_sw else None)
    m.prepare(i, psi, rng.uniform(-300, 300), volts)
    m.switching(STATE_OF[rng.randrange(8)])
    return m, rng.uniform(-7.5, 7.5), 0.71


def _pmsm_prediction(rng, c, volts):
    i_ab = complex(rng.uniform(-8, 4), rng.uniform(-25, 25)) * cmath.exp(1j * rng.uniform(0, 7))
    theta, w_e = rng.uniform(0, 2 * math.pi), rng.uniform(-400, 400)
    lam_sw = rng.choice([0.0, 0.01, 0.05])
    m = PMSMPrediction(c, TS, 0.75, 0.15, SwitchingEffort(lam_sw) if lam_sw else None)
    m.rotor_motion = rng.random() < 0.5
    m.prepare(i_ab.real, i_ab.imag, theta, 312.0, w_e)
    m.theta_e, m.w_e, m.volts = theta, w_e, volts
    m.switching(STATE_OF[rng.randrange(8)])
    return m, rng.uniform(-30, 30), rng.uniform(0.2, 0.3)


@pytest.mark.parametrize("horizon", [2, 3, 5])
@pytest.mark.parametrize("family", ["mptc_im", "mptc_pmsm"])
def test_compiled_branch_and_bound_is_the_reference_bit_for_bit(im, family, horizon):
    """mptc's branch and bound compiled (kernels.compiled_branch_and_bound, each family's
    stages) against search.branch_and_bound of the family's horizon_stages: the same plan,
    cost, node count and completion, from random states, with and without a guess and a
    switching effort, with budgets that stop it and none; the PMSM with both predictions."""
    kernels = pytest.importorskip("predictive_drive.core.control.kernels")
    if kernels.kernel_unavailable() is not None:
        pytest.skip(kernels.kernel_unavailable())
    compiled = kernels.compiled_branch_and_bound()
    s = make_strategy(family, "mptc")
    rng = random.Random(50 + horizon)
    stopped = 0
    for _ in range(200 if horizon < 5 else 40):
        if family == "mptc_im":
            m, t_ref, psi_ref = _im_prediction(rng, im[0], im[1], tuple(vector_voltages(582.0)))
        else:
            m, t_ref, psi_ref = _pmsm_prediction(
                rng, PMSMCoefficients.of(IPMSM), vector_voltages(312.0)
            )
        m.horizon = horizon
        plan = tuple(rng.randrange(7) for _ in range(horizon)) if rng.random() < 0.5 else ()
        for budget in (0, 7 * horizon + 7, 140):
            m.budget = budget
            out = []
            for search in (None, compiled):
                m.compiled = search
                s.plan = plan
                out.append((s.decide(m, t_ref, psi_ref), s.found))
            assert out[0] == out[1], budget
            stopped += not out[0][1].complete
    assert stopped > 20  # the budgets were reached


def test_a_budget_applies_the_best_so_far_and_report_counts_the_steps(tmp_path, capsys):
    """direct_mpc at N = 10 with node_budget 1,500: a step whose search ran out records
    suboptimal = 1 and exactly 1,500 nodes, the others 0 and at most that; report says
    "suboptimal steps: n of N" with the recording's count. Every decision is the decoder's own
    (held bit for bit by test_compiled_direct_mpc_is_the_reference_bit_for_bit)."""
    from predictive_drive.api.report import details_of, evaluate, report
    from predictive_drive.api.run import run
    from predictive_drive.cli.common import print_recording

    settings = {"torque_controller.horizon": 10, "torque_controller.node_budget": 1500}
    r = run("ipmsm_steady_mpc", engine="inprocess", duration=0.05, out=tmp_path / "b",
            settings=settings)  # fmt: skip
    ev = evaluate(r.bag)
    sub, cal = ev.trace.col("command", "suboptimal"), ev.trace.col("command", "cal")
    assert set(np.unique(sub)) == {0.0, 1.0} and (sub == 1.0).sum() > 20
    assert np.all(cal[sub == 1.0] == 1500) and np.all(cal[sub == 0.0] <= 1500)
    d = details_of(ev)
    assert (d.suboptimal_steps, d.searched_steps) == (int((sub == 1.0).sum()), len(sub))
    print_recording(report(r.bag))
    assert f"suboptimal steps: {d.suboptimal_steps} of {len(sub)}" in capsys.readouterr().out


def test_a_compiled_search_is_made_at_its_first_call_and_refused_without_numba(monkeypatch):
    """auto: the kernel where numba is installed, made when first called (a controller that
    never searches never imports numba), the reference where it is not; compiled without
    numba: ConfigError naming the key and the reason."""
    from predictive_drive.core.control import base

    made = []
    search = base.compiled("auto", "search", lambda: made.append(1) or (lambda *args: args))
    assert made == [] and search(1, 2) == (1, 2) and search(3) == (3,) and made == [1]
    assert base.compiled("python", "search", lambda: made.append(2)) is None
    monkeypatch.setattr(base, "kernel_unavailable", lambda: "numba is not installed")
    assert base.compiled("auto", "decoder", lambda: made.append(3)) is None
    with pytest.raises(ConfigError, match="torque_controller.decoder: compiled, but numba"):
        base.compiled("compiled", "decoder", lambda: made.append(4))
    assert made == [1]
