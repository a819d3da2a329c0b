"""The efficiency study (docs/reproduction.md#efficiency-maps): a small grid run for real, each
point's efficiency held to the energy it books, the operating-point check blanking the points
that leave it, and what the study refuses."""

from __future__ import annotations

import json

import numpy as np
import pytest

from predictive_drive import cli
from predictive_drive.api.efficiency import (
    EfficiencyChoice,
    grid_settings,
    mtpa_flux,
    reproduce_efficiency,
)
from predictive_drive.api.study import studying
from predictive_drive.config import load_scenario
from predictive_drive.errors import ConfigError
from predictive_drive.reports.efficiency import EFFICIENCY

pytestmark = pytest.mark.core

SPEEDS, TORQUES = (500.0, 1000.0), (1.5, 7.5, 15.0)


@pytest.fixture(scope="module")
def small(tmp_path_factory):
    study = EfficiencyChoice(["mptc", "foc_formula"], SPEEDS, TORQUES).study()
    told: list = []
    with studying(None, jobs=2, progress=lambda *a: told.append(a)) as runner:
        result = reproduce_efficiency(
            runner, study=study, figures=tmp_path_factory.mktemp("figures")
        )
    return result, told


def test_every_point_is_its_grid_point_and_its_efficiency_is_what_its_energy_says(small):
    """Each map's points come back as rows of torque by columns of speed; at every point that
    holds its operating point η = P_out/P_in, and P_in = P_out + the inverter's and the
    machine's losses within 1 % (steady: no stored energy gained over the window) — the
    energy's own balance, not the efficiency's formula; more speed at the same torque gives
    more power out."""
    d, told = small
    assert [m.name for m in d.maps] == ["mptc", "foc_formula"] and d.runs == 12
    assert (d.speeds_rpm, d.torques) == (SPEEDS, TORQUES)
    for m in d.maps:
        assert [(p.torque, p.speed_rpm) for p in m.points] == [
            (t, n) for t in TORQUES for n in SPEEDS
        ]
        for p in m.points:
            if not p.holds:
                continue
            f = p.figures
            assert f["efficiency"] == pytest.approx(f["p_out"] / f["p_in"], rel=1e-12)
            losses = f["p_inverter"] + f["p_machine"]
            assert f["p_in"] == pytest.approx(f["p_out"] + losses, rel=0.01)
            assert 0.5 < f["efficiency"] < 1.0 and f["p_iron"] > 0 and f["p_sw_t"] > 0
        grid = m.grid("p_out", SPEEDS, TORQUES)
        for row in grid:
            if None not in row:
                assert row[1] > 1.8 * row[0]
    assert sorted({name.split(" ")[0] for *_, name in told}) == ["foc_formula", "mptc"]
    assert [p.name for p in d.figures] == ["efficiency_maps.png"]
    json.dumps(d.as_dict())


def test_a_point_that_leaves_its_operating_point_is_blank_and_listed(small):
    """MPTC at 1.5 N·m (a tenth of rated) lets |ψ_s| fall far below the MTPA flux and draws
    many times the MTPA current: blank on its map, listed with its misses; FOC holds it."""
    d, _ = small
    mptc, foc = d.maps
    assert mptc.grid("efficiency", SPEEDS, TORQUES)[0] == [None, None]
    assert all(v is not None for v in foc.grid("efficiency", SPEEDS, TORQUES)[0])
    listed = [(name, p.torque) for name, p in d.excluded()]
    assert ("mptc", 1.5) in listed and all(name != "foc_formula" for name, _ in listed)
    (p, *_) = [p for name, p in d.excluded() if name == "mptc"]
    assert p.reason.startswith("left the operating point: ") and p.misses["flux"] < -0.02
    assert d.as_dict()["excluded"][0]["map"] == "mptc"


def test_each_grid_point_holds_its_speed_and_asks_the_mtpa_flux_of_its_torque():
    """ψ* is |ψ_s| of the MTPA point of T* (0.2385 Wb at rated torque, as the steady scenario
    states it; nearly ψ_f at light load); T* ramps over 10 ms to its value; the window is at
    least 0.2 s and two electrical periods (100 r/min, 3 pole pairs: 0.4 s)."""
    sc = load_scenario("ipmsm_steady")
    assert mtpa_flux(sc, 15.0) == pytest.approx(sc.speed_pi_params.flux_ref, abs=1e-4)
    assert mtpa_flux(sc, 1.5) == pytest.approx(0.2265, abs=1e-4)
    s = grid_settings(sc, 100.0, 6.0, 0.2)
    assert s["speed_pi.torque_values"][-1] == 6.0 and s["speed_pi.torque_times"][-1] == 0.0095
    assert s["plant.held_speed_rpm"] == [100.0] and s["duration"] == pytest.approx(0.45)
    assert grid_settings(sc, 1000.0, 6.0, 0.2)["metrics_logger.window_end"] == pytest.approx(0.25)


def test_the_choice_is_checked_before_anything_runs(capsys):
    with pytest.raises(ConfigError, match="--maps nope: no map of that name; the maps: mptc"):
        EfficiencyChoice(maps=["nope"]).study()
    with pytest.raises(ConfigError, match="--torques: -3.0 is not a positive number"):
        EfficiencyChoice(torques=[-3.0]).study()
    full = EfficiencyChoice().study()
    assert len(full.speeds_rpm) >= 10 and len(full.torques) >= 10 and full == EFFICIENCY
    assert {m.name for m in full.maps} == {"mptc", "foc_formula", "direct_mpc"}
    assert cli.main(["reproduce", "fronts", "--maps", "mptc", "--json"]) == 2
    assert "chooses the efficiency study's runs" in capsys.readouterr().out
    assert cli.main(["reproduce", "efficiency", "--set", "speed_pi.flux_ref=0.3", "--json"]) == 2
    assert "sets it at every grid point" in capsys.readouterr().out


def test_a_maps_cells_stop_at_zero_for_a_positive_grid():
    """Two torques 3 and 15 N·m: the cells' edges 0, 9, 21 (was -3: a negative torque drawn)."""
    from predictive_drive.reports.figures import _edges

    np.testing.assert_allclose(_edges([3.0, 15.0]), [0.0, 9.0, 21.0])
    np.testing.assert_allclose(_edges([250.0, 500.0, 750.0]), [125.0, 375.0, 625.0, 875.0])
    np.testing.assert_allclose(_edges([-2.0, 2.0]), [-4.0, 0.0, 4.0])  # a grid through zero
