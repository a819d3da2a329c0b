"""Controller families plug in by their module and one registry entry: a throwaway family defined
here runs through the scenario loader, the in-process engine and a recording, touching no other
family's code."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest

from predictive_drive.api.run import run_inprocess_to_bag
from predictive_drive.config import config_dir, load_scenario, load_scenario_text
from predictive_drive.core.control import (
    CONTROLLERS,
    Decision,
    VectorController,
    controller_class,
    make_controller,
    strategy_names,
)
from predictive_drive.core.fields import check_fields, choice, quantity
from predictive_drive.core.machines import Machine
from predictive_drive.core.machines.induction import InductionMotor
from predictive_drive.core.runner import run_inprocess
from predictive_drive.errors import ConfigError
from predictive_drive.readback import read_bag

pytestmark = pytest.mark.core


@dataclass(frozen=True)
class SixStepParams:
    motor: InductionMotor
    strategy: str = choice("control law", ("six_step", "hold_v1"))
    steps_per_vector: int = quantity("periods each vector is held", ge=1, integer=True, default=10)

    def __post_init__(self) -> None:
        check_fields(self)


class SixStep:
    """V1, V2, ..., V6 in turn, each for ``steps_per_vector`` periods (open loop)."""

    name = "six_step"

    def decide(self, k: int, every: int) -> Decision:
        return Decision(1 + (k // every) % 6, 1.0, float("nan"), 0)


class HoldV1:
    name = "hold_v1"

    def decide(self, k: int, every: int) -> Decision:
        return Decision(1, 1.0, float("nan"), 0)


class SixStepController(VectorController):
    family = "six_step_im"
    machine = Machine.INDUCTION
    params_type = SixStepParams
    strategies = {"six_step": SixStep, "hold_v1": HoldV1}

    def _observe(self, state):
        self.k = int(state.k)

    def _decide(self, state, ref):
        return self.strategy.decide(self.k, self.params.steps_per_vector)


@pytest.fixture
def registered(monkeypatch):
    monkeypatch.setitem(CONTROLLERS, "six_step_im", SixStepController)


def six_step_scenario_text() -> str:
    """im_short with its torque controller replaced by the throwaway family's section."""
    text = (config_dir() / "im_short.yaml").read_text()
    head, _, rest = text.partition("/drive/torque_controller:")
    _, _, tail = rest.partition("/drive/metrics_logger:")
    motor = load_scenario("im_short").controller.motor
    section = "\n".join(f"      {k}: {v!r}" for k, v in vars(motor).items())
    return (
        f"{head}/drive/torque_controller:\n  ros__parameters:\n    family: six_step_im\n"
        f"    strategy: six_step\n    steps_per_vector: 4\n    motor:\n{section}\n\n"
        f"/drive/metrics_logger:{tail}"
    )


def test_a_new_family_runs_through_loader_engine_and_recording(registered, tmp_path):
    sc = load_scenario_text(six_step_scenario_text(), "six_step.yaml").with_duration(0.01)
    assert sc.family == "six_step_im" and isinstance(sc.controller, SixStepParams)
    assert strategy_names("six_step_im") == ("six_step", "hold_v1")
    tr = run_inprocess(sc)
    vectors = tr.col("command", "vector").astype(int)
    np.testing.assert_array_equal(vectors, 1 + (np.arange(200) // 4) % 6)
    assert tr.strategy_names == ("six_step", "hold_v1")
    # the plant ran on it: six-step voltage turns the stator flux
    psi = tr.col("state", "psi_alpha") + 1j * tr.col("state", "psi_beta")
    assert abs(psi[-1]) > 0.1
    run_inprocess_to_bag(sc, tmp_path / "bag")
    rec, info = read_bag(tmp_path / "bag")
    assert info.info["family"] == "six_step_im"
    np.testing.assert_array_equal(rec.command[:, :-1], tr.command[:, :-1])
    switched = run_inprocess(sc, switches=[(100, "hold_v1")])
    assert set(switched.col("command", "vector")[100:].astype(int)) == {1}


def test_unregistered_family_is_refused_with_the_registered_ones():
    with pytest.raises(ConfigError, match="'six_step_im' is not one of mptc_im, mptc_pmsm"):
        load_scenario_text(six_step_scenario_text(), "six_step.yaml")
    with pytest.raises(ValueError, match="valid: mptc_im, mptc_pmsm"):
        controller_class("six_step_im")


def test_make_controller_builds_by_family(registered):
    sc = load_scenario_text(six_step_scenario_text(), "six_step.yaml")
    ctrl = make_controller("six_step_im", sc.controller, ts=sc.ts)
    assert isinstance(ctrl, SixStepController) and ctrl.strategy.name == "six_step"
