"""The fronts study (docs/reproduction.md#fronts-distortion-against-switching-frequency): the
front of a curve, its interpolation, a small study run for real, and what it refuses."""

from __future__ import annotations

import json
import math

import pytest

from predictive_drive import cli
from predictive_drive.api.fronts import (
    FrontsResult,
    interpolate,
    pareto,
    reproduce_fronts,
    with_knob_values,
)
from predictive_drive.api.reproduce import reproduce
from predictive_drive.api.study import studying
from predictive_drive.errors import ConfigError
from predictive_drive.reports.fronts import COMMON_FSW, FRONTS, Curve, OperatingPoint

pytestmark = pytest.mark.core

NAN = math.nan


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


def test_a_front_is_interpolated_log_log_and_not_beyond_its_ends_or_across_a_gap():
    front = [(1e3, 1.0), (2e3, 0.5), (4e3, 0.25)]  # figure ∝ 1/f_sw
    assert interpolate(front, 1.5e3) == pytest.approx(1 / 1.5, rel=1e-12)
    assert interpolate(front, 1e3) == 1.0 and interpolate(front, 4e3) == 0.25
    assert interpolate(front, 999.0) is None and interpolate(front, 4001.0) is None
    assert interpolate([(5e3, 0.3)], 5e3) == 0.3 and interpolate([], 5e3) is None
    gap = [(1e3, 1.0), (2.5e3, 0.4)]  # more than twice apart: not known in between
    assert interpolate(gap, 2e3) is None and interpolate(gap, 2.5e3) == 0.4


SMALL = {
    "ipmsm_steady": OperatingPoint(
        "paper 001's IPMSM, two curves of two points",
        (
            Curve("mptc", "ipmsm_steady", "torque_controller.lambda_sw", (0.0, 0.03)),
            Curve("foc_formula", "ipmsm_steady_foc", "ts", (5e-4, 2.5e-4), label="foc_mtpa"),
            Curve(
                "mptc",
                "ipmsm_steady",
                "torque_controller.lambda_sw",
                (0.01,),
                {"torque_controller.horizon": 2},
                label="mptc N=2",
            ),  # fmt: skip
        ),
        ("mptc",),
        "a test",
    )
}


@pytest.fixture(scope="module")
def small(tmp_path_factory) -> FrontsResult:
    with studying(None, jobs=2) as runner:
        return reproduce_fronts(runner, study=SMALL, figures=tmp_path_factory.mktemp("figures"))


def test_a_small_study_traces_each_curve_over_its_knob(small):
    """The switching effort lowers MPTC's f_sw; FOC switches at its carrier, 1/Ts; every point
    held the operating point; the table interpolates each front at the common frequencies and
    ranks the curves by what it interpolated."""
    (t,) = small.points
    mptc, foc, longer = t.curves
    assert longer.name == "mptc N=2" and longer.settings == {"torque_controller.horizon": 2}
    assert 1e3 < longer.points[0].figures["f_sw_hz"] < 1e4
    assert [p.value for p in mptc.points] == [0.0, 0.03]
    f_mptc = [p.figures["f_sw_hz"] for p in mptc.points]
    assert f_mptc[0] > f_mptc[1] > 1e3
    assert [p.figures["f_sw_hz"] for p in foc.points] == pytest.approx([2e3, 4e3], rel=1e-9)
    assert all(p.holds for c in t.curves for p in c.points) and t.torque_ref == 15.0
    for key in ("t_ripple_cont", "i_thd_cont"):
        assert t.at[key]["foc_mtpa"][COMMON_FSW.index(2e3)] == foc.points[0].figures[key]
        assert sum(len(r) == 2 for r in t.ranking[key]) >= 2  # both curves reach 3 and 4 kHz
        for i, f in enumerate(COMMON_FSW):
            known = {n: v[i] for n, v in t.at[key].items() if v[i] is not None}
            assert t.ranking[key][i] == sorted(known, key=known.get)
            inside = f_mptc[1] <= f <= f_mptc[0]
            assert (t.at[key]["mptc"][i] is not None) == inside
    assert [p.name for p in small.figures] == ["fronts_ipmsm_steady.png"]
    json.dumps(small.as_dict())  # --json prints it


def test_the_knobs_values_are_checked_before_anything_runs(monkeypatch):
    ran = []
    monkeypatch.setattr("predictive_drive.api.study.run_cases", lambda *a, **k: ran.append(a))
    for kw, words in [
        ({"lambda_sw": [0.1, -0.2]}, "--lambda-sw: -0.2 is outside 0..1000"),
        ({"lambda_sw": [math.inf]}, "--lambda-sw: inf is outside 0..1000"),
        ({"fsw_khz": [5.0, 200.0]}, "--fsw-khz: 200.0 is outside 0.1..100 kHz"),
        ({"fsw_khz": [0.0]}, "--fsw-khz: 0.0 is not a positive number of kHz"),
        ({"lambda_sw": []}, "--lambda-sw: give at least one value"),
    ]:
        with pytest.raises(ConfigError, match=words):
            reproduce("fronts", **kw)
    with pytest.raises(ConfigError, match="--set torque_controller.lambda_sw: the fronts study"):
        reproduce("fronts", settings={"torque_controller.lambda_sw": 0.1})
    with pytest.raises(ConfigError, match=r"--set ts: the fronts study sweeps it"):
        reproduce("fronts", settings={"ts": 1e-4})
    with pytest.raises(ConfigError, match="dead_time"):  # refused by the scenario: Ts/10
        reproduce("fronts", settings={"plant.dead_time": 1e-5})
    with pytest.raises(ConfigError, match="not on the ros engine"):
        reproduce("fronts", engine="ros")
    with pytest.raises(ConfigError, match="--lambda-sw, --lambda-u and --fsw-khz choose the"):
        reproduce("im_paper", lambda_sw=[0.1])
    assert not ran


def test_given_values_replace_every_curves_own():
    study = with_knob_values(FRONTS, lambda_sw=[0.0, 0.1], fsw_khz=[2.0, 10.0], lambda_u=[0.5])
    wants = {
        "torque_controller.lambda_sw": (0.0, 0.1),
        "torque_controller.lambda_u": (0.5,),
        "ts": (5e-4, 1e-4),
    }
    for op in study.values():
        for c in op.curves:
            assert c.values == pytest.approx(wants[c.knob])
    with pytest.raises(ConfigError, match="--lambda-u: 0.0 is outside 1e-09..1000"):
        with_knob_values(FRONTS, lambda_u=[0.0])


def test_the_command_refuses_a_knob_of_another_reproduction(capsys):
    assert cli.main(["reproduce", "im_paper", "--lambda-sw", "0.1"]) == 2
    assert "--lambda-sw" in capsys.readouterr().err
    with pytest.raises(SystemExit) as e:  # argparse's usage error
        cli.main(["reproduce", "fronts", "--fsw-khz", "1,x"])
    assert e.value.code == 2
    assert "expected numbers separated by commas, got '1,x'" in capsys.readouterr().err


def test_runs_more_than_a_fifth_apart_in_f_sw_are_said_not_to_compare():
    from predictive_drive.core.metrics import unequal_switching

    assert unequal_switching({"a": 4000.0, "b": 4800.0}) is None  # 20 %: still comparable
    text = unequal_switching({"mptc": 4690.0, "db_mptc": 8120.0, "x": NAN})
    assert text.startswith("not comparable at equal switching frequency: f_sw 4.69 kHz (mptc) to")
    assert "8.12 kHz (db_mptc), 1.7 times" in text
    assert unequal_switching({"a": 4000.0}) is None


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
