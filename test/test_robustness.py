"""Many drawn drives (docs/reproduction.md#robustness): the statistics against closed forms and
an independent bootstrap, the draws (reproducible, common to every strategy, refused before
anything runs where they leave a parameter's range), ``sweep --draw`` and a short
``reproduce robustness``, the draw of every run in its recording."""

from __future__ import annotations

import json
import math
import random
from statistics import NormalDist

import numpy as np
import pytest

from predictive_drive.api.draws import Spread, draw_cases, drawn, parse_spread, sweep_drawn
from predictive_drive.api.reproduce import reproduce
from predictive_drive.api.sweep import Case
from predictive_drive.core.stats import (
    first_shares,
    mean_interval,
    student_t_cdf,
    t_quantile,
    wilson_interval,
)
from predictive_drive.errors import ConfigError
from predictive_drive.readback import read_bag

pytestmark = pytest.mark.core


@pytest.mark.parametrize("p", [0.6, 0.9, 0.975, 0.995])
def test_t_quantiles_against_closed_forms(p):
    """ν = 1 (Cauchy): tan(π(p - ½)); ν = 2: (2p - 1)/sqrt(2p(1 - p)); ν → ∞: the normal's."""
    assert t_quantile(p, 1) == pytest.approx(math.tan(math.pi * (p - 0.5)), rel=1e-9)
    assert t_quantile(p, 2) == pytest.approx((2 * p - 1) / math.sqrt(2 * p * (1 - p)), rel=1e-9)
    assert t_quantile(p, 1e7) == pytest.approx(NormalDist().inv_cdf(p), rel=1e-5)
    assert student_t_cdf(t_quantile(p, 7.0), 7.0) == pytest.approx(p, abs=1e-12)
    assert t_quantile(1 - p, 5) == -t_quantile(p, 5)


def test_the_mean_interval_covers_95_percent_and_matches_a_bootstrap():
    """2,000 samples of 10 normal values: the t interval holds the true mean 95 % ± 1.5 % of
    the time; for 400 skewed values its half-width agrees with a percentile bootstrap's (an
    independent computation) within 10 %."""
    rng = random.Random(11)
    hits = 0
    for _ in range(2000):
        iv = mean_interval([rng.gauss(3.0, 2.0) for _ in range(10)])
        hits += iv.low <= 3.0 <= iv.high
    assert abs(hits / 2000 - 0.95) < 0.015
    gen = np.random.default_rng(4)
    xs = gen.lognormal(0.0, 0.5, 400)
    iv = mean_interval(xs.tolist())
    boot = np.mean(gen.choice(xs, (4000, xs.size)), axis=1)
    lo, hi = np.percentile(boot, [2.5, 97.5])
    assert (iv.high - iv.low) == pytest.approx(hi - lo, rel=0.1)
    assert iv.value == pytest.approx(float(np.mean(xs)), rel=1e-12)


def test_wilson_interval_closed_forms():
    """k = 0: [0, z²/(n + z²)]; k = n mirrored; inside, each end p solves |p̂ - p| =
    z·sqrt(p(1 - p)/n) (the score test's boundary)."""
    z = NormalDist().inv_cdf(0.975)
    iv = wilson_interval(0, 20)
    assert (iv.low, iv.high) == (0.0, pytest.approx(z * z / (20 + z * z), rel=1e-12))
    iv = wilson_interval(20, 20)
    assert iv.high == 1.0 and iv.low == pytest.approx(20 / (20 + z * z), rel=1e-12)
    iv = wilson_interval(7, 30)
    for end in (iv.low, iv.high):
        assert abs(7 / 30 - end) == pytest.approx(z * math.sqrt(end * (1 - end) / 30), rel=1e-9)


def test_first_shares_split_ties_and_skip_failed_draws():
    draws = [
        {"a": 1.0, "b": 2.0, "c": 3.0},
        {"a": 2.0, "b": 1.0, "c": 1.0},  # b and c tie for first
        {"a": math.nan, "b": math.nan, "c": math.nan},  # every run failed: not counted
        {"a": math.nan, "b": 5.0, "c": 4.0},
    ]
    firsts, counted = first_shares(draws)
    assert counted == 3 and firsts == {"a": 1.0, "b": 0.5, "c": 1.5}


def test_a_spread_parses_and_a_bad_one_is_refused_naming_the_key():
    assert parse_spread("plant.motor.l_q=normal:0.2") == Spread("plant.motor.l_q", "normal", 0.2)
    with pytest.raises(ConfigError, match=r"plant.motor.r_s: the spread must be .*>= 0.*-0.1"):
        parse_spread("plant.motor.r_s=normal:-0.1")
    with pytest.raises(ConfigError, match="'gamma' is not one of normal, uniform"):
        parse_spread("plant.motor.r_s=gamma:0.1")
    with pytest.raises(ConfigError, match="expected KEY=normal:S"):
        parse_spread("plant.motor.r_s")


def test_draws_are_reproducible_common_and_independent_per_key():
    one = drawn("ipmsm_steady", [parse_spread("plant.motor.l_q=normal:0.1")], 20, 7)
    two = drawn(
        "ipmsm_steady",
        [parse_spread("plant.motor.r_s=uniform:0.2"), parse_spread("plant.motor.l_q=normal:0.1")],
        20,
        7,
    )
    assert [d.values["plant.motor.l_q"] for d in one] == [
        d.values["plant.motor.l_q"] for d in two
    ]  # adding a spread leaves the others' draws
    assert all(0.8 <= d.factors["plant.motor.r_s"] <= 1.2 for d in two)
    # two keys of one distribution draw independently, not the same z
    both = drawn(
        "ipmsm_steady",
        [parse_spread("plant.motor.l_d=normal:0.1"), parse_spread("plant.motor.l_q=normal:0.1")],
        50,
        7,
    )
    z = np.array([[d.factors["plant.motor.l_d"], d.factors["plant.motor.l_q"]] for d in both])
    assert abs(np.corrcoef(z.T)[0, 1]) < 0.5
    other = drawn("ipmsm_steady", [parse_spread("plant.motor.l_q=normal:0.1")], 20, 8)
    assert [d.values for d in other] != [d.values for d in one]
    lq = np.array([d.values["plant.motor.l_q"] for d in one])
    assert np.all(
        lq == pytest.approx(0.0073 * np.array([d.factors["plant.motor.l_q"] for d in one]))
    )
    cases = draw_cases([Case("mptc"), Case("simplified1")], one)
    assert [c.settings for c in cases[0::2]] == [c.settings for c in cases[1::2]]  # CRN
    assert [c.draw["index"] for c in cases[:4]] == [0, 0, 1, 1]


def test_a_draw_that_leaves_the_range_is_refused_before_anything_runs():
    with pytest.raises(ConfigError) as e:
        drawn("ipmsm_steady", [parse_spread("plant.motor.r_s=normal:0.6")], 200, 1)
    text = str(e.value)
    assert "plant.motor.r_s=normal:0.6: draw" in text and "must be a finite number > 0" in text
    with pytest.raises(ConfigError, match="σ > 0"):  # a cross-check of the loaded drive
        drawn("im_short", [parse_spread("plant.motor.l_m=uniform:0.1")], 50, 1)
    with pytest.raises(ConfigError, match="plant saturates: its magnetic model"):
        drawn("pmsyrm_steady", [parse_spread("plant.motor.l_q=normal:0.1")], 5, 1)
    with pytest.raises(ConfigError, match="plant.saturation is off"):
        drawn("ipmsm_steady", [parse_spread("plant.saturation.lq_drop=normal:0.1")], 5, 1)


def test_sweep_draws_record_their_draw_and_summarise(tmp_path):
    """sweep --draw 3 over two strategies: six runs, each bag's metadata naming its draw and
    the drawn values in its stored scenario; a summary per strategy."""
    r = sweep_drawn(
        "ipmsm_steady",
        draw=3,
        spreads=["plant.motor.l_q=normal:0.1"],
        seed=5,
        strategies=["mptc", "simplified1"],
        duration=0.02,
        out=tmp_path / "out",
        record=True,
        jobs=2,
    )
    assert len(r.rows) == 6 and not any(row.error for row in r.rows)
    assert {f.strategy for f in r.drawn} == {"mptc", "simplified1"}
    for row in r.rows:
        _, info = read_bag(row.bag)
        draw = json.loads(info.info["draw"])
        assert draw == row.draw and draw["seed"] == 5
        assert f"l_q: {draw['values']['plant.motor.l_q']!r}" in info.info["scenario_yaml"]
    mptc = next(f for f in r.drawn if f.strategy == "mptc")
    assert mptc.mean["t_rmse"].n == 3 and mptc.mean["t_rmse"].low < mptc.mean["t_rmse"].high
    assert sum(f.first["t_rmse"].value for f in r.drawn) == pytest.approx(1.0)


def test_a_short_robustness_study_ranks_with_intervals_and_reproduces(tmp_path):
    """Three drives of ipmsm_steady, 60 ms each: each strategy's mean within its interval, the
    P(first) summing to one, the conditions run, the figure drawn; the same seed the same
    figures, another seed others."""
    kw = dict(points=["ipmsm_steady"], draws=3, duration=0.06, jobs=2)
    a = reproduce("robustness", seed=3, figures=tmp_path / "fig", **kw)
    b = reproduce("robustness", seed=3, **kw)
    c = reproduce("robustness", seed=4, **kw)
    (p,) = a.points
    assert [f.strategy for f in p.figures] == ["mptc", "simplified1", "simplified2", "simplified3"]
    for f in p.figures:
        iv = f.mean["t_rmse"]
        assert iv.n == 3 and iv.low < iv.value < iv.high
    assert sum(f.first["t_rmse"].value for f in p.figures) == pytest.approx(1.0)
    assert set(p.conditions) == {"nominal", "L_q +20 %", "L_q -20 %", "saturated"}

    def t_rmse(r):
        return {s: v["t_rmse"] for s, v in r.points[0].values.items()}

    assert t_rmse(a) == t_rmse(b) != t_rmse(c)
    assert [x.name for x in a.figures] == ["robustness_ipmsm_steady.png"]
    assert a.as_dict()["points"][0]["ranking"]["t_rmse"] == p.ranking("t_rmse")


def test_the_robustness_options_belong_to_the_robustness_study():
    with pytest.raises(ConfigError, match="choose the robustness study's drives"):
        reproduce("fronts", draws=3)
    with pytest.raises(ConfigError, match="runs as a sweep"):
        reproduce("robustness", engine="ros", draws=2)
    with pytest.raises(ConfigError, match="not a point of the robustness study; one of"):
        reproduce("robustness", points=["nowhere"], draws=2)
    with pytest.raises(ConfigError, match="plant.motor.r_s=normal:5: draw"):
        reproduce(
            "robustness", points=["ipmsm_steady"], draws=50, spreads=["plant.motor.r_s=normal:5"]
        )


def test_sweep_draw_prints_each_strategy_over_the_drives(capsys):
    from predictive_drive import cli

    args = ["sweep", "ipmsm_steady", "--strategy", "mptc,simplified3", "--draw", "3",
            "--spread", "plant.motor.l_q=normal:0.1", "--duration", "0.02", "--jobs", "2"]  # fmt: skip
    assert cli.main(args) == 0
    out = capsys.readouterr().out
    assert "3 drives drawn (seed 0): plant.motor.l_q=normal:0.1" in out
    assert "P(first) T_RMSE" in out and "vs best T_RMSE" in out
    lines = [line for line in out.splitlines() if line.startswith(("mptc ", "simplified3 "))]
    assert len(lines) == 2 and all("[" in line for line in lines)
    assert cli.main([*args[:-2], "--spread", "plant.motor.l_q=normal:-1", "--json"]) == 2


@pytest.mark.core
@pytest.mark.parametrize(
    "args,says",
    [
        (["--spread", "plant.motor.l_q=normal:0.1"],
         "--spread: give --draw N too (the number of drives to draw, at least 1)"),
        (["--draw", "0"], "--draw 0: the number of drawn drives must be at least 1"),
        (["--draw", "3"], "--draw: give the spreads to draw from"),
    ],
    ids=["spread-without-draw", "draw-0", "draw-without-spread"],
)  # fmt: skip
def test_draw_and_spread_go_together_and_say_so(args, says, capsys):
    """A spread without --draw names --draw (was: '--draw 0: ... at least 1', a value the user
    never gave); --draw 0 is refused (was: a plain sweep, silently)."""
    from predictive_drive import cli

    code = cli.main(["sweep", "im_short", "--duration", "0.01", "--jobs", "1", *args])
    err = capsys.readouterr().err
    assert code == 2 and says in err, err
