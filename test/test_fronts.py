"""The fronts study (docs/reproduction.md#fronts-distortion-against-switching-frequency): the
front of a curve, its interpolation, a small study run for real, and what it refuses."""

from __future__ import annotations

import dataclasses
import json
import math

import pytest

from predictive_drive import cli
from predictive_drive.api.fronts import (
    FrontsChoice,
    FrontsResult,
    interpolate,
    joined,
    pareto,
    prediction_setting,
    reading,
    reproduce_fronts,
    subset,
    with_knob_values,
)
from predictive_drive.api.reproduce import reproduce
from predictive_drive.api.study import studying
from predictive_drive.errors import ConfigError
from predictive_drive.reports.fronts import (
    COMMON_FSW,
    FRONTS,
    IGBT,
    PERIODS,
    PREDICTION,
    Curve,
    OperatingPoint,
    loss_interpolate,
    loss_reading,
)

NAN = math.nan


@pytest.mark.core
@pytest.mark.parametrize(
    ("points", "front"),
    [
        ([(1e3, 2.0), (2e3, 1.0), (3e3, 0.5)], [True, True, True]),
        ([(1e3, 2.0), (2e3, 3.0), (3e3, 0.5)], [True, False, True]),  # more switching, worse
        ([(2e3, 1.0), (2e3, 1.5)], [True, False]),  # the same f_sw, worse
        ([(2e3, 1.0), (2e3, 1.0)], [True, True]),  # equal: neither beats the other
        ([(1e3, NAN), (2e3, 1.0)], [False, True]),  # a point that left the operating point
    ],
    ids=["falling", "dominated", "same-fsw", "equal", "nan"],
)
def test_the_front_is_what_no_other_point_beats_in_both(points, front):
    assert pareto(points) == front


@pytest.mark.core
def test_a_front_is_interpolated_log_log_and_not_beyond_its_ends_or_across_a_gap():
    front = [(1e3, 1.0), (2e3, 0.5), (4e3, 0.25)]  # figure ∝ 1/f_sw
    assert interpolate(front, 1.5e3) == pytest.approx(1 / 1.5, rel=1e-12)
    assert interpolate(front, 1e3) == 1.0 and interpolate(front, 4e3) == 0.25
    assert interpolate(front, 969.0) is None and interpolate(front, 4130.0) is None
    assert interpolate([(5e3, 0.3)], 5e3) == 0.3 and interpolate([], 5e3) is None
    gap = [(1e3, 1.0), (2.5e3, 0.4)]  # more than twice apart: not known in between
    assert interpolate(gap, 2e3) is None and interpolate(gap, 2.5e3) == 0.4


@pytest.mark.core
def test_a_measured_point_near_a_column_is_read_as_is_and_no_front_is_read_across_a_jump():
    """Within 3 % of a column a front's point is the column's value, as measured (direct_mpc
    N = 1 had a point at 1.013 kHz and '-' at 1 kHz: its lower neighbour was far); between two
    neighbours whose figure steps by more than the cube of their f_sw ratio the front jumps from
    one way of switching to another and the table says '-' (db_mptc's THD from 43.7 % at 6.51
    kHz to 10.0 % at 7.29 kHz was read as 17.1 % at 7 kHz)."""
    assert interpolate([(0.4e3, 9.0), (1.013e3, 5.0)], 1e3) == 5.0
    assert reading([(0.4e3, 9.0), (1.013e3, 5.0)], 1e3) == (1, 1, 0.0)
    assert interpolate([(1.04e3, 5.0)], 1e3) is None  # 4 %: not the column's
    jump = [(6.51e3, 0.437), (7.29e3, 0.100)]
    assert not joined(*jump) and interpolate(jump, 7e3) is None
    steep = [(2.43e3, 0.478), (3.40e3, 0.189)]  # MPTC's THD as λ_sw rises: steep, one regime
    assert joined(*steep) and interpolate(steep, 3e3) == pytest.approx(0.27, abs=0.01)


SMALL = {
    "im_steady": OperatingPoint(
        "paper 000's IM, four small curves",
        (
            Curve(
                "mptc",
                "im_steady",
                "torque_controller.lambda_sw",
                (0.0, 0.3),
                periods=(1e-4,),
                period_values=1,
            ),
            Curve("ifoc", "im_steady_foc", "ts", (5e-4, 2.5e-4)),
            Curve("mptc_db", "im_steady", "torque_controller.lambda_sw", (0.2,)),
            Curve(
                "mptc",
                "im_steady",
                "torque_controller.lambda_sw",
                (0.1,),
                {"torque_controller.horizon": 2},
                label="mptc N=2",
            ),
            Curve(
                "mptc",
                "im_steady",
                "torque_controller.lambda_e",
                (250.0,),
                {"torque_controller.device": IGBT},
                label="mptc lambda_e",
            ),
        ),  # fmt: skip
        ("mptc",),
        "a test",
        "im_steady",
        IGBT,
        (10.0, 12.0, 13.0, 16.0),
    )
}


@pytest.fixture(scope="module")
def small(tmp_path_factory) -> tuple[FrontsResult, list]:
    told: list = []
    with studying(None, jobs=2, progress=lambda *a: told.append(a)) as runner:
        result = reproduce_fronts(runner, study=SMALL, figures=tmp_path_factory.mktemp("figures"))
    return result, told


@pytest.mark.core
def test_a_small_study_traces_each_curve_over_its_knob_and_period(small):
    """The switching effort and a longer period lower MPTC's f_sw; FOC switches at its carrier,
    1/Ts; the table reads each front at the common frequencies and ranks the curves by what it
    read; the progress names each run's curve."""
    d, told = small
    (t,) = d.points
    mptc, foc, db, longer, energy = t.curves
    assert longer.name == "mptc N=2" and longer.settings == {"torque_controller.horizon": 2}
    assert [(p.value, p.ts) for p in mptc.points] == [(0.0, 5e-5), (0.3, 5e-5), (0.0, 1e-4)]
    f_mptc = [p.figures["f_sw_hz"] for p in mptc.points]
    assert f_mptc[0] > f_mptc[1] > 1e3 and f_mptc[0] > f_mptc[2] > 1e3
    assert [p.figures["f_sw_hz"] for p in foc.points] == pytest.approx([2e3, 4e3], rel=1e-9)
    assert [(p.value, p.ts) for p in foc.points] == [(5e-4, 5e-4), (2.5e-4, 2.5e-4)]
    assert all(p.holds for c in (mptc, foc, longer) for p in c.points)
    assert t.torque_ref == 3.0 and t.flux_ref == 0.71
    for key in ("t_ripple_cont", "i_thd_cont", "t_rmse_cont", "i_tdd_cont"):
        assert t.at[key]["ifoc"][COMMON_FSW.index(2e3)] == foc.points[0].figures[key]
        for i in range(len(COMMON_FSW)):
            known = {n: v[i] for n, v in t.at[key].items() if v[i] is not None}
            assert t.ranking[key][i] == sorted(known, key=known.get)
    assert (
        t.torque_miss_at["t_ripple_cont"]["ifoc"][COMMON_FSW.index(2e3)]
        == (foc.points[0].misses["torque"])
    )
    assert sorted({name for *_, name in told}) == [
        "im_steady ifoc", "im_steady mptc", "im_steady mptc N=2", "im_steady mptc lambda_e",
        "im_steady mptc_db",
    ]  # fmt: skip
    assert [told[-1][0], told[-1][1]] == [d.runs, d.runs] == [8, 8]
    assert [p.name for p in d.figures] == ["fronts_im_steady.png", "fronts_im_steady_loss.png"]
    json.dumps(d.as_dict())  # --json prints it


@pytest.mark.core
def test_a_front_against_loss_is_read_in_one_regime_judged_by_f_sw():
    """Against the inverter's loss a column reads a front's point within 0.5 % as measured,
    else interpolates log-log between the neighbours that enclose it — if they are one regime
    by the f_sw rule on their own (f_sw, figure): at most twice apart in f_sw, the figure
    stepping by no more than the cube of their f_sw ratio, whichever way f_sw runs with the
    loss; else None."""
    front = [(10.0, 0.30, 2000.0), (12.0, 0.20, 3000.0), (14.0, 0.19, 3500.0)]
    assert loss_interpolate(front, 11.0) == pytest.approx(
        math.exp(math.log(0.3) + math.log(1.1) / math.log(1.2) * math.log(0.2 / 0.3)), rel=1e-12
    )
    assert loss_interpolate(front, 10.04) == 0.30 and loss_interpolate(front, 14.0) == 0.19
    assert loss_interpolate(front, 9.9) is None and loss_interpolate(front, 14.2) is None
    assert loss_reading(front, 13.0) == (1, 2, pytest.approx(math.log(13 / 12) / math.log(14 / 12)))
    jump = [(10.0, 0.5, 2000.0), (12.0, 0.1, 2400.0)]  # 5-fold over 1.2 in f_sw: two regimes
    assert loss_interpolate(jump, 11.0) is None
    gap = [(10.0, 0.3, 1000.0), (12.0, 0.2, 2500.0)]  # close in loss, 2.5 times apart in f_sw
    assert loss_interpolate(gap, 11.0) is None
    falling = [(10.0, 0.3, 3000.0), (12.0, 0.2, 2000.0)]  # f_sw falls as the loss rises
    assert loss_interpolate(falling, 11.0) is not None


@pytest.mark.core
def test_a_point_on_the_front_of_f_sw_may_be_beaten_at_equal_loss():
    """Which front a point lies on depends on the axis: B switches twice as often as A at less
    loss (it commutates at lower currents) and lower ripple, so both are on the front against
    f_sw, B alone on the front against the loss; a run that left the operating point on none."""
    from predictive_drive.api.fronts import FrontPoint, on_fronts

    def point(f, w, v, holds=True):
        figures = dict.fromkeys(("t_ripple_cont", "t_rmse_cont", "i_thd_cont", "i_tdd_cont"), v)
        return FrontPoint(0.0, 5e-5, {**figures, "f_sw_hz": f, "p_inverter": w}, {}, holds, "",
                          {}, 0.0)  # fmt: skip

    a, b, lost = on_fronts(
        [point(1e3, 10.0, 0.5), point(2e3, 9.0, 0.4), point(5e2, 1.0, 0.1, False)]
    )
    assert all(a.on_front.values()) and all(b.on_front.values())
    assert not any(a.on_loss_front.values()) and all(b.on_loss_front.values())
    assert not any(lost.on_front.values()) and not any(lost.on_loss_front.values())


@pytest.mark.core
def test_every_run_books_its_inverter_loss_and_the_fronts_are_ranked_at_equal_loss(small):
    """Every run of the study has the point's device: its inverter loss the sum of the
    transistors' and diodes' conduction and switching losses; a curve's front against the loss
    is its held points no other beats in both loss and figure; the columns read it by
    :func:`loss_interpolate` and rank the curves lowest first; the loss-aware weight at 250
    N·m/J commutates less energy per commutation than the papers' law."""
    d, _ = small
    (t,) = d.points
    assert t.device == IGBT and t.loss_columns == (10.0, 12.0, 13.0, 16.0)
    for c in t.curves:
        held = [p for p in c.points if p.holds]
        for p in c.points:
            f = p.figures
            parts = f["p_cond_t"] + f["p_cond_d"] + f["p_sw_t"] + f["p_sw_d"]
            assert f["p_inverter"] == pytest.approx(parts, rel=1e-12) and f["p_sw_t"] > 0
        for key in ("t_ripple_cont", "i_thd_cont"):
            beaten = {
                id(p) for p in held for q in held
                if q is not p and q.figures["p_inverter"] <= p.figures["p_inverter"]
                and q.figures[key] <= p.figures[key]
                and (q.figures["p_inverter"], q.figures[key]) != (p.figures["p_inverter"],
                                                                  p.figures[key])
            }  # fmt: skip
            assert {id(p) for p in c.loss_front(key)} == {id(p) for p in held} - beaten
            triples = [
                (p.figures["p_inverter"], p.figures[key], p.figures["f_sw_hz"])
                for p in c.loss_front(key)
            ]
            want = [loss_interpolate(triples, w) for w in t.loss_columns]
            assert t.at_loss[key][c.name] == want
    for key, ranked in t.ranking_loss.items():
        for i in range(len(t.loss_columns)):
            known = {n: v[i] for n, v in t.at_loss[key].items() if v[i] is not None}
            assert ranked[i] == sorted(known, key=known.get)
    assert any(v is not None for v in t.at_loss["t_ripple_cont"]["ifoc"])
    mptc, energy = t.curves[0].points[0].figures, t.curves[-1].points[0].figures
    per_turn_on = [(f["p_sw_t"] + f["p_sw_d"]) / f["f_sw_hz"] for f in (mptc, energy)]
    assert per_turn_on[1] < per_turn_on[0]


@pytest.mark.core
def test_a_run_that_misses_the_operating_point_is_listed_with_its_miss_not_on_a_front(small):
    """The operating point held within 2 % of T* (mean torque), of ψ* (mean |ψ_s|) and of the
    point's current (the fundamental): MPTC-DB at λ_sw = 0.2 misses T* by 8 % and is listed with
    it, on no front, in no column; the point's current is what FOC asks at T*, ψ*, and each
    run's TDD is its distortion over it (its THD times its fundamental over the base)."""
    d, _ = small
    (t,) = d.points
    db = t.curves[2]
    (p,) = db.points
    assert not p.holds and p.misses["torque"] == pytest.approx(-0.083, abs=0.003)
    assert p.reason.startswith("left the operating point: mean torque -8.")
    assert not any(p.on_front.values())
    assert all(v is None for key in t.at for v in t.at[key]["mptc_db"])
    (e,) = t.excluded
    assert (e.curve, e.value, e.ts, e.reason) == ("mptc_db", 0.2, 5e-5, p.reason)
    assert t.base_current_a == pytest.approx(3.901, abs=1e-3)
    for c in t.curves:
        for q in c.points:
            tdd = q.figures["i_thd_cont"] * q.figures["i_fundamental_cont"] / t.base_current_a
            assert q.figures["i_tdd_cont"] == pytest.approx(tdd, rel=1e-12)
            assert q.misses["torque"] == q.figures["t_mean_error_cont"] / 3.0
    assert d.as_dict()["tolerance"] == {"torque": 0.02, "flux": 0.02, "current": 0.02}


@pytest.mark.core
def test_the_figures_give_each_curve_its_colour_and_marker_and_no_line_across_a_gap(small):
    """Every curve of a figure its own colour and marker; a front's line only between the
    neighbours the table reads between (:func:`joined`): none across a jump."""
    from predictive_drive.reports.figures import fronts_figures

    d, _ = small
    (t,) = d.points
    mptc = t.curves[0]
    # a front with a jump: MPTC's points moved so that its two held points step 5-fold
    jumped = [
        dataclasses.replace(
            p, figures={**p.figures, "f_sw_hz": f, "t_ripple_cont": v},
            on_front={**p.on_front, "t_ripple_cont": True},
        )
        for p, (f, v) in zip(mptc.points, [(4e3, 0.5), (5e3, 0.1), (3e3, 0.6)])
    ]  # fmt: skip
    curves = [dataclasses.replace(mptc, points=jumped), *t.curves[1:]]
    figs = fronts_figures(dataclasses.replace(d, points=[dataclasses.replace(t, curves=curves)]))
    ax = figs["im_steady"].axes[0]  # T_ripple cont
    dots = [
        ln for ln in ax.get_lines() if ln.get_linestyle() == "None" and ln.get_label()[0] != "_"
    ]
    assert [ln.get_label() for ln in dots] == [c.name for c in t.curves]
    assert len({ln.get_color() for ln in dots}) == len({ln.get_marker() for ln in dots}) == 5
    segments = [
        ln
        for ln in ax.get_lines()
        if ln.get_linestyle() != "None" and ln.get_color() == dots[0].get_color()
    ]
    assert [list(ln.get_xdata()) for ln in segments] == [[3.0, 4.0]]  # not 4 → 5: a jump
    import matplotlib.pyplot as plt

    plt.close("all")


@pytest.mark.core
def test_the_knobs_values_are_checked_before_anything_runs(monkeypatch):
    ran = []
    monkeypatch.setattr("predictive_drive.api.study.run_cases", lambda *a, **k: ran.append(a))
    for kw, words in [
        ({"lambda_sw": [0.1, -0.2]}, "--lambda-sw: -0.2 is outside 0..1000"),
        ({"lambda_sw": [math.inf]}, "--lambda-sw: inf is outside 0..1000"),
        ({"fsw_khz": [5.0, 200.0]}, "--fsw-khz: 200.0 is outside 0.1..100 kHz"),
        ({"fsw_khz": [0.0]}, "--fsw-khz: 0.0 is not a positive number of kHz"),
        ({"lambda_sw": []}, "--lambda-sw: give at least one value"),
        ({"periods_us": [50.0, 2e5]}, r"--periods-us: 200000.0 is outside 10..10000"),
        ({"points": ["im_stedy"]}, "--points im_stedy: not an operating point of the study; "
         "one of im_steady, ipmsm_steady, hs_ipmsm_steady"),
        ({"points": ["im_steady"], "curves": ["direct_mpc N=3"]}, r"--curves direct_mpc N=3: "
         r"no curve of that name at im_steady; the curves: db_mptc, ifoc, mptc, mptc N=2"),
        ({"label": "mine"}, "--label and --knob name and trace a controller of your own"),
        ({"external": "x"}, "--external: your controller goes on one operating point; choose "
         "it with --points"),
        ({"external": "x", "points": ["im_steady"], "knobs": {"plant.u_dc": [1]}},
         r"--knob plant.u_dc: your controller is traced over one of its own parameters"),
        ({"external": "x", "points": ["im_steady"], "label": "a:b"}, "--label 'a:b'"),
    ]:  # fmt: skip
        with pytest.raises(ConfigError, match=words):
            reproduce("fronts", fronts=FrontsChoice(**kw))
    with pytest.raises(ConfigError, match="--set torque_controller.lambda_sw: the fronts study"):
        reproduce("fronts", settings={"torque_controller.lambda_sw": 0.1})
    with pytest.raises(ConfigError, match=r"--set ts: the fronts study sweeps it"):
        reproduce("fronts", settings={"ts": 1e-4})
    with pytest.raises(ConfigError, match="dead_time"):  # refused by the scenario: Ts/10
        reproduce("fronts", settings={"plant.dead_time": 1e-5})
    with pytest.raises(ConfigError, match="not on the ros engine"):
        reproduce("fronts", engine="ros")
    with pytest.raises(ConfigError, match="--lambda-sw, --lambda-u, --fsw-khz, --periods-us"):
        reproduce("im_paper", fronts=FrontsChoice(lambda_sw=[0.1]))
    assert not ran


@pytest.mark.core
def test_given_values_replace_every_curves_own():
    study = with_knob_values(
        FRONTS, lambda_sw=[0.0, 0.1], fsw_khz=[2.0, 10.0], lambda_u=[0.5], periods_us=[100.0]
    )
    wants = {
        "torque_controller.lambda_sw": (0.0, 0.1),
        "torque_controller.lambda_u": (0.5,),
        "ts": (5e-4, 1e-4),
    }
    own = {(n, c.name): c.values for n, op in FRONTS.items() for c in op.curves}
    for name, op in study.items():
        for c in op.curves:
            if c.knob == "torque_controller.lambda_e":  # its own values, the papers' period
                assert c.values == own[(name, c.name)] and c.periods == ()
                continue
            assert c.values == pytest.approx(wants[c.knob])
            assert c.periods == (() if c.knob == "ts" else (1e-4,))
    with pytest.raises(ConfigError, match="--lambda-u: 0.0 is outside 1e-09..1000"):
        with_knob_values(FRONTS, lambda_u=[0.0])
    alone = with_knob_values(FRONTS, periods_us=[])
    assert all(c.periods == () for op in alone.values() for c in op.curves)


@pytest.mark.core
def test_the_period_sweep_runs_each_fcs_curves_two_smallest_values_at_every_period():
    """The stated rule: at the papers' 50 µs every value of the curve's knob, at each of the
    other periods (20-500 µs, about 1.6 times apart) its two smallest; FOC over its carrier;
    the loss-aware weight at the papers' period alone."""
    for op in FRONTS.values():
        for c in op.curves:
            points = c.points()
            if c.knob in ("ts", "torque_controller.lambda_e"):
                assert points == [{c.knob: v} for v in c.values] and not c.periods
                continue
            assert c.periods == PERIODS
            assert points[: len(c.values)] == [{c.knob: v} for v in c.values]
            two = sorted(c.values)[:2]
            assert points[len(c.values) :] == [{"ts": t, c.knob: v} for t in PERIODS for v in two]
    ratios = [b / a for a, b in zip(sorted((*PERIODS, 5e-5)), sorted((*PERIODS, 5e-5))[1:])]
    assert max(ratios) < 1.7 and min(PERIODS) == 2e-5 and max(PERIODS) == 5e-4


@pytest.mark.core
def test_subsets_choose_points_curves_and_horizons():
    s = subset(FRONTS, points=["im_steady", "ipmsm_steady"], horizons=False)
    assert list(s) == ["im_steady", "ipmsm_steady"]
    assert [c.name for c in s["im_steady"].curves] == [
        "mptc", "mptc_db", "db_mptc", "mptc lambda_e", "ifoc"
    ]  # fmt: skip
    assert "direct_mpc N=1" in [c.name for c in s["ipmsm_steady"].curves]
    assert all(c.horizon == 1 for op in s.values() for c in op.curves)
    one = subset(FRONTS, curves=["ifoc", "foc_formula"])
    assert {n: [c.name for c in op.curves] for n, op in one.items()} == {
        "im_steady": ["ifoc"], "ipmsm_steady": ["foc_formula"],
        "hs_ipmsm_steady": ["foc_formula"],
    }  # fmt: skip
    names = {c.name for op in FRONTS.values() for c in op.curves}
    assert "foc_mtpa" not in names and "foc_formula" in names  # one name per strategy


@pytest.mark.core
def test_the_pmsm_prediction_is_the_rotor_motions_wherever_a_family_declares_it():
    """The finite-control-set PMSM families run the fronts with the rotor-motion compensated
    prediction where their settings declare ``prediction``; a family without the field, a field-
    oriented one or an induction motor's runs as it is, and each curve says what it used."""
    from types import SimpleNamespace

    from predictive_drive.config import load_scenario
    from predictive_drive.core.machines import Machine

    @dataclasses.dataclass(frozen=True)
    class WithChoice:
        prediction: str = "frozen_rotor"

    @dataclasses.dataclass(frozen=True)
    class Without:
        gain: float = 1.0

    pmsm = SimpleNamespace(machine=Machine.PMSM, controller=WithChoice())
    assert prediction_setting(pmsm) == {"torque_controller.prediction": PREDICTION}
    assert prediction_setting(SimpleNamespace(machine=Machine.PMSM, controller=Without())) == {}
    im = SimpleNamespace(machine=Machine.INDUCTION, controller=WithChoice())
    assert prediction_setting(im) == {}
    from predictive_drive.api.fronts import FROZEN_ONLY, _prediction
    from predictive_drive.config import apply_settings, load_scenario_text, resolve_scenario_path

    for name in ("ipmsm_steady", "ipmsm_steady_mpc", "im_steady", "ipmsm_steady_foc"):
        sc = load_scenario(name)
        has = "prediction" in {f.name for f in dataclasses.fields(sc.controller)}
        fcs = name != "ipmsm_steady_foc" and sc.machine == Machine.PMSM
        extra = prediction_setting(sc)
        assert bool(extra) == (has and fcs)
        path = resolve_scenario_path(name)
        ran = load_scenario_text(apply_settings(path.read_text(), extra, path), path)
        said = _prediction(ran)  # what the curve reports: read from the settings applied
        assert said == (None if not fcs else PREDICTION if has else FROZEN_ONLY)


@pytest.mark.core
def test_the_command_offers_the_subsets_and_refuses_a_choice_of_another_reproduction(capsys):
    assert cli.main(["reproduce", "im_paper", "--lambda-sw", "0.1"]) == 2
    assert "--lambda-sw" in capsys.readouterr().err
    assert cli.main(["reproduce", "im_paper", "--no-horizons"]) == 2
    assert "--no-horizons chooses the fronts study's runs" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:  # argparse's usage error
        cli.main(["reproduce", "fronts", "--fsw-khz", "1,x"])
    assert e.value.code == 2
    assert "expected numbers separated by commas, got '1,x'" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        cli.main(["reproduce", "--help"])
    said = " ".join(capsys.readouterr().out.split())
    for option in ("--points", "--curves", "--no-horizons", "--periods-us", "--external",
                   "--label", "--knob", "im_steady, ipmsm_steady, hs_ipmsm_steady",
                   "mptc N=2", "foc_formula", "20,32,80,125,200,320,500"):  # fmt: skip
        assert option in said, option
    assert cli.main(["reproduce", "fronts", "--external", "speed_pi=x", "--points",
                     "im_steady"]) == 2  # fmt: skip
    assert "torque_controller=COMMAND" in capsys.readouterr().err


@pytest.mark.core
def test_runs_more_than_a_fifth_apart_in_f_sw_are_said_not_to_compare():
    from predictive_drive.core.metrics import unequal_switching

    assert unequal_switching({"a": 4000.0, "b": 4800.0}) is None  # 20 %: still comparable
    text = unequal_switching({"mptc": 4690.0, "db_mptc": 8120.0, "x": NAN})
    assert text.startswith("not comparable at equal switching frequency: f_sw 4.69 kHz (mptc) to")
    assert "8.12 kHz (db_mptc), 1.7 times" in text
    assert unequal_switching({"a": 4000.0}) is None


@pytest.mark.core
def test_compare_says_when_its_runs_switch_too_differently(tmp_path, capsys):
    from predictive_drive.api.run import run

    bags = []
    for s in ("mptc", "db_mptc"):
        bags.append(str(run("im_short", strategy=s, engine="inprocess", duration=0.1,
                            out=tmp_path / s).bag))  # fmt: skip
    assert cli.main(["compare", *bags]) == 0
    out = capsys.readouterr().out
    assert (
        "note: not comparable at equal switching frequency" in out and "(im_short db_mptc)" in out
    )
    assert "T_ripple cont N·m" in out


@pytest.mark.process
def test_your_controller_is_drawn_on_a_front_through_the_ros_graph(tmp_path):
    """The example DTC node (examples/dtc_im) on paper 000's steady point over its own
    torque_band, run through the ROS graph beside the built-in FOC (in-process): its points are
    checked against the operating point by the same rule, drawn on the same figure and read
    into the same table. Short: 0.3 s runs, the window 0.2-0.3 s."""
    import shlex
    import sys
    from pathlib import Path

    from predictive_drive.api.fronts import external_curve

    example = Path(__file__).resolve().parents[1] / "examples" / "dtc_im" / "dtc_im" / "dtc_node.py"
    command = f"{shlex.quote(sys.executable)} {shlex.quote(str(example))}"
    point = OperatingPoint(
        "paper 000's IM", (Curve("ifoc", "im_steady_foc", "ts", (2.5e-4,)),), (), "", "im_steady"
    )
    study = external_curve(
        {"im_steady": point}, command, label="dtc",
        knobs={"torque_controller.torque_band": [0.05, 0.2]},
    )  # fmt: skip
    window = {
        "metrics_logger.window_start": 0.2, "metrics_logger.window_end": 0.3,
        "metrics_logger.thd_window": [0.2, 0.3],
    }  # fmt: skip
    with studying(None, duration=0.3) as runner:
        d = reproduce_fronts(runner, study=study, settings=window, figures=tmp_path / "figures")
        bags = list(runner.bags)
    (t,) = d.points
    foc, dtc = t.curves
    assert (dtc.name, dtc.strategy, dtc.external) == ("external:dtc", "external:dtc", command)
    assert [(p.value, p.ts) for p in dtc.points] == [(0.05, 5e-5), (0.2, 5e-5)]
    wide, narrow = dtc.points[1], dtc.points[0]
    assert 1e2 < wide.figures["f_sw_hz"] < narrow.figures["f_sw_hz"] < 2e4  # a wider band
    for p in dtc.points:
        assert all(math.isfinite(p.figures[k]) for k in ("t_ripple_cont", "i_thd_cont"))
        assert p.holds == all(abs(v) <= d.tolerance[k] for k, v in p.misses.items())
        assert p.holds or any(e.value == p.value for e in t.excluded if e.curve == dtc.name)
    assert set(t.at["t_ripple_cont"]) == {"ifoc", "external:dtc"}
    (figure,) = d.figures
    assert figure.stat().st_size > 20_000
    assert bags and not any(Path(b).exists() for b in bags)  # recorded where needed, removed


@pytest.mark.core
def test_a_figure_with_nothing_for_its_log_axes_says_so(tmp_path):
    """A study too short to hold its current's cycles (--duration 0.02) has no THD to draw:
    the panel says so, the figure is drawn (was: a matplotlib traceback, 'Data cannot be
    log-scaled', exit 1, no table); a point with nothing in any panel is not drawn and a note
    names it."""
    from predictive_drive.api.fronts import FrontsChoice
    from predictive_drive.reports.figures import fronts_figures

    choice = FrontsChoice(points=["im_steady"], curves=["mptc", "ifoc"], periods_us=[],
                          lambda_sw=[0.0], fsw_khz=[2.0, 5.0])  # fmt: skip
    d = reproduce("fronts", duration=0.02, figures=tmp_path, fronts=choice)
    names = [p.name for p in d.figures]
    assert names == ["fronts_im_steady.png", "fronts_im_steady_loss.png"] and not d.figure_notes
    for c in d.points[0].curves:
        for p in c.points:
            p.figures.update(dict.fromkeys(p.figures, math.nan))
    notes: list[str] = []
    assert fronts_figures(d, notes) == {}
    assert notes == [
        "im_steady: no figure drawn: no run has a positive f_sw and figure to put on log axes "
        "(a run too short to switch?)"
    ]


@pytest.mark.core
def test_a_run_whose_junction_went_above_its_rating_is_off_the_fronts():
    """A run whose hottest junction over the window went above its device's rated T_j is not a
    point a drive can run at: its reason names the device position, the temperature, when, and
    the rating, whatever its misses (ipmsm_steady's MPTC at λ_sw 0.04 ran away to 752 °C)."""
    from types import SimpleNamespace

    from predictive_drive.api.fronts import overheated
    from predictive_drive.config import read_device

    sic = read_device("wolfspeed_c3m0065100j", "test")
    hot = SimpleNamespace(tj_max=752.5, tj_max_device="ta_hi", tj_max_t=0.1234)
    assert overheated(hot, sic) == (
        "a junction above its rating: 752.5 °C in ta_hi at 0.1234 s (rated 150 °C)"
    )
    assert overheated(SimpleNamespace(tj_max=150.0, tj_max_device="da_lo", tj_max_t=0.1), sic) == ""
    assert overheated(hot, None) == ""  # no device: nothing booked
    assert overheated(SimpleNamespace(tj_max=math.nan, tj_max_device="", tj_max_t=0.0), sic) == ""
    igbt = read_device("semikron_skm150gb124d", "test")
    assert igbt.diode.t_j_max == 150.0
    assert "in dc_lo" in overheated(SimpleNamespace(tj_max=151.0, tj_max_device="dc_lo",
                                                    tj_max_t=0.2), igbt)  # fmt: skip


@pytest.mark.core
def test_a_figure_not_measured_is_said_so_not_nan():
    """A window without a whole cycle has no current fundamental: the reason says 'not
    measured' (was '+nan %'), and the run does not hold the point."""
    from types import SimpleNamespace

    from predictive_drive.api.fronts import held

    m = SimpleNamespace(
        t_mean_error_cont=0.01, psi_mean_error_cont=0.0, i_fundamental_cont=math.nan
    )
    misses, reason = held(m, 3.0, 0.71, 3.9)
    assert math.isnan(misses["current"]) and "nan" not in reason
    assert reason.startswith("left the operating point: current's fundamental not measured")
