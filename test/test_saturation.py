"""Saturating machines (docs/physics.md#saturation): the magnetic models against independent
computations (finite differences, closed forms), the saturated plants against the linear ones
where the magnetics are linear, a flux map's checks on load, the range beyond which a run stops,
and what a controller that knows the map reads off it."""

from __future__ import annotations

import dataclasses
import math
import random

import numpy as np
import pytest

from predictive_drive.config import apply_settings, load_scenario, load_scenario_text
from predictive_drive.config import resolve_scenario_path as scenario_path
from predictive_drive.core.control.maps import ApparentModel, MapMTPA
from predictive_drive.core.control.mtpa import mtpa_point
from predictive_drive.core.machines.induction import InductionMotor
from predictive_drive.core.machines.magnetics import (
    CONSERVATIVE_TOLERANCE,
    PMSMSaturation,
    algebraic_currents,
    magnetic_model,
)
from predictive_drive.core.machines.pmsm import PMSM, PMSMCoefficients
from predictive_drive.core.machines.saturated import (
    IMSaturation,
    SaturatedIM,
    SaturatedIMCoefficients,
    saturated_im_current,
)
from predictive_drive.core.plant import InductionPlant, PMSMPlant
from predictive_drive.core.runner import run_inprocess
from predictive_drive.core.saturation import SaturatedIMPlant, SaturatedPMSM, SaturatedPMSMPlant
from predictive_drive.core.signals import Command
from predictive_drive.core.timebase import StepProfile
from predictive_drive.errors import ConfigError

pytestmark = pytest.mark.core

TS = 5e-5
IPMSM = PMSM(0.25, 0.0033, 0.0073, 0.2264, 3, 0.001, 15.0, 1000.0)
#: the 5.6-kW PM-SyRM (Lelli et al. 2024), as config/pmsyrm_steady.yaml gives it
PMSYRM = PMSMSaturation(
    model="algebraic", a_d0=3.96, a_dd=28.5, s=4, a_q0=5.89, a_qq=2.67, t=6, a_dq=41.5, u=1,
    v=1, a_b=81.75, a_bp=1, k_q=0.1, psi_n=0.804, w=2, max_current=25,
)  # fmt: skip
PMSYRM_MOTOR = PMSM(0.63, 0.0305, 0.145, 0.477, 2, 0.05, 29.7, 1800.0)
LINEAR = PMSMSaturation(
    model="algebraic", psi_offset=IPMSM.psi_f, a_d0=1 / IPMSM.l_d, a_q0=1 / IPMSM.l_q,
    max_current=200,
)  # fmt: skip


def command(k: int, pulses: tuple[float, ...]) -> Command:
    return Command(k, k * TS, *pulses, *[math.nan] * (len(Command._fields) - 8))


def random_pulses(rng: random.Random) -> tuple[float, ...]:
    rises = [rng.choice((0.0, rng.random() * 0.5)) for _ in range(3)]
    return (*rises, *(rng.random() * (1 - r) for r in rises))


def table_of(sat: PMSMSaturation, motor: PMSM, step: int = 4) -> PMSMSaturation:
    """A flux-map table sampled from a model (every ``step``-th point of its map)."""
    fm = magnetic_model(motor, sat).flux_map
    return PMSMSaturation(
        model="table",
        i_d=tuple(fm.i_d[::step]),
        i_q=tuple(fm.i_q[::step]),
        psi_d=tuple(fm.psi_d[::step, ::step].ravel()),
        psi_q=tuple(fm.psi_q[::step, ::step].ravel()),
    )


def test_the_algebraic_model_is_conservative_and_monotonic():
    """∂i_d/∂ψ_q = ∂i_q/∂ψ_d (a magnetic energy exists) and the incremental inverse inductances
    positive, by central differences at random fluxes over the model's range."""
    current = algebraic_currents(PMSYRM)
    rng = random.Random(1)
    h = 1e-6
    for _ in range(200):
        pd, pq = rng.uniform(-0.2, 1.1), rng.uniform(-1.1, 1.1)
        d_dq = (current(pd, pq + h)[0] - current(pd, pq - h)[0]) / (2 * h)
        d_qd = (current(pd + h, pq)[1] - current(pd - h, pq)[1]) / (2 * h)
        assert d_dq == pytest.approx(d_qd, rel=1e-5, abs=1e-6)
        assert (current(pd + h, pq)[0] - current(pd - h, pq)[0]) > 0
        assert (current(pd, pq + h)[1] - current(pd, pq - h)[1]) > 0


def test_the_published_machine_makes_rated_torque_at_rated_current():
    """Lelli et al.'s 5.6-kW PM-SyRM: rated torque 29.7 N·m on the MTPA curve of the map takes
    11.9 A, the nameplate's 8.8 A rms (12.4 A peak) within 5 %; the magnet's flux at zero
    current between 0 and psi_n."""
    mm = magnetic_model(PMSYRM_MOTOR, PMSYRM)
    amp, _ = MapMTPA(mm.flux_map, 2).mtpa(29.7)
    assert amp == pytest.approx(8.8 * math.sqrt(2), rel=0.05)
    assert 0.3 < mm.psi0[0] < 0.804 and mm.psi0[1] == 0.0


def test_flux_and_current_are_inverse():
    mm = magnetic_model(PMSYRM_MOTOR, PMSYRM)
    for i in (complex(0, 0), complex(-8, 9), complex(5, -12), complex(-20, 3)):
        pd, pq = mm.flux(i.real, i.imag)
        assert complex(*mm.current(pd, pq)) == pytest.approx(i, abs=1e-8)


def test_the_curve_takes_lq_down_by_its_share_at_rated_current():
    """The papers' machines' assumed curve: the apparent L_q = ψ_q/i_q at the q current of rated
    torque (T_r/(1.5 p ψ_f), i_d = 0) is L_q·(1 - lq_drop); near zero current it is L_q."""
    sat = PMSMSaturation(model="curve", lq_drop=0.2)
    mm = magnetic_model(IPMSM, sat)
    i_qr = 15.0 / (1.5 * 3 * 0.2264)
    assert mm.flux(0.0, i_qr)[1] / i_qr == pytest.approx(0.8 * IPMSM.l_q, rel=1e-9)
    assert mm.flux(0.0, 0.01)[1] / 0.01 == pytest.approx(IPMSM.l_q, rel=1e-6)
    assert mm.flux(0.0, 0.0)[0] == pytest.approx(IPMSM.psi_f, abs=1e-12)


def test_a_linear_map_runs_todays_pmsm_to_rounding():
    """The flux-coordinate plant on a linear model (a_d0 = 1/L_d, a_q0 = 1/L_q, ψ_f the offset)
    is the current-coordinate PMSM plant: two implementations, one closed-loop run of
    ipmsm_short (2,000 steps through a load step), states equal to 1e-9."""
    sc = load_scenario("ipmsm_short", duration=0.1)
    lin = run_inprocess(sc)
    sat = dataclasses.replace(sc, plant=dataclasses.replace(sc.plant, saturation=LINEAR))
    s = run_inprocess(sat)
    np.testing.assert_allclose(s.state, lin.state, rtol=1e-9, atol=1e-9)
    # the same decisions: pulses and vectors (the diagnostics' estimates differ by rounding)
    np.testing.assert_array_equal(s.command[:, :10], lin.command[:, :10])


def test_the_saturated_im_without_saturation_is_todays_im():
    """The Γ-circuit plant in flux coordinates with drop = 0 against the T-circuit plant
    (exact for frozen speed): the same random commands, currents and fluxes equal to 1e-6 of
    their peak over 400 steps."""
    m = InductionMotor(2.68, 2.13, 0.2834, 0.2834, 0.2751, 1, 0.005)
    kw = dict(ts=TS, u_dc=582.0, load=StepProfile((0.0,), (1.0,)), max_substep=TS)
    a = InductionPlant(m, **kw)
    b = SaturatedIMPlant(SaturatedIM(m, IMSaturation("curve", 0.71, 0.0)), **kw)
    rng = random.Random(3)
    for k in range(400):
        c = command(k, random_pulses(rng))
        sa, sb = a.step(c), b.step(c)
    for f in ("i_alpha", "i_beta", "psi_alpha", "psi_beta", "torque", "omega_m"):
        scale = max(1.0, abs(getattr(sa, f)))
        assert getattr(sb, f) == pytest.approx(getattr(sa, f), abs=1e-6 * scale), f


def test_the_im_curve_takes_lm_down_by_its_share_at_rated_flux():
    """L_M = ψ_s/i_M with no rotor current (ψ_R = ψ_s): (1 - drop)·L_s at ψ_n, ~L_s well below."""
    m = InductionMotor(2.68, 2.13, 0.2834, 0.2834, 0.2751, 1, 0.005)
    c = SaturatedIMCoefficients.of(SaturatedIM(m, IMSaturation("curve", 0.71, 0.1, 6.0)))
    at = 0.71 / saturated_im_current(0.71 + 0j, 0.71 + 0j, c).real
    assert at == pytest.approx(0.9 * 0.2834, rel=1e-12)
    low = 0.1 / saturated_im_current(0.1 + 0j, 0.1 + 0j, c).real
    assert low == pytest.approx(0.2834, rel=1e-5)


def test_a_locked_rotor_dc_step_settles_at_the_maps_flux():
    """A d-axis voltage on a locked rotor: the current settles at u/R_s (closed form) and the
    flux at the map's flux there (the saturated plant integrates ψ and reads i off the model)."""
    mm = magnetic_model(PMSYRM_MOTOR, PMSYRM)
    kw = dict(ts=TS, u_dc=540.0, load=StepProfile((0.0,), (0.0,)), max_substep=TS)
    kw["held_speed"] = StepProfile((0.0,), (0.0,))
    plant = SaturatedPMSMPlant(SaturatedPMSM(PMSYRM_MOTOR, mm), **kw)
    duty = 6.3 / 540.0  # phase a high for a share of the period: u_d = 2/3·u_dc·duty = 4.2 V
    for k in range(20000):
        s = plant.step(command(k, (0.0, 0.0, 0.0, duty, 0.0, 0.0)))
    u_d = 2.0 / 3.0 * 540.0 * duty
    assert s.i_alpha == pytest.approx(u_d / 0.63, rel=1e-3)  # the sample lies on the ripple
    assert s.psi_alpha == pytest.approx(mm.flux(s.i_alpha, s.i_beta)[0], rel=1e-9)
    assert s.psi_alpha == pytest.approx(mm.flux(u_d / 0.63, 0.0)[0], rel=1e-3)


def test_a_table_sampled_from_the_model_passes_its_checks_and_inverts():
    tab = table_of(PMSYRM, PMSYRM_MOTOR)
    mm = magnetic_model(PMSYRM_MOTOR, tab)
    exact = magnetic_model(PMSYRM_MOTOR, PMSYRM)
    for i in (complex(-5, 8), complex(3, -10), complex(-12, 12)):
        pd, pq = exact.flux(i.real, i.imag)
        # the table's current at the exact flux: the model within the bilinear grid's error
        assert complex(*mm.current(pd, pq)) == pytest.approx(i, abs=0.3)


def _fields(tab: PMSMSaturation, **change: object) -> dict[str, object]:
    return {**{f.name: getattr(tab, f.name) for f in dataclasses.fields(tab)}, **change}


@pytest.mark.parametrize(
    ("change", "words"),
    [
        ("cross", "not conservative"),
        ("fold", "not monotonic"),
        ("no_zero", "must hold 0 A"),
        ("short", "values; the grid"),
        ("falling", "must rise"),
    ],
    ids=["not_conservative", "not_monotonic", "no_zero", "wrong_size", "falling_grid"],
)
def test_a_bad_table_is_refused_on_load_naming_key_and_cell(change, words):
    tab = table_of(PMSYRM, PMSYRM_MOTOR)
    n_q = len(tab.i_q)
    pd = np.reshape(tab.psi_d, (-1, n_q)).copy()
    if change == "cross":  # ψ_d gains a cross term in i_q that ψ_q does not mirror: 2 × the
        # tolerance of the d-axis's unsaturated self-inductance (~30 mH) near the middle
        pd += 2 * CONSERVATIVE_TOLERANCE * 0.03 * np.asarray(tab.i_q)[None, :]
        bad = _fields(tab, psi_d=tuple(pd.ravel()))
    elif change == "fold":
        pd[5, 4] = pd[4, 4] - 0.01
        bad = _fields(tab, psi_d=tuple(pd.ravel()))
    elif change == "no_zero":
        bad = _fields(tab, i_d=tuple(v + 100.0 for v in tab.i_d))
    elif change == "short":
        bad = _fields(tab, psi_q=tab.psi_q[:-1])
    else:
        bad = _fields(tab, i_q=tuple(reversed(tab.i_q)))
    with pytest.raises(ConfigError, match=words) as e:
        PMSMSaturation(**bad)  # type: ignore[arg-type]
    assert "saturation." in str(e.value)


def test_leaving_the_map_stops_the_run_naming_the_step_and_the_current():
    """pmsyrm_steady with a map said to hold 8 A: rated torque needs 11.9 A; the run stops at
    the step its current first lies beyond, naming it, the current and the range."""
    path = scenario_path("pmsyrm_steady")
    text = apply_settings(path.read_text(), {"plant.saturation.max_current": 8.0}, path)
    sc = load_scenario_text(text, path).with_duration(0.02)
    with pytest.raises(ConfigError, match=r"at step (\d+) .* leaves the range .* 8 A") as e:
        run_inprocess(sc)
    import re

    got = re.search(r"at step (\d+) .* i_d = (\S+) A, i_q = (\S+) A", str(e.value))
    assert got is not None
    k, i_d, i_q = int(got[1]), float(got[2]), float(got[3])
    assert math.hypot(i_d, i_q) > 8.0 and 0 < k < 400


def test_a_table_map_outside_its_fluxes_stops_naming_the_step():
    """A table covers the fluxes of its grid; a d-axis voltage that drives the flux beyond them
    stops the run with the step and the current (the plant's last within the map)."""
    tab = table_of(PMSYRM, PMSYRM_MOTOR)
    mm = magnetic_model(PMSYRM_MOTOR, tab)
    kw = dict(ts=TS, u_dc=540.0, load=StepProfile((0.0,), (0.0,)), max_substep=TS)
    kw["held_speed"] = StepProfile((0.0,), (0.0,))
    plant = SaturatedPMSMPlant(SaturatedPMSM(PMSYRM_MOTOR, mm), **kw)
    with pytest.raises(ConfigError, match=r"step \d+ .*i_d = .* A, i_q = .* leaves the range"):
        for k in range(4000):
            plant.step(command(k, (0.0, 0.0, 0.0, 1.0, 0.0, 0.0)))


def test_saturation_none_is_the_linear_plant_object():
    """model none (given, or left out) builds today's plant classes, not the saturated ones
    (test_fingerprints holds their recordings bit for bit)."""
    from predictive_drive.core.runner import build_plant

    sc = load_scenario("ipmsm_short")
    assert sc.plant.saturation is None
    path = scenario_path("ipmsm_short")
    given = load_scenario_text(
        apply_settings(path.read_text(), {"plant.saturation.model": "none"}, path), path
    )
    assert given.plant == sc.plant
    assert type(build_plant("pmsm", given.plant, ts=TS)) is PMSMPlant
    im = load_scenario("im_short")
    assert type(build_plant("induction", im.plant, ts=im.ts)) is InductionPlant


def test_a_saturation_setting_reaches_the_group_and_an_unknown_key_is_refused():
    path = scenario_path("im_short")
    text = apply_settings(
        path.read_text(),
        {"plant.saturation.model": "curve", "plant.saturation.flux_rated": 0.71},
        path,
    )
    sc = load_scenario_text(text, path)
    assert sc.plant.saturation == IMSaturation("curve", 0.71)
    with pytest.raises(ConfigError, match="no key 'lq_drop'"):
        apply_settings(path.read_text(), {"plant.saturation.lq_drop": 0.2}, path)
    with pytest.raises(ConfigError, match="flux_rated"):
        load_scenario_text(
            apply_settings(path.read_text(), {"plant.saturation.model": "curve"}, path), path
        )


def test_the_apparent_model_gives_the_maps_flux_and_torque():
    """mptc_pmsm with the map: the linear model it predicts with at a current (ψ_f' = ψ_d(0,
    i_q), L_d', L_q' secants) forms the map's flux and its torque there exactly."""
    fm = magnetic_model(PMSYRM_MOTOR, PMSYRM).flux_map
    model = ApparentModel(fm, PMSMCoefficients.of(PMSYRM_MOTOR))
    rng = random.Random(5)
    for _ in range(50):
        i = complex(rng.uniform(-15, 5), rng.uniform(-15, 15))
        theta = rng.uniform(0, 2 * math.pi)
        i_ab = i * complex(math.cos(theta), math.sin(theta))
        c = model.at(i_ab.real, i_ab.imag, theta)
        psi = complex(c.l_d * i.real + c.psi_f, c.l_q * i.imag)
        assert psi == pytest.approx(complex(*fm.flux(i.real, i.imag)), abs=1e-9)
        torque = c.torque_k * i.imag * (c.psi_f + (c.l_d - c.l_q) * i.real)
        assert torque == pytest.approx(fm.torque(i.real, i.imag, 2), abs=1e-8)


def test_the_maps_mtpa_on_a_linear_map_is_paper_002s_formula():
    """MTPA found on the map by search (linear map of paper 001's IPMSM) against the closed
    form (paper 002 eq 10, mtpa_point): the same current and angle to the grids' resolution."""
    fm = magnetic_model(IPMSM, LINEAR).flux_map
    mtpa = MapMTPA(fm, 3)
    for torque in (5.0, 15.0, 25.0):
        amp, theta = mtpa.mtpa(torque)
        exact = mtpa_point(torque, p=3, psi_f=IPMSM.psi_f, l_d=IPMSM.l_d, l_q=IPMSM.l_q)
        assert amp == pytest.approx(exact.i_s, rel=2e-3)
        assert theta == pytest.approx(exact.theta, abs=5e-3)
        assert mtpa.zero_d(torque) == pytest.approx(exact.i_s_zero_d, rel=1e-3)


def test_knowing_the_map_buys_torque_accuracy():
    """pmsyrm_steady, mptc: the linear nominal controller misses T* by several N·m; given the
    map (torque_controller.saturation as the plant's), it tracks within 1.5 N·m. foc_formula
    with the map reaches rated torque from its MTPA table."""
    path = scenario_path("pmsyrm_steady")
    sc = load_scenario(path, duration=0.08)
    own = {
        f"torque_controller.saturation.{f.name}": getattr(sc.plant.saturation, f.name)
        for f in dataclasses.fields(PMSMSaturation)
        if not f.name.startswith(("i_", "psi_d", "psi_q"))
    }
    mapped = load_scenario_text(apply_settings(path.read_text(), own, path), path)
    mapped = mapped.with_duration(0.08)
    from predictive_drive.api.report import metrics_of

    def t_rmse(s):  # over 0.05-0.08 s
        tr = run_inprocess(s)
        return metrics_of(tr, s).t_rmse

    nominal, knowing = t_rmse(sc), t_rmse(mapped)
    assert nominal > 3.0 and knowing < 1.5, (nominal, knowing)


@pytest.mark.parametrize("law", ["foc_formula", "foc_zero_d"])
def test_field_orientation_takes_its_current_for_t_star_from_the_map(law):
    """foc_pmsm with the map: the current reference for rated torque is the map's MTPA point
    (foc_formula) or its i_d = 0 current (foc_zero_d), and the map's torque there is T*;
    without the map it is the linear model's."""
    from predictive_drive.core.control.foc_pmsm import FOCController, FOCParams
    from predictive_drive.core.plant import PERIOD_MEANS
    from predictive_drive.core.signals import Reference, State

    given = (0.0, 0.0, 0.0, 0.0, 10.0, 0.0, 540.0, *(0.0,) * 6, 0.0, 0.0, 10.0, 0.0,
             *(0.0,) * len(PERIOD_MEANS))  # fmt: skip
    state = State(*given, *(math.nan,) * (len(State._fields) - len(given)))  # the rest: NaN
    ref = Reference(0, 0, 29.7, 0.94, 10.0)
    fm = magnetic_model(PMSYRM_MOTOR, PMSYRM).flux_map
    mapped = FOCController(FOCParams(PMSYRM_MOTOR, law, saturation=PMSYRM), ts=1e-4)
    mapped.step(state, ref)
    assert fm.torque(mapped.i_ref.real, mapped.i_ref.imag, 2) == pytest.approx(29.7, rel=1e-3)
    if law == "foc_zero_d":
        assert mapped.i_ref.real == 0.0
    else:  # the MTPA point: no other angle makes rated torque with less current
        amp = abs(mapped.i_ref)
        for th in np.linspace(-0.3, 1.3, 200):
            i = amp * 0.995 * complex(-math.sin(th), math.cos(th))
            assert fm.torque(i.real, i.imag, 2) < 29.7
    linear = FOCController(FOCParams(PMSYRM_MOTOR, law), ts=1e-4)
    linear.step(state, ref)
    assert abs(fm.torque(linear.i_ref.real, linear.i_ref.imag, 2) - 29.7) > 1.0


def test_the_published_machines_transient_runs_and_rates_the_map():
    """pmsyrm_short (held speed, T* steps to rated and down): the linear mptc runs it within the
    map's range, worse than when it knows the map."""
    from predictive_drive.api.report import metrics_of

    path = scenario_path("pmsyrm_short")
    sc = load_scenario(path, duration=0.12)
    own = {f"torque_controller.saturation.{k}": v for k, v in _PMSYRM_SETTINGS.items()}
    mapped = load_scenario_text(apply_settings(path.read_text(), own, path), path)
    mapped = mapped.with_duration(0.12)
    linear, knowing = (metrics_of(run_inprocess(s), s).t_rmse for s in (sc, mapped))
    assert knowing < 0.6 * linear, (linear, knowing)


_PMSYRM_SETTINGS = {
    "model": "algebraic", "a_d0": 3.96, "a_dd": 28.5, "s": 4.0, "a_q0": 5.89, "a_qq": 2.67,
    "t": 6.0, "a_dq": 41.5, "u": 1.0, "v": 1.0, "psi_n": 0.804, "a_b": 81.75, "a_bp": 1.0,
    "w": 2.0, "k_q": 0.1, "max_current": 25.0,
}  # fmt: skip


def test_losses_on_a_saturating_machine_are_refused_before_the_run():
    """The loss ledger needs the machine's temperature model and flux hooks, which only the
    linear machines have: the combination is refused naming both keys, not a traceback."""
    from predictive_drive.api.run import run
    from predictive_drive.errors import ConfigError

    for key, value in (("plant.losses.device", "wolfspeed_c3m0065100j"),
                       ("plant.losses.machine", True)):  # fmt: skip
        with pytest.raises(ConfigError, match="plant.losses with plant.saturation"):
            run("pmsyrm_short", engine="inprocess", duration=0.001, settings={key: value})
