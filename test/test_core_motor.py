"""IM physics against closed forms, finite differences and an independent formula (paper 000)."""

import cmath
import math

import numpy as np
import pytest

from predictive_drive.core.control.mptc_im import IMPrediction
from predictive_drive.core.machines.induction import (
    InductionCoefficients,
    induction_dynamics,
    induction_exact,
    induction_rk4,
    induction_torque,
)
from predictive_drive.core.plant import rk4

pytestmark = pytest.mark.core

TS = 5e-5
STATE = (3.1 - 2.2j, 0.55 + 0.42j, 180.0, 0.3)  # i_s, ψ_s, ω_m, θ_m: a running machine


@pytest.fixture(scope="module")
def motor(im_short):
    return im_short.plant.motor


@pytest.fixture(scope="module")
def coef(motor):
    return InductionCoefficients.of(motor)


def test_fused_rk4_equals_generic_rk4(coef):
    u = (388.0 + 0j, 1.5)
    a = induction_rk4(0.0, STATE, u, coef, TS, 3)
    b = rk4(induction_dynamics)(0.0, STATE, u, coef, TS, 3)
    np.testing.assert_allclose(
        np.array(a, dtype=complex), np.array(b, dtype=complex), rtol=1e-13, atol=1e-13
    )


def test_locked_rotor_step_matches_closed_form(coef, motor):
    """ω = 0, from rest: the 2x2 linear system has the closed form x(t) = A⁻¹(e^{At} - I)B u."""
    u = 50.0 + 20.0j
    a = np.array([[coef.a_ii, coef.b_ipsi], [-motor.r_s, 0.0]], dtype=complex)
    b = np.array([coef.c_w, 1.0], dtype=complex)
    w, v = np.linalg.eig(a)
    for t in (1e-4, 2e-3, 2e-2):
        expm = v @ np.diag(np.exp(w * t)) @ np.linalg.inv(v)
        exact = np.linalg.solve(a, (expm - np.eye(2)) @ b * u)
        x = (0j, 0j, 0.0, 0.0)
        # inertia made huge so the rotor stays locked
        locked = coef._replace(inv_j=0.0)
        n = math.ceil(t / TS)
        x = induction_rk4(0.0, x, (u, 0.0), locked, t, n)
        np.testing.assert_allclose([x[0], x[1]], exact, rtol=1e-7, atol=1e-9)


def test_exact_segment_equals_rk4_for_frozen_speed(coef):
    """With ω held (J → ∞) the exact discretisation is exact: fine RK4 converges onto it."""
    frozen = coef._replace(inv_j=0.0)
    for u, h in ((388.0 + 0j, TS), (-194.0 + 336.0j, 0.3 * TS), (0j, 7 * TS)):
        a = induction_exact(0.0, STATE, (u, 1.5), frozen, h, 1)
        b = induction_rk4(0.0, STATE, (u, 1.5), frozen, h, 400)
        np.testing.assert_allclose(a[:2], b[:2], rtol=1e-12, atol=1e-12)
        assert a[2] == STATE[2] and a[3] == pytest.approx(STATE[3] + h * STATE[2], rel=1e-15)


def test_exact_segment_tracks_rk4_with_the_rotor_moving(coef):
    """ω frozen only over each sub-step (at its predicted midpoint): over 200 periods of
    alternating vectors (ω falls 180 → 125 rad/s) the two integrators stay within 1e-5 relative,
    and the error falls with the square of the sub-step."""
    volts = (388.0 + 0j, 0j, -194.0 + 336.0j, 0j)

    def run(f, n):
        x = STATE
        for k in range(200):
            x = f(0.0, x, (volts[k % 4], 1.5), coef, TS, n)
        return x

    ref = run(induction_rk4, 8)
    errs = []
    for n in (1, 2):
        x = run(induction_exact, n)
        errs.append(abs(x[0] - ref[0]) / abs(ref[0]))
        assert errs[-1] < 1e-5
        assert abs(x[1] - ref[1]) / abs(ref[1]) < 1e-5
        assert x[2] == pytest.approx(ref[2], rel=2e-6)
    assert errs[1] < 0.3 * errs[0]


def _derived_dtdt(m: IMPrediction, u: complex) -> float:
    return m.a_u(u) + m.a0


@pytest.mark.parametrize("vector", [0, 1, 2, 4], ids=["V0", "V1", "V2", "V4"])
def test_torque_derivative_matches_finite_difference(coef, vector):
    """a_u + a_0 (paper 000 eq 10, corrected a_0) = dT_e/dt of the model, by central difference."""
    u = 388.0 * cmath.exp(1j * math.pi / 3 * (vector - 1)) if vector else 0j
    m = IMPrediction(coef, TS, 17.5, a0_printed=False)
    i, psi, w, _ = STATE
    m.prepare(i, psi, w, (u,))
    h = 1e-7

    def torque_after(dt):
        x = induction_rk4(0.0, STATE, (u, 0.0), coef._replace(inv_j=0.0), dt, 1)
        return induction_torque(x[1], x[0], coef.torque_k)

    fd = (torque_after(h) - torque_after(-h)) / (2 * h)
    assert _derived_dtdt(m, u) == pytest.approx(fd, rel=1e-6)


def test_printed_a0_has_the_sign_error(coef):
    """Erratum: paper 000 eq 10 as printed flips the ω_r·Re(conj(ψ_s)·i_s) term."""
    i, psi, w, _ = STATE
    good = IMPrediction(coef, TS, 17.5, a0_printed=False)
    bad = IMPrediction(coef, TS, 17.5, a0_printed=True)
    good.prepare(i, psi, w, (0j,))
    bad.prepare(i, psi, w, (0j,))
    wr = coef.p * w
    re = (psi.conjugate() * i).real
    assert good.a0 - bad.a0 == pytest.approx(2 * coef.torque_k * wr * re, rel=1e-12)
    # and only the derived one agrees with the model: the printed one misses dT_e/dt by > 1 %
    h = 1e-7

    def torque_after(dt):
        x = induction_rk4(0.0, STATE, (0j, 0.0), coef._replace(inv_j=0.0), dt, 1)
        return induction_torque(x[1], x[0], coef.torque_k)

    fd = (torque_after(h) - torque_after(-h)) / (2 * h)
    assert good.a0 == pytest.approx(fd, rel=1e-6)
    assert abs(bad.a0 - fd) > 0.01 * abs(fd)


def _eq5_corrected(motor, i, psi, w, u):
    """Paper 000 eq 5 as corrected (docs/physics.md#paper-000s-misprints) — an independent form of
    the same prediction."""
    s = motor.sigma
    r_sig = motor.r_s + motor.r_r * motor.l_m**2 / motor.l_r**2
    tau_sig = s * motor.l_s / r_sig
    tau_r = motor.l_r / motor.r_r
    k_r = motor.l_m / motor.l_r
    psi_r = (motor.l_r / motor.l_m) * psi + (motor.l_m - motor.l_r * motor.l_s / motor.l_m) * i
    wr = motor.p * w
    return (1 - TS / tau_sig) * i + (TS / tau_sig) * (1 / r_sig) * (
        k_r * (1 / tau_r - 1j * wr) * psi_r + u
    )


def _eq5_printed(motor, i, psi, w, u):
    s = motor.sigma
    r_sig = motor.r_s + motor.r_r * motor.l_m**2 / motor.l_r**2
    tau_sig = s * motor.l_s / r_sig
    psi_r = (motor.l_r / motor.l_m) * psi + (motor.l_m - motor.l_r * motor.l_s / motor.l_m) * i
    wr = motor.p * w
    return (1 + TS / tau_sig) * i + TS / (tau_sig + TS) * (1 / r_sig) * (
        motor.l_m / motor.l_r * (1 / tau_sig - 1j * wr) * psi_r + u
    )


def test_prediction_equals_corrected_eq5_not_printed_eq5(coef, motor):
    i, psi, w, _ = STATE
    u = 388.0 * cmath.exp(1j)
    m = IMPrediction(coef, TS, 17.5, a0_printed=False)
    m.prepare(i, psi, w, (u,))
    ours = m.i_free + m.gain_i * u
    assert abs(ours - _eq5_corrected(motor, i, psi, w, u)) < 1e-9 * abs(i)
    assert abs(ours - _eq5_printed(motor, i, psi, w, u)) > 1e-2 * abs(i)
