"""A saturating machine through the four node processes (docs/physics.md#saturation): the same
run as in-process, bit for bit — the PMSM on its published flux model with the controller given
the map too, and paper 000's induction motor with its assumed main-flux saturation."""

from __future__ import annotations

import numpy as np
import pytest

from predictive_drive.api.run import run
from predictive_drive.readback import read_bag

pytestmark = pytest.mark.process

#: the controller's own flux map: the plant's published model (config/pmsyrm_steady.yaml)
_PMSYRM_MAP = {
    "model": "algebraic", "a_d0": 3.96, "a_dd": 28.5, "s": 4.0, "a_q0": 5.89, "a_qq": 2.67,
    "t": 6.0, "a_dq": 41.5, "u": 1.0, "v": 1.0, "psi_n": 0.804, "a_b": 81.75, "a_bp": 1.0,
    "w": 2.0, "k_q": 0.1, "max_current": 25.0,
}  # fmt: skip
CASES = {
    "pmsm_map": (
        "pmsyrm_steady",
        {f"torque_controller.saturation.{k}": v for k, v in _PMSYRM_MAP.items()},
    ),
    "im_curve": (
        "im_short",
        {"plant.saturation.model": "curve", "plant.saturation.flux_rated": 0.71},
    ),
}


@pytest.mark.parametrize("case", list(CASES))
def test_a_saturating_machine_through_the_graph_equals_inprocess(tmp_path, case):
    scenario, settings = CASES[case]
    g = run(scenario, duration=0.02, settings=settings, out=tmp_path / "g")
    i = run(scenario, duration=0.02, settings=settings, engine="inprocess", out=tmp_path / "i")
    a, info = read_bag(g.bag)
    b, _ = read_bag(i.bag)
    assert info.complete and a.steps == b.steps == 400
    np.testing.assert_array_equal(a.state, b.state)
    np.testing.assert_array_equal(a.reference, b.reference)
    np.testing.assert_array_equal(a.command[:, :-1], b.command[:, :-1])
    assert "saturation:" in info.info["scenario_yaml"]
    assert np.abs(a.col("state", "i_alpha")).max() > 1.0  # current flowed
