"""A drive as real drives are (docs/physics.md#a-real-drive): computation delay and its
compensation, dead time and device drops with the FOC feed-forward, seeded sensors; the papers'
ideal drive unchanged by default."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from predictive_drive.config import load_scenario
from predictive_drive.core.metrics import compute_metrics
from predictive_drive.core.plant import ALL_LOW, PERIOD_MEANS, make_plant
from predictive_drive.core.runner import build_plant, run_inprocess
from predictive_drive.core.signals import Command, PhasePulses, State
from predictive_drive.errors import ConfigError

pytestmark = pytest.mark.core


def _with(name: str, strategy: str | None = None, plant=None, ctrl=None, duration=None):
    sc = load_scenario(name, strategy=strategy, duration=duration)
    return dataclasses.replace(
        sc,
        plant=dataclasses.replace(sc.plant, **(plant or {})),
        controller=dataclasses.replace(sc.controller, **(ctrl or {})),
    )


def _t_rmse(sc) -> float:
    lo = sc.logger
    return compute_metrics(run_inprocess(sc), t_start=lo.window_start, t_end=lo.window_end).t_rmse


@pytest.mark.parametrize("strategy", ["mptc", "db_mptc"])
def test_uncompensated_delay_degrades_and_compensation_restores(strategy):
    """One period of computation delay (a DSP's): uncompensated, the FCS law decides on a
    state that is gone by the time its vector acts; predicting k+1 with the command in force and
    deciding for the period after brings T_RMSE back near the ideal drive's."""
    ideal = _t_rmse(_with("im_short", strategy))
    late = _t_rmse(_with("im_short", strategy, {"actuation_delay_steps": 1}))
    compensated = _t_rmse(
        _with("im_short", strategy, {"actuation_delay_steps": 1}, {"delay_compensation": True})
    )
    assert late > 2.5 * ideal, (ideal, late)
    assert compensated < 1.25 * ideal, (ideal, compensated)


def _command(k: int, pulses) -> Command:
    return Command(float(k), 0.0, *pulses, *([math.nan] * (len(Command._fields) - 8)))


def test_a_delayed_command_acts_that_many_periods_later():
    """With actuation_delay_steps = d the plant applies command k during period k+d and holds
    every phase low before the first one acts: the same states as an ideal plant fed the
    commands shifted by d."""
    sc = load_scenario("ipmsm_short")
    rng = np.random.default_rng(1)
    pulses = [PhasePulses(*rng.uniform(0, 0.5, 3), *rng.uniform(0, 0.5, 3)) for _ in range(40)]
    for d in (1, 2):
        late = build_plant("pmsm", dataclasses.replace(sc.plant, actuation_delay_steps=d), ts=sc.ts)
        ideal = build_plant("pmsm", sc.plant, ts=sc.ts)
        shifted = [ALL_LOW] * d + pulses
        for k in range(40):
            a = late.step(_command(k, pulses[k]))
            b = ideal.step(_command(k, shifted[k]))
            assert a == b, (d, k)


def _same_state(a, b):
    """The same sample; the same period means to the quadrature's accuracy: the dead-time plant
    cuts the period into more pieces, each signal taken as linear between other points (0.012 %
    apart here: the torque's curvature over a 27 us piece)."""
    n = State._fields.index(PERIOD_MEANS[0])
    m = n + len(PERIOD_MEANS)  # the losses after them: NaN here
    np.testing.assert_allclose(a[:n], b[:n], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(a[n:m], b[n:m], rtol=1e-3)
    np.testing.assert_array_equal(a[m:], b[m:])


def test_dead_time_delays_the_edge_that_goes_against_the_current():
    """Phase a commanded high on [0.2, 0.7) Ts with its current flowing out of the leg: during
    the dead time after the rising edge both devices are off and the lower diode holds the leg
    low, so the leg is high on [0.2 + t_d/Ts, 0.7) (the falling edge is not delayed: the diode
    already holds the leg low) — the ideal plant given that pulse reaches the same state."""
    sc = load_scenario("ipmsm_short")
    ts, td = sc.ts, 0.04 * sc.ts
    kw = dict(ts=ts, u_dc=sc.plant.u_dc, load=sc.plant.load_profile(), max_substep=ts)
    kw["period_means"] = True
    dead = make_plant("pmsm", sc.plant.motor, dead_time=td, **kw)
    ideal = make_plant("pmsm", sc.plant.motor, **kw)
    for p in (dead, ideal):
        p.x = (complex(2.0, -5.0), 50.0, 0.1)  # i_dq; at θ_e = 0.3 rad phase a carries +3.4 A
    i_a = dead._i_ab(dead.x).real
    assert i_a > 1.0
    a = dead.step(_command(0, (0.2, 0.0, 0.0, 0.5, 0.0, 0.0)))
    b = ideal.step(_command(0, (0.2 + td / ts, 0.0, 0.0, 0.5 - td / ts, 0.0, 0.0)))
    _same_state(a, b)
    # the opposite current: the rising edge is on time, the falling edge late
    dead = make_plant("pmsm", sc.plant.motor, dead_time=td, **kw)
    ideal = make_plant("pmsm", sc.plant.motor, **kw)
    for p in (dead, ideal):
        p.x = (complex(-2.0, 5.0), 50.0, 0.1)
    assert dead._i_ab(dead.x).real < -1.0
    a = dead.step(_command(0, (0.2, 0.0, 0.0, 0.5, 0.0, 0.0)))
    b = ideal.step(_command(0, (0.2, 0.0, 0.0, 0.5 + td / ts, 0.0, 0.0)))
    _same_state(a, b)


def test_dead_time_raises_foc_thd_and_the_feed_forward_lowers_it():
    """3 µs of dead time (3 % of Ts) distorts the phase current of an SVPWM drive; the voltage
    feed-forward by current sign takes most of it away again (docs/physics.md#a-real-drive)."""

    def thd(plant, ctrl) -> float:
        sc = _with("ipmsm_mtpa_short", "foc_zero_d", plant, ctrl)
        m = compute_metrics(run_inprocess(sc), t_start=0.2, t_end=0.4, thd_window=(0.2, 0.4))
        return m.thd

    ideal = thd({}, {})
    dead = thd({"dead_time": 3e-6, "device_drop": 1.5}, {})
    fed = thd(
        {"dead_time": 3e-6, "device_drop": 1.5},
        {"dead_time_compensation": 3e-6, "drop_compensation": 1.5},
    )
    assert dead > 4 * ideal, (ideal, dead)
    assert fed < 0.4 * dead, (dead, fed)


def test_sensors_measure_from_a_seed_and_the_truth_is_kept():
    """The same seed gives the same run bit for bit, another seed another run; the ADC's
    readings lie on its steps, the encoder's angle on its counts; the truth stays beside."""
    noisy = {
        "current_noise": 0.05,
        "current_adc_bits": 12,
        "current_range": 20.0,
        "encoder_lines": 1024,
        "sensor_seed": 7,
    }
    a = run_inprocess(_with("im_short", plant=noisy, duration=0.05))
    b = run_inprocess(_with("im_short", plant=noisy, duration=0.05))
    c = run_inprocess(_with("im_short", plant={**noisy, "sensor_seed": 8}, duration=0.05))
    np.testing.assert_array_equal(a.state, b.state)
    np.testing.assert_array_equal(a.command[:, :-1], b.command[:, :-1])
    assert not np.array_equal(a.col("state", "i_alpha"), c.col("state", "i_alpha"))
    lsb = 40.0 / 2**12
    i_a = a.col("state", "i_alpha")  # phase a is measured directly
    np.testing.assert_allclose(i_a / lsb, np.round(i_a / lsb), atol=1e-9)
    count = 2 * math.pi / (4 * 1024)  # p = 1
    th = a.col("state", "theta_e")
    assert np.all(np.abs(th / count - np.round(th / count)) < 1e-6)
    true = a.col("state", "i_alpha_true")
    err = i_a - true
    assert 0.02 < np.std(err[100:]) < 0.08  # 50 mA rms of noise and a 10 mA step
    assert np.array_equal(a.truth("i_alpha"), true)


@pytest.mark.parametrize(
    ("setting", "message"),
    [
        ({"dead_time": -1e-6}, r"dead_time must be a finite number >= 0 s, got -1e-06"),
        ({"dead_time": math.nan}, r"dead_time must be a finite number >= 0 s, got nan"),
        ({"dead_time": 5e-6}, r"plant.dead_time: 5e-06 s must be below a tenth of the control"),
        ({"actuation_delay_steps": 3}, r"actuation_delay_steps must be 0..2, got 3"),
        ({"device_drop": -0.1}, r"device_drop must be a finite number >= 0 V"),
        ({"current_adc_bits": 12}, r"current_adc_bits: 12 bits need plant.current_range"),
        ({"current_adc_bits": 25, "current_range": 5.0}, r"current_adc_bits must be 0..24"),
        ({"current_range": 5.0}, r"current_range: given without plant.current_adc_bits"),
        ({"current_noise": math.inf}, r"current_noise must be a finite number >= 0 A rms"),
        ({"encoder_lines": -4}, r"encoder_lines must be an integer >= 0"),
        ({"encoder_lines": 100, "speed_window": 1e-5}, r"speed_window: 1e-05 s is shorter"),
        ({"sensor_seed": 1.5}, r"sensor_seed must be an integer >= 0"),
    ],
)
def test_impossible_real_drive_settings_are_refused_naming_the_key(setting, message):
    with pytest.raises(ConfigError, match=message):
        _with("im_short", plant=setting)


def test_the_dc_link_gain_changes_what_is_measured_not_the_drive():
    """plant.u_dc_gain 1.1: the published u_dc is 1.1 × the DC link; the plant under the same
    commands moves as with an exact sensor (the inverter's voltages are the true ones)."""
    import math as m

    from predictive_drive.core.machines.pmsm import PMSM
    from predictive_drive.core.plant import PMSMPlant
    from predictive_drive.core.signals import Command
    from predictive_drive.core.timebase import StepProfile

    motor = PMSM(0.25, 0.0033, 0.0073, 0.2264, 3, 0.001, 15.0, 1000.0)
    kw = dict(ts=5e-5, u_dc=312.0, load=StepProfile((0.0,), (0.0,)), max_substep=5e-5)
    exact, off = PMSMPlant(motor, **kw), PMSMPlant(motor, u_dc_gain=1.1, **kw)
    for k in range(50):
        c = Command(
            k, k * 5e-5, 0.0, 0.1, 0.2, 0.5, 0.3, 0.1, *[m.nan] * (len(Command._fields) - 8)
        )
        a, b = exact.step(c), off.step(c)
    assert b.u_dc == pytest.approx(1.1 * 312.0, rel=1e-15) and a.u_dc == 312.0
    assert (b.i_alpha, b.i_beta, b.omega_m) == (a.i_alpha, a.i_beta, a.omega_m)
