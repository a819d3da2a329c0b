"""Strategies against exhaustive search, deadbeat landing, soft start, speed PI (docs/physics.md)."""

import cmath
import math
import random

import numpy as np
import pytest

from predictive_drive.core.control import InductionController, make_strategy, strategy_names
from predictive_drive.core.control.base import SwitchingEffort
from predictive_drive.core.control.mptc_im import IMPrediction
from predictive_drive.core.control.speed_pi import SpeedPI, SpeedPIParams
from predictive_drive.core.inverter import (
    VECTOR_STATES,
    active_then_zero,
    segments,
    vector_voltages,
)
from predictive_drive.core.machines.induction import (
    InductionCoefficients,
    induction_dynamics,
    induction_rk4,
    induction_torque,
)
from predictive_drive.core.signals import Reference, State

pytestmark = pytest.mark.core

TS = 5e-5
LAM = 17.5


def random_states(n, seed=1):
    rng = random.Random(seed)
    for _ in range(n):
        psi = 0.71 * cmath.exp(1j * rng.uniform(-math.pi, math.pi)) * rng.uniform(0.97, 1.03)
        i = rng.uniform(1, 6) * cmath.exp(1j * rng.uniform(-math.pi, math.pi))
        yield i, psi, rng.uniform(-300, 300), rng.uniform(-7.5, 7.5)


def exhaustive(coef, i, psi, w, t_ref, candidates):
    """Independent brute force: one forward-Euler step of the plant's own dynamics function
    (paper 000 eq 1; what the controller's prediction is specified to be) for each candidate (vector,
    time it is applied: the voltage averaged over Ts), scored with the cost of paper 000 eq 8; first
    strict minimum in V0..V6 order."""
    best, best_n = math.inf, None
    for n, u, t_u in candidates:
        di, dpsi, _, _ = induction_dynamics(0.0, (i, psi, w, 0.0), (u * t_u / TS, 0.0), coef)
        i1, p1 = i + TS * di, psi + TS * dpsi
        t1 = induction_torque(p1, i1, coef.torque_k)
        g = abs(t_ref - t1) + LAM * abs(0.71 - abs(p1))
        if g < best:
            best, best_n = g, n
    return best_n


def torque_rate(coef, i, psi, w, v):
    """dT_e/dt with voltage v applied, by central differences of the torque along the
    dynamics (never the controller's a_u, a_0)."""
    h = 1e-7
    f = induction_dynamics(0.0, (i, psi, w, 0.0), (v, 0.0), coef)
    ahead = induction_torque(psi + h * f[1], i + h * f[0], coef.torque_k)
    back = induction_torque(psi - h * f[1], i - h * f[0], coef.torque_k)
    return (ahead - back) / (2 * h)


def deadbeat_time(coef, i, psi, w, u, t_ref):
    """t_u of paper 000 eq 9-13 from the model alone: the torque moves linearly over Ts, so
    T(k+1) = T + Ts·dT0 + t_u·(dT_u - dT0) = T* gives t_u."""
    t_now = induction_torque(psi, i, coef.torque_k)
    d0 = torque_rate(coef, i, psi, w, 0j)
    return (t_ref - t_now - TS * d0) / (torque_rate(coef, i, psi, w, u) - d0)


@pytest.fixture(scope="module")
def coef(im_short):
    return InductionCoefficients.of(im_short.controller.motor)


def test_mptc_equals_exhaustive_search(coef):
    volts = vector_voltages(582.0)
    s = make_strategy("mptc_im", "mptc")
    for i, psi, w, t_ref in random_states(300):
        m = IMPrediction(coef, TS, LAM, False)
        m.prepare(i, psi, w, volts)
        d = s.decide(m, t_ref, 0.71)
        want = exhaustive(coef, i, psi, w, t_ref, [(n, volts[n], TS) for n in range(7)])
        assert d.vector == want and d.fraction == 1.0 and d.cal == 7


def test_db_mptc_equals_exhaustive_search_over_scaled_vectors(coef):
    """DB-MPTC (paper 000 eq 9-16) against a brute force built from the plant's dynamics alone:
    each vector's deadbeat time from finite differences of the torque along the dynamics (never
    the controller's a_u, a_0), the torque and flux at k+1 moving linearly over Ts (eq 16), the
    cost of eq 8 over V0 and the vectors with t_u >= 0 (clamped to Ts). Where the brute force's
    best two costs lie closer than its own numerical error (1e-6), either pick is right."""
    volts = vector_voltages(582.0)
    s = make_strategy("mptc_im", "db_mptc")
    checked = 0
    for i, psi, w, t_ref in random_states(300, seed=2):
        m = IMPrediction(coef, TS, LAM, False)
        m.prepare(i, psi, w, volts)
        d = s.decide(m, t_ref, 0.71)
        dpsi0 = induction_dynamics(0.0, (i, psi, w, 0.0), (0j, 0.0), coef)[1]
        costs, ats = {}, {}
        for n in range(7):
            t_u = 0.0 if n == 0 else deadbeat_time(coef, i, psi, w, volts[n], t_ref)
            if t_u < 0:
                continue
            t_u = min(t_u, TS)
            dpsi = induction_dynamics(0.0, (i, psi, w, 0.0), (volts[n], 0.0), coef)[1]
            t1 = _torque_after(coef, i, psi, w, volts[n], t_u)
            p1 = psi + TS * dpsi0 + t_u * (dpsi - dpsi0)
            costs[n] = abs(t_ref - t1) + LAM * abs(0.71 - abs(p1))
            ats[n] = t_u
        ranked = sorted(costs, key=lambda n: (costs[n], n))
        want = ranked[0]
        assert d.cal == len(costs)
        if len(ranked) > 1 and costs[ranked[1]] - costs[want] < 1e-6:
            assert d.vector in ranked[:2]
            continue
        assert d.vector == want
        assert d.fraction == (pytest.approx(ats[want] / TS, rel=1e-5) if want else 1.0)
        checked += 1
    assert checked > 290


def _torque_after(coef, i, psi, w, u, t_u):
    """T(k+1) when u is applied for t_u and the zero vector for the rest: the torque's rates
    held over the period (eq 16)."""
    d0 = torque_rate(coef, i, psi, w, 0j)
    du = torque_rate(coef, i, psi, w, u)
    return induction_torque(psi, i, coef.torque_k) + TS * d0 + t_u * (du - d0)


def test_mptc_db_keeps_mptc_vector_and_clamps_duty(coef):
    """The MPTC vector, applied for the deadbeat time the model gives (derived here by finite
    differences of the dynamics, not by the controller's a_u, a_0), clamped to [0, Ts]."""
    volts = vector_voltages(582.0)
    mptc = make_strategy("mptc_im", "mptc")
    mdb = make_strategy("mptc_im", "mptc_db")
    cases = {"inside": 0, "below": 0, "above": 0}
    for n, (i, psi, w, t_far) in enumerate(random_states(400, seed=3)):
        # references near the present torque too, so every clamping case occurs
        near = induction_torque(psi, i, coef.torque_k) + (-0.3, -0.05, 0.05, 0.3)[n % 4]
        t_ref = t_far if n % 5 == 0 else near
        m = IMPrediction(coef, TS, LAM, False)
        m.prepare(i, psi, w, volts)
        a, b = mptc.decide(m, t_ref, 0.71), mdb.decide(m, t_ref, 0.71)
        assert a.vector == b.vector
        if not b.vector:
            assert b.fraction == 1.0  # the zero vector all period, no deadbeat time
            continue
        t_u = deadbeat_time(coef, i, psi, w, volts[b.vector], t_ref)
        assert b.t_u == pytest.approx(t_u, rel=1e-5)
        if t_u < 0:
            cases["below"] += 1
            assert b.fraction == 0.0
        elif t_u > TS:
            cases["above"] += 1
            assert b.fraction == 1.0
        else:
            cases["inside"] += 1
            assert b.fraction == pytest.approx(t_u / TS, rel=1e-5)
    assert all(n > 5 for n in cases.values()), cases


def test_deadbeat_duty_lands_on_the_reference_on_the_nominal_model(coef):
    """Apply the deadbeat time on the continuous model: T_e(k+1) lands on T* up to the
    second-order error of the linearisation (here < 3 % of the requested change)."""
    volts = vector_voltages(582.0)
    checked = 0
    for i, psi, w, _ in random_states(200, seed=4):
        m = IMPrediction(coef, TS, LAM, False)
        m.prepare(i, psi, w, volts)
        t_ref = m.te + 0.5  # ask for +0.5 N·m within one period
        for n in range(1, 7):
            t_u = m.deadbeat_time(volts[n], t_ref)
            if not (0 < t_u < TS):
                continue
            frozen = coef._replace(inv_j=0.0)
            x = induction_rk4(0.0, (i, psi, w, 0.0), (volts[n], 0.0), frozen, t_u, 1)
            x = induction_rk4(t_u, x, (0j, 0.0), frozen, TS - t_u, 1)
            t1 = induction_torque(x[1], x[0], coef.torque_k)
            assert abs(t1 - t_ref) < 0.03 * 0.5
            checked += 1
    assert checked > 100


def test_first_strict_minimum_breaks_ties_in_vector_order(coef):
    """Two identical candidates: V0 (000) must win over later ties. With U_dc = 0 V every vector
    predicts the same, so the first (V0) is chosen."""
    m = IMPrediction(coef, TS, LAM, False)
    m.prepare(1 + 1j, 0.7 + 0j, 100.0, vector_voltages(0.0))
    assert make_strategy("mptc_im", "mptc").decide(m, 1.0, 0.71).vector == 0


def test_unknown_strategy_lists_the_valid_ones():
    with pytest.raises(ValueError, match="valid: mptc, mptc_db, db_mptc"):
        make_strategy("mptc_im", "dtc")
    assert strategy_names("mptc_im") == ("mptc", "mptc_db", "db_mptc")


def _state(k, i=0j, w=0.0):
    sampled = (float(k), k * TS, i.real, i.imag, w, 0.0, 582.0, 0, 0, 0, 0, 0, 0)
    truth = (i.real, i.imag, w, 0.0)
    rest = len(State._fields) - len(sampled) - len(truth)
    return State(*sampled, *truth, *(0.0,) * rest)  # the controller reads no mean, no loss


def test_soft_start_is_latched_off_once_flux_reaches_threshold(im_short):
    ctrl = InductionController(im_short.controller, ts=TS)
    ref = Reference(0, 0, 7.5, 0.71, 0)
    assert ctrl.step(_state(0, 0j), ref).vector == 1  # low current: V1
    assert ctrl.step(_state(1, 7 + 0j), ref).vector == 0  # high current: V0
    ctrl.psi_hat = 0.66 + 0j
    ctrl.step(_state(2, 1 + 0j), ref)
    assert not ctrl.soft_start
    ctrl.psi_hat = 0.3 + 0j  # flux sags later (braking at low speed): no re-trigger
    ctrl.step(_state(3, 1 + 0j), ref)
    assert not ctrl.soft_start


def test_flux_estimator_integrates_applied_voltage(im_short):
    ctrl = InductionController(im_short.controller, ts=TS)
    ctrl.soft_start = False
    i = 2 + 1j
    cmd = ctrl.step(_state(0, i), Reference(0, 0, 1.0, 0.71, 0))
    u = cmd.duty * vector_voltages(582.0)[int(cmd.vector)]
    assert ctrl.psi_hat == pytest.approx(TS * (u - im_short.controller.motor.r_s * i))


def pi_params(**kw):
    base = dict(
        kp=0.5,
        ki=10.0,
        torque_limit=2.0,
        flux_ref=0.71,
        speed_times=(0.0,),
        speed_values_rpm=(60 / (2 * math.pi) * 10.0,),
    )  # 10 rad/s
    base.update(kw)
    return SpeedPIParams(**base)


def test_speed_pi_linear_region_matches_closed_form():
    pi = SpeedPI(pi_params(kp=0.01, ki=1.0), ts=TS)
    refs = [pi.step(_state(k, w=9.9)) for k in range(100)]
    e = 10.0 - 9.9
    # T*(k) = Kp e + Ki Ts e k
    for k, r in enumerate(refs):
        assert r.torque_ref == pytest.approx(0.01 * e + 1.0 * TS * e * k, rel=1e-9)
        assert r.k == k + 1


def test_speed_pi_clamping_anti_windup_holds_integrator():
    pi = SpeedPI(pi_params(), ts=TS)
    for k in range(1000):  # e = 10 rad/s → Kp e = 5 > limit: saturated high
        r = pi.step(_state(k, w=0.0))
        assert r.torque_ref == 2.0
    assert pi.integral == 0.0
    # error reverses: integrator integrates again at once (no wind-up to unwind)
    r = pi.step(_state(1000, w=10.5))
    assert r.torque_ref == pytest.approx(0.5 * -0.5)


@pytest.mark.core
def test_the_immediate_speed_loop_applies_t_star_at_the_step_of_its_state(tmp_path):
    """one_step (default): reference k+1 is the PI's answer to state k, reference 0 the initial
    T* = 0. immediate: reference k is the answer to state k itself: the same PI, one step earlier
    (its first T* is the proportional kick of the first speed error, not 0)."""
    from predictive_drive.config import load_scenario, scenario_with
    from predictive_drive.core.control.speed_pi import SpeedPI
    from predictive_drive.core.runner import run_inprocess
    from predictive_drive.core.signals import State

    base = load_scenario("im_short", duration=0.01)
    fast = load_scenario(
        scenario_with("im_short", {"speed_pi.speed_loop": "immediate"}, tmp_path), duration=0.01
    )
    assert (base.speed_pi.speed_loop, fast.speed_pi.speed_loop) == ("one_step", "immediate")
    for sc, lag in ((base, 1), (fast, 0)):
        tr = run_inprocess(sc)
        pi = SpeedPI(sc.speed_pi, ts=sc.ts)
        refs = tr.reference
        if lag:
            np.testing.assert_array_equal(refs[0], pi.initial())
        for k in range(tr.steps):  # the PI fed the recorded states gives the recorded references
            ref = pi.step(State(*tr.state[k]))
            np.testing.assert_array_equal(ref, refs[k + lag])
        assert refs[0][2] == (0.0 if lag else pytest.approx(min(
            sc.speed_pi.torque_limit, sc.speed_pi.kp * 800 * 2 * np.pi / 60)))  # fmt: skip


def test_the_printed_a0_is_used_only_when_the_scenario_asks_for_it(im_short):
    """`torque_controller.a0_form: paper_printed` reaches the deadbeat strategies (their commands
    change), not conventional MPTC (it never uses a_0); a value outside derived/paper_printed is
    refused naming the key."""
    from predictive_drive.config import apply_settings, load_scenario_text, resolve_scenario_path
    from predictive_drive.core.runner import run_inprocess
    from predictive_drive.errors import ConfigError

    path = resolve_scenario_path("im_short")

    def commands(strategy, form):
        text = apply_settings(path.read_text(), {"torque_controller.a0_form": form}, path)
        sc = load_scenario_text(text, path).with_strategy(strategy)
        return run_inprocess(sc).command[:, :-1]  # compute_ns aside

    for strategy in ("mptc_db", "db_mptc"):
        derived, printed = commands(strategy, "derived"), commands(strategy, "paper_printed")
        assert not np.array_equal(derived, printed, equal_nan=True)
    np.testing.assert_array_equal(commands("mptc", "derived"), commands("mptc", "paper_printed"))
    with pytest.raises(ConfigError, match=r"a0_form.*derived, paper_printed"):
        commands("mptc", "printed")


def commutations(vector, fraction, prev):
    """Leg commutations of ``vector`` for ``fraction`` of Ts then the zero vector, counted from
    switching state ``prev`` by the plant's own segment count (two device transitions per leg
    change), never by the controller's tables."""
    pulses, _ = active_then_zero(vector, fraction, prev)
    return segments(pulses, prev)[2] // 2


PREVIOUS = [VECTOR_STATES[n] for n in range(8)]


@pytest.mark.parametrize("lam_sw", [0.05, 0.4, 3.0])
@pytest.mark.parametrize("name", ["mptc", "mptc_db", "db_mptc"])
def test_switching_effort_equals_exhaustive_search(coef, name, lam_sw):
    """Each IM strategy with λ_sw against a brute force of the documented cost
    (docs/physics.md#switching-effort): paper 000's cost of each candidate (mptc and mptc_db:
    the full-period prediction; db_mptc: the scaled vector) plus λ_sw × the commutations the
    candidate causes as it would be applied from the state in force — mptc_db's and db_mptc's
    duty returning to the zero vector within the period — counted by the plant. Near-ties of
    the brute force's finite differences (1e-6) and duties within 1e-5 of 0 or 1 accept either."""
    volts = vector_voltages(582.0)
    s = make_strategy("mptc_im", name)
    rng = random.Random(7)
    checked = 0
    for i, psi, w, t_ref in random_states(300, seed=4):
        prev = rng.choice(PREVIOUS)
        m = IMPrediction(coef, TS, LAM, False, SwitchingEffort(lam_sw))
        m.prepare(i, psi, w, volts)
        m.switching(prev)
        d = s.decide(m, t_ref, 0.71)
        dpsi0 = induction_dynamics(0.0, (i, psi, w, 0.0), (0j, 0.0), coef)[1]
        costs, edge = {}, False
        for n in range(7):
            t_u = TS if n == 0 else deadbeat_time(coef, i, psi, w, volts[n], t_ref)
            if name == "db_mptc" and t_u < 0:
                continue
            frac = 1.0 if name == "mptc" else min(max(t_u / TS, 0.0), 1.0)
            raw = t_u / TS
            edge |= n > 0 and name != "mptc" and min(abs(raw), abs(1.0 - raw)) < 1e-5
            if name == "db_mptc":
                dpsi = induction_dynamics(0.0, (i, psi, w, 0.0), (volts[n], 0.0), coef)[1]
                t1 = _torque_after(coef, i, psi, w, volts[n], frac * TS)
                p1 = psi + TS * dpsi0 + frac * TS * (dpsi - dpsi0)
            else:
                di, dpsi, _, _ = induction_dynamics(0.0, (i, psi, w, 0.0), (volts[n], 0.0), coef)
                i1, p1 = i + TS * di, psi + TS * dpsi
                t1 = induction_torque(p1, i1, coef.torque_k)
            g = abs(t_ref - t1) + LAM * abs(0.71 - abs(p1))
            costs[n] = g + lam_sw * commutations(n, frac, prev)
        ranked = sorted(costs, key=lambda n: (costs[n], n))
        if edge or (len(ranked) > 1 and costs[ranked[1]] - costs[ranked[0]] < 1e-6):
            assert d.vector in ranked[:2] or edge
            continue
        assert d.vector == ranked[0], (prev, costs)
        checked += 1
    assert checked > 200


@pytest.mark.parametrize("name", ["mptc", "mptc_db", "db_mptc"])
def test_no_switching_effort_is_the_law_without_it(coef, name):
    """λ_sw = 0 through the effort's own code path decides exactly as the law without it."""
    volts = vector_voltages(582.0)
    s = make_strategy("mptc_im", name)
    for i, psi, w, t_ref in random_states(200, seed=5):
        plain = IMPrediction(coef, TS, LAM, False)
        zero = IMPrediction(coef, TS, LAM, False, SwitchingEffort(0.0))
        for m in (plain, zero):
            m.prepare(i, psi, w, volts)
        zero.switching((1, 0, 1))
        a, b = s.decide(plain, t_ref, 0.71), s.decide(zero, t_ref, 0.71)
        assert a[:2] == b[:2] and a.cal == b.cal


@pytest.mark.parametrize("name", ["mptc", "mptc_db", "db_mptc"])
def test_switching_effort_lowers_the_switching_frequency(im_short, name):
    """Closed loop on paper 000's induction motor: f_sw falls as λ_sw rises (N·m per commutation,
    against a torque error of tenths of N·m)."""
    import dataclasses

    from predictive_drive.core.metrics import compute_metrics
    from predictive_drive.core.runner import run_inprocess

    f_sw = []
    for lam_sw in (0.0, 0.1, 0.5):
        ctrl = dataclasses.replace(im_short.controller, strategy=name, lambda_sw=lam_sw)
        sc = dataclasses.replace(im_short, controller=ctrl)
        f_sw.append(compute_metrics(run_inprocess(sc, steps=3000), t_start=0.02).f_sw_hz)
    assert f_sw[0] > f_sw[1] > f_sw[2], f_sw


@pytest.mark.parametrize("loop", ["one_step", "immediate"])
def test_a_torque_profile_replaces_the_speed_pi(loop):
    """With speed_pi.torque_times the reference is the torque profile's at the step it is for,
    whatever the speed, and the PI integrates nothing."""
    pi = SpeedPI(
        pi_params(torque_times=(0.0, 0.001), torque_values=(2.0, -2.0), speed_loop=loop), ts=TS
    )
    lag = 0 if loop == "immediate" else 1
    if loop == "one_step":
        assert pi.initial().torque_ref == 2.0
    for k in range(60):
        r = pi.step(_state(k, w=123.0))
        assert r.k == k + lag and r.torque_ref == (2.0 if k + lag < 20 else -2.0)
    assert pi.integral == 0.0


def test_a_torque_profile_beyond_the_limit_is_refused():
    from predictive_drive.errors import ConfigError

    with pytest.raises(ConfigError, match=r"speed_pi.torque_values: \[9.0\] N·m reach beyond"):
        pi_params(torque_times=(0.0,), torque_values=(9.0,))
