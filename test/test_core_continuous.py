"""The continuous-time figures (docs/physics.md#continuous-time-figures) against closed forms and
an independent FFT: the current's fundamental and distortion of a waveform of known content,
SVPWM's THD against the FFT of its rebuilt waveform (test/continuous.py), T_RMSE / T_ripple /
the mean error of a torque of known shape, and the plant's period mean of i_αβ over a sub-step
the rotor turns far in (its closed-form branch)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from continuous import compare
from predictive_drive.core.machines.pmsm import PMSM
from predictive_drive.core.metrics import (
    compute_metrics,
    continuous_current,
    continuous_mean_error,
    continuous_ripple,
    continuous_rmse,
    whole_cycles,
)
from predictive_drive.core.plant import PMSMPlant
from predictive_drive.core.signals import Command, Reference, State
from predictive_drive.core.timebase import StepProfile
from predictive_drive.core.trace import Trace

pytestmark = pytest.mark.core

TWO_PI = 2.0 * math.pi


def _period_mean(nu: float, t0: np.ndarray, ts: float) -> np.ndarray:
    """The mean of e^{jνt} over [t0, t0 + Ts): e^{jν(t0 + Ts/2)}·sin(νTs/2)/(νTs/2)."""
    return np.exp(1j * nu * (t0 + ts / 2)) * np.sinc(nu * ts / TWO_PI)


def _trace(state_columns: dict[str, np.ndarray], ref_columns: dict[str, np.ndarray], ts, n):
    state = np.zeros((n + 1, len(State._fields)))
    ref = np.zeros((n + 1, len(Reference._fields)))
    k = np.arange(n + 1, dtype=float)
    for rows, fields, columns in ((state, State._fields, state_columns),
                                  (ref, Reference._fields, ref_columns)):  # fmt: skip
        rows[:, 0], rows[:, 1] = k, k * ts
        for name, values in columns.items():
            rows[:, fields.index(name)] = values
    command = np.zeros((n, len(Command._fields)))
    command[:, 0] = k[:-1]
    return Trace(ts, state, ref, command)


def known_current(parts, *, ts, n, w_e, w_1):
    """A trace whose stator current is Σ a·e^{jνt} (``parts``: (a A, ν rad/s)), given as the
    plant gives it: samples, and period means — of i_αβ, of |i|² and of i in the rotor's frame
    (θ_e = w_e·t) — integrated in closed form; the stator flux turns at w_1."""
    k = np.arange(n + 1)
    t, t0 = k * ts, (k - 1) * ts  # state k holds the means over period k-1
    mean_i = sum(a * _period_mean(nu, t0, ts) for a, nu in parts)
    mean_r = sum(a * _period_mean(nu - w_e, t0, ts) for a, nu in parts)
    mean_sq = sum(a * a for a, _ in parts) + sum(
        2 * (a * b * _period_mean(nu - mu, t0, ts)).real
        for i, (a, nu) in enumerate(parts)
        for b, mu in parts[i + 1 :]
    )
    sampled = sum(a * np.exp(1j * nu * t) for a, nu in parts)
    flux = 0.7 * np.exp(1j * (w_1 * t - 1.0)) * (1 + 0.01 * np.cos(6 * w_1 * t))  # rippling
    theta = np.mod(w_e * t, TWO_PI)
    columns = {
        "theta_e": theta, "theta_e_true": theta, "i_alpha": sampled.real,
        "i_alpha_true": sampled.real, "i_beta": sampled.imag, "i_beta_true": sampled.imag,
        "psi_alpha": flux.real, "psi_beta": flux.imag, "i_alpha_avg": mean_i.real,
        "i_beta_avg": mean_i.imag, "current_sq_avg": mean_sq, "i_d_avg": mean_r.real,
        "i_q_avg": mean_r.imag,
    }  # fmt: skip
    return _trace(columns, {}, ts, n)


F_C = 20e3  # the carrier of the known waveform: Ts = 50 µs


def _content(f1: float) -> list[tuple[float, float]]:
    """10 A of fundamental at f1; the 5th (negative sequence) and 7th harmonics; the carrier's
    sidebands 2f_c ± f1 and f_c ± 2f1 — the lines period means of i_αβ fold onto f1 — a line
    at 27 kHz and 30 mA of DC. THD sqrt(Σ others²)/10 = 2.08 %."""
    w = TWO_PI * f1
    return [
        (10.0, w), (0.05, -5 * w), (0.04, 7 * w), (0.1, TWO_PI * (2 * F_C + f1)),
        (0.1, TWO_PI * (2 * F_C - f1)), (0.05, TWO_PI * (F_C - 2 * f1)),
        (0.05, TWO_PI * (F_C + 2 * f1)), (0.08, TWO_PI * 27e3), (0.03, 0.0),
    ]  # fmt: skip


@pytest.mark.parametrize(
    ("f1", "f_rotor", "slips", "ts", "keep", "rtol"),
    [
        (47.6, 47.6, False, 1 / F_C, None, 1e-3),  # a synchronous machine
        (50.0, 50.0, False, 1 / F_C, None, 1e-9),  # ... whole cycles in whole periods: exact
        (47.6, 46.2, True, 1 / F_C, None, 3e-3),  # an induction motor at 1.4 Hz of slip
        (47.6, 46.2, True, 1 / F_C, (0, 1, 2, 7, 8), 1e-3),  # ... its lines away from m/Ts ± f1
        (625.0, 125.0, True, 2e-4, (0, 1, 2, 8), 1e-9),  # a slip of 0.63 rad per period
    ],
    ids=["synchronous", "synchronous-aligned", "slip", "slip-no-sidebands", "large-slip"],
)
def test_the_current_distortion_of_known_content(f1, f_rotor, slips, ts, keep, rtol):
    """The fundamental and distortion of a waveform of known content, through the metric: its
    THD to ``rtol`` (0.1 % asked). A synchronous machine's fundamental stands still in the rotor
    frame, where the plant averages it: exact when the window's whole cycles are whole periods,
    else within 5e-5 (the window holds up to one period more: lines that differ by a harmonic
    of f1 do not quite average out). An induction motor's turns there at the slip,
    demodulated with each period's sinc divided out (the large-slip case fails without it); what
    the rotor-frame means still fold onto the fundamental are the lines at m/Ts ± f1, reduced
    by f_slip/f1 (-0.17 % here; period means of i_αβ fold them whole: -4 % on the synchronous
    case)."""
    parts = _content(f1)
    if keep is not None:
        parts = [parts[i] for i in keep]
    n = round(0.4 / ts)
    tr = known_current(parts, ts=ts, n=n, w_e=TWO_PI * f_rotor, w_1=TWO_PI * f1)
    w = whole_cycles(tr, 0.0, n * ts, slips=slips)
    c = continuous_current(tr, w, slips=slips)
    distortion = math.sqrt(sum(a * a for a, _ in parts[1:]))
    assert c.thd == pytest.approx(distortion / 10.0, rel=rtol)
    assert c.fundamental == pytest.approx(10.0, rel=max(1e-12, rtol * 0.02))
    assert c.tdd(5.0) == pytest.approx(2 * c.thd * c.fundamental / 10.0, rel=1e-12)
    m = compute_metrics(tr, thd_window=(0.0, n * ts), slips=slips)
    assert (m.i_thd_cont, m.i_fundamental_cont, m.i_distortion_cont) == (
        c.thd,
        c.fundamental,
        c.distortion,
    )


@pytest.mark.parametrize(
    ("scenario", "khz"), [("ipmsm_steady_foc", 3.0), ("im_steady_foc", 2.0)], ids=["ipmsm", "im"]
)
def test_svpwm_distortion_is_the_fft_of_its_continuous_waveform(scenario, khz):
    """FOC + SVPWM at a steady point: THD_i cont within 1 % (relative) of the FFT of the current
    rebuilt between the samples over whole fundamental periods (test/continuous.py; measured
    -0.006 % on paper 001's IPMSM, +0.19 % on paper 000's IM, whose plant averages the current
    as linear in the rotor frame while its switching ramps are straight in the stator's)."""
    m, thd, fund = compare(scenario, khz)
    assert m.i_thd_cont == pytest.approx(thd, rel=1e-2)
    assert m.i_fundamental_cont == pytest.approx(fund, rel=1e-4)


def _stepping_torque(ts: float, n: int):
    """T(t) = T*(t) + B + A·sin(ωt), T* stepping between 1 and 2 N·m every 3 periods: its period
    means in closed form, and the figures by a fine quadrature of the same function."""
    big, a, w = 0.05, 0.3, TWO_PI * 730.0
    k = np.arange(n + 1)
    t_ref = np.where((k // 3) % 2 == 0, 1.0, 2.0)
    t0 = (k - 1) * ts
    sin_mean = _period_mean(w, t0, ts).imag
    sin_sq_mean = (1 - _period_mean(2 * w, t0, ts).real) / 2
    before = np.roll(t_ref, 1)  # the reference in force over period k-1 (state k's)
    mean = before + big + a * sin_mean
    square = (before + big) ** 2 + 2 * (before + big) * a * sin_mean + a * a * sin_sq_mean
    columns = {"torque_avg": mean, "torque_sq_avg": square}
    tr = _trace(columns, {"torque_ref": t_ref}, ts, n)
    fine = 400
    t = (np.arange(n * fine) + 0.5) * (ts / fine)  # midpoints of every period's fine slices
    ref = np.repeat(t_ref[:n], fine)
    torque = ref + big + a * np.sin(w * t)
    return tr, t, torque, ref, fine


def test_continuous_rmse_ripple_and_mean_error_of_a_known_torque():
    """T_RMSE cont, T_ripple cont and the mean error against a fine quadrature of a torque of
    known shape under a reference that steps every three periods: each period's means are paired
    with the reference in force over that period (state k+1 holds period k's; read one period
    early, each step of T* is met a period late: T_RMSE cont 0.617 instead of 0.218 N·m)."""
    ts, n = 1e-4, 600
    tr, t, torque, ref, fine = _stepping_torque(ts, n)
    k0, k1 = 90, 510
    s = slice(k0 * fine, k1 * fine)
    err = torque[s] - ref[s]
    rmse = math.sqrt(float(np.mean(err**2)))
    ripple = float(np.std(torque[s]))
    assert continuous_rmse(tr, "torque", "torque_ref", k0, k1) == pytest.approx(rmse, rel=1e-6)
    assert continuous_ripple(tr, "torque", k0, k1) == pytest.approx(ripple, rel=1e-6)
    assert continuous_mean_error(tr, "torque", "torque_ref", k0, k1) == pytest.approx(
        float(np.mean(err)), rel=1e-6
    )
    m = compute_metrics(tr, t_start=k0 * ts, t_end=k1 * ts)
    assert (m.t_rmse_cont, m.t_ripple_cont) == pytest.approx((rmse, ripple), rel=1e-6)
    assert m.t_mean_error_cont == pytest.approx(0.05, rel=0.05)


IPMSM = PMSM(0.25, 0.0033, 0.0073, 0.2264, 3, 0.001, 15.0, 1000.0)


def test_the_period_mean_of_the_current_when_the_rotor_turns_far_in_a_sub_step():
    """At 3000 r/min and Ts = 400 µs (one sub-step per switching segment) the rotor turns more
    than 0.1 rad in most segments, where the plant takes ∫(i_0 + (i_1 - i_0)s)·e^{j(θ_0 + φs)} h
    ds in closed form (below it, by its series): every period's mean of i_αβ against the same
    integral by 20-point Gauss-Legendre quadrature of each sub-step the plant took, and the
    rotor-frame mean against the trapezoid."""
    ts = 4e-4
    plant = PMSMPlant(
        IPMSM, ts=ts, u_dc=312.0, load=StepProfile((0.0,), (0.0,)), max_substep=ts,
        period_means=True, held_speed=StepProfile((0.0,), (3000.0 * TWO_PI / 60.0,)),
    )  # fmt: skip
    pieces: list[tuple[complex, complex, float, float, float]] = []
    integrate = plant._integrate

    def logged(t, x, u, coef, h, n):
        y = integrate(t, x, u, coef, h, n)
        pieces.append((x[0], y[0], IPMSM.p * x[2], IPMSM.p * y[2], h))
        return y

    plant._integrate = logged
    nodes, weights = np.polynomial.legendre.leggauss(20)
    s = (nodes + 1) / 2
    large = 0
    for k in range(60):
        pieces.clear()
        duty = 0.15 + 0.7 * (k % 7) / 6
        pulses = (0.0, 0.5 * (1 - duty), 0.1, duty, duty / 2, 0.85)
        state = plant.step(Command(k, k * ts, *pulses, *[math.nan] * (len(Command._fields) - 8)))
        whole = sum(
            h * np.sum(weights / 2 * (i0 + (i1 - i0) * s) * np.exp(1j * (th0 + (th1 - th0) * s)))
            for i0, i1, th0, th1, h in pieces
        )
        rotor = sum(h * (i0 + i1) / 2 for i0, i1, _, _, h in pieces)
        large += sum(abs(th1 - th0) >= 0.1 for _, _, th0, th1, _ in pieces)
        mean = complex(state.i_alpha_avg, state.i_beta_avg)
        assert mean == pytest.approx(whole / ts, rel=1e-7)  # the series: within 2e-8
        assert complex(state.i_d_avg, state.i_q_avg) == pytest.approx(rotor / ts, rel=1e-12)
    assert large > 60  # the closed form was taken, more than once a period
