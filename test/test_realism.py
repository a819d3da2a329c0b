"""The realism study (docs/physics.md#the-papers-strategies-on-a-real-drive): every strategy of
both scenarios under every column, each cell the run its settings say, ranked per column; the
real drive's settings replaceable, the study's own refused; the same on a Dask cluster."""

from __future__ import annotations

import math

import pytest

from predictive_drive import cli
from predictive_drive.api import study as study_module
from predictive_drive.api.reproduce import RealismResult, _ranks, reproduce
from predictive_drive.api.sweep import Case, run_case
from predictive_drive.config import apply_settings, resolve_scenario_path
from predictive_drive.errors import ConfigError, Interrupted
from predictive_drive.reports.figures import realism_figures
from predictive_drive.reports.realism import (
    CONDITIONS,
    DEAD_TIME_KEYS,
    HARDWARE_KEYS,
    SENSOR_KEYS,
    SHOWN,
    STUDY_KEY,
)
from procs import dask_cluster

DURATION = 0.06  #: s: long enough for every column to differ from the ideal one


@pytest.fixture(scope="module")
def study(tmp_path_factory) -> RealismResult:
    d = reproduce("realism", duration=DURATION, figures=tmp_path_factory.mktemp("figures"))
    assert isinstance(d, RealismResult)
    return d


def _rerun(scenario: str, strategy: str, settings: dict) -> dict[str, float]:
    """The figures of one run made here, in this process, as a user's sweep case would be."""
    path = resolve_scenario_path(scenario)
    text = apply_settings(path.read_text(), settings, path)
    row = run_case(text, str(path), Case(strategy, settings), DURATION)
    assert row.error is None, row.error
    return {k: getattr(row.metrics, k) for k in SHOWN}


def _same(a: dict[str, float], b: dict[str, float]) -> bool:
    """Equal bit for bit, NaN equal to NaN (a THD outside a shortened run)."""
    return a.keys() == b.keys() and all(
        a[k] == b[k] or (math.isnan(a[k]) and math.isnan(b[k])) for k in a
    )


@pytest.mark.core
def test_every_strategy_of_both_scenarios_runs_under_every_column(study):
    assert study.conditions == CONDITIONS
    assert set(study.strategies) == {"im_paper", "ipmsm_validation"}
    cells = {(c.scenario, c.strategy, c.condition) for c in study.cells}
    expected = {(n, s, c) for n, ss in study.strategies.items() for s in ss for c in CONDITIONS}
    assert cells == expected and len(study.cells) == len(expected) == 35
    for c in study.cells:
        # the columns are cumulative: each adds its keys to the one before
        keys = set(c.settings) & (set(HARDWARE_KEYS) | {STUDY_KEY})
        want = {
            "ideal": set(),
            "delay": {"plant.actuation_delay_steps"},
            "compensated": {"plant.actuation_delay_steps", STUDY_KEY},
            "+ dead time": {"plant.actuation_delay_steps", STUDY_KEY, *DEAD_TIME_KEYS},
            "+ sensors": {"plant.actuation_delay_steps", STUDY_KEY, *DEAD_TIME_KEYS,
                          *SENSOR_KEYS},
        }[c.condition]  # fmt: skip
        assert keys == want, (c.condition, keys)
        assert c.settings.get(STUDY_KEY, False) == (c.condition not in ("ideal", "delay"))
        assert math.isfinite(c.figures["t_rmse"]) and math.isfinite(c.figures["f_sw_hz"])
    # every column changes the drive: no two columns of a strategy give the same torque error
    for n, ss in study.strategies.items():
        for s in ss:
            t = [study.cell(n, s, c).figures["t_rmse"] for c in CONDITIONS]
            assert len(set(t)) == len(t), (n, s, t)


@pytest.mark.core
@pytest.mark.parametrize(
    "scenario,strategy,condition",
    [("im_paper", "db_mptc", "+ sensors"), ("ipmsm_validation", "simplified2", "delay"),
     ("ipmsm_validation", "mptc", "ideal")],
)  # fmt: skip
def test_a_cell_is_the_run_its_settings_say(study, scenario, strategy, condition):
    """Each cell's figures are those of a run of its scenario with its settings, made apart from
    the study: no cell holds another's row."""
    cell = study.cell(scenario, strategy, condition)
    assert _same(cell.figures, _rerun(scenario, strategy, cell.settings))


@pytest.mark.core
def test_the_strategies_are_ranked_in_every_column(study):
    for n, ss in study.strategies.items():
        for c in CONDITIONS:
            t = {s: study.cell(n, s, c).figures["t_rmse"] for s in ss}
            for s in ss:  # 1 + how many did better; equal figures share a place
                assert study.cell(n, s, c).rank["t_rmse"] == 1 + sum(v < t[s] for v in t.values())
    assert _ranks({"a": 2.0, "b": 1.0, "c": 2.0, "d": math.nan}) == {
        "a": 2,
        "b": 1,
        "c": 2,
        "d": None,
    }


@pytest.mark.core
def test_the_figures_draw_the_table(study):
    """Two figures (one per scenario) written; each bar is a cell's figure."""
    assert sorted(p.name for p in study.figures) == [
        "realism_im_paper.png",
        "realism_ipmsm_validation.png",
    ]
    assert all(p.stat().st_size > 10_000 for p in study.figures)
    table = {
        n: {s: {k: [study.cell(n, s, c).figures[k] for c in CONDITIONS] for k in SHOWN}
            for s in ss}
        for n, ss in study.strategies.items()
    }  # fmt: skip
    figs = realism_figures(table, CONDITIONS)
    ax = figs["ipmsm_validation"].axes[0]  # T_RMSE
    for container, strategy in zip(ax.containers, study.strategies["ipmsm_validation"]):
        heights = [bar.get_height() for bar in container]
        assert heights == table["ipmsm_validation"][strategy]["t_rmse"]


@pytest.mark.core
def test_a_real_drive_setting_replaces_the_studys_in_its_columns(monkeypatch):
    """--set of a real drive's key: in the columns that have it; any other key: every run. The
    study's own key, and a value the plant refuses, stop it before anything runs."""
    seen = []

    def record(scenario, cases, **kw):
        seen.append((scenario, cases))
        raise KeyboardInterrupt  # enough: the cases are what this test looks at

    monkeypatch.setattr(study_module, "run_cases", record)  # every study runs its cases there
    with pytest.raises(Interrupted):  # the study's: 0 runs had finished
        reproduce("realism", settings={"plant.dead_time": 1e-6, "speed_pi.kp": "*0.5"})
    scenario, cases = seen[0]
    assert scenario == "im_paper"
    for case in cases:
        assert case.settings["speed_pi.kp"] == "*0.5"
        assert case.settings.get("plant.dead_time") in (None, 1e-6)
    assert sum("plant.dead_time" in c.settings for c in cases) == 2 * 3  # two columns, 3 strategies

    seen.clear()
    with pytest.raises(ConfigError, match=f"--set {STUDY_KEY}: the realism study sets it"):
        reproduce("realism", settings={STUDY_KEY: True})
    with pytest.raises(ConfigError, match="dead_time"):
        reproduce("realism", settings={"plant.dead_time": 1e-5})  # Ts/10 = 5 µs
    with pytest.raises(ConfigError, match="not on the ros engine"):
        reproduce("realism", engine="ros")
    assert not seen  # refused before any run


@pytest.mark.core
def test_the_command_prints_every_column_with_its_ranks(capsys, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert cli.main(["reproduce", "realism", "--duration", "0.02"]) == 0
    out = capsys.readouterr().out
    assert "NOTE: runs shortened to 0.02 s" in out
    assert out.count("T_RMSE N·m (rank)") == 2 and out.count("f_sw kHz") == 2
    head = next(line for line in out.splitlines() if line.startswith("T_RMSE"))
    assert all(c in head for c in CONDITIONS)
    assert "plant.encoder_lines = 32768" in out and "plant.encoder_lines = 2500" in out
    assert not list(tmp_path.iterdir())  # the study records no bags


@pytest.mark.process
def test_the_study_on_a_dask_cluster_equals_the_local_one(tmp_path, study):
    pytest.importorskip("distributed")
    with dask_cluster(tmp_path) as address:
        remote = reproduce("realism", duration=DURATION, scheduler=address)
    assert remote.engine == f"dask ({address}, 2 workers)"
    assert [(c.scenario, c.strategy, c.condition) for c in remote.cells] == [
        (c.scenario, c.strategy, c.condition) for c in study.cells
    ]
    for a, b in zip(remote.cells, study.cells):
        assert _same(a.figures, b.figures) and a.rank == b.rank, (a, b)


@pytest.mark.core
def test_an_induction_motors_thd_is_counted_on_its_stator_frequency():
    """The study's IM THD window: the currents run at the rotor's frequency plus the slip, and
    the analysis counts their cycles there (on the rotor's it read hundreds of per cent)."""
    settings = {"metrics_logger.thd_window": [1.0, 1.45]}
    path = resolve_scenario_path("im_paper")
    text = apply_settings(path.read_text(), settings, path)
    row = run_case(text, str(path), Case("mptc", settings), duration=1.45)
    assert row.error is None, row.error
    m = row.metrics
    rotor_hz = 289.5 / (2 * math.pi)  # p = 1, the speed settled near 2772 r/min
    assert m.thd_fundamental_hz > rotor_hz + 1.0  # motoring: the field leads by the slip
    assert 0.05 < m.thd < 0.3 and m.thd_harmonics < m.thd
