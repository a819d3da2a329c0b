"""Scenario files: ROS parameter-file form, validation errors that name file, key and allowed values."""

import dataclasses
import math
from pathlib import Path

import pytest
import yaml

from predictive_drive.config import (
    FAMILY_KEY,
    config_dir,
    load_scenario,
    scenario_names,
    section_classes,
    section_fields,
)
from predictive_drive.core.machines.induction import InductionMotor
from predictive_drive.core.machines.pmsm import PMSM
from predictive_drive.core.scenario import RunParams
from predictive_drive.errors import ConfigError
from predictive_drive.interface import NAMESPACE

pytestmark = pytest.mark.core


@pytest.mark.parametrize("name", scenario_names())
def test_yaml_keys_equal_dataclass_fields(name):
    doc = yaml.safe_load((config_dir() / f"{name}.yaml").read_text())
    assert set(doc["/**"]["ros__parameters"]) == set(section_fields(RunParams))
    machine = doc["/**"]["ros__parameters"]["machine"]
    family = doc[f"{NAMESPACE}/torque_controller"]["ros__parameters"][FAMILY_KEY]
    for node, (cls, nested) in section_classes(machine, family).items():
        params = dict(doc[f"{NAMESPACE}/{node}"]["ros__parameters"])
        if node == "torque_controller":
            params.pop(FAMILY_KEY)  # names the settings class; not one of its fields
        # every key the file gives is a field; every field without a default is given (the
        # real-drive settings of plant and controller default to the ideal drive, left out)
        required = {f.name for f in dataclasses.fields(cls) if f.default is dataclasses.MISSING}
        assert required <= set(params) <= set(section_fields(cls)), node
        for key, sub in nested.items():
            if key in required:
                assert set(params[key]) == set(section_fields(sub)), f"{node}.{key}"
            else:  # a group of defaults (plant.losses): left out, or the keys it changes
                assert set(params.get(key, {})) <= set(section_fields(sub)), f"{node}.{key}"
    load_scenario(name)


def test_im_paper_has_the_paper_values():
    sc = load_scenario("im_paper")
    assert sc.plant.motor == InductionMotor(
        r_s=2.68, r_r=2.13, l_s=0.2834, l_r=0.2834, l_m=0.2751, p=1, j=0.005, b=0.0
    )
    assert (sc.ts, sc.run.duration, sc.plant.u_dc) == (5e-5, 6.0, 582.0)
    assert sc.speed_pi.kp == 0.06 and sc.speed_pi.ki == 0.15 and sc.speed_pi.torque_limit == 7.5
    assert sc.controller.lambda_psi == 17.5 and sc.speed_pi.flux_ref == 0.71
    assert sc.plant.load_values == (3.0, -3.0, 3.0) and sc.plant.load_times == (0.0, 1.5, 4.5)


def test_pmsm_scenarios_have_the_paper_values():
    sp = load_scenario("spmsm_analysis")
    m = sp.plant.motor
    assert isinstance(m, PMSM) and m.surface
    assert (m.r_s, m.l_d, m.psi_f, m.p, m.rated_torque, m.rated_speed_rpm) == (
        0.2,
        0.0085,
        0.175,
        4,
        12.0,
        750.0,
    )
    assert (sp.ts, sp.run.duration, sp.plant.u_dc, sp.speed_pi.flux_ref) == (5e-5, 4.0, 312.0, 0.3)
    assert (sp.speed_pi.kp, sp.speed_pi.ki, sp.speed_pi.torque_limit) == (5.0, 10.0, 30.0)
    assert sp.plant.load_values == (10.0, -10.0, 10.0) and sp.plant.load_times == (0.0, 1.0, 3.0)
    assert sp.speed_pi.speed_values_rpm == (500.0, -500.0) and sp.speed_pi.speed_times == (0, 2)
    assert sp.controller.torque_threshold == pytest.approx(0.05 * m.rated_torque)
    ip = load_scenario("ipmsm_validation")
    m = ip.plant.motor
    assert (m.r_s, m.l_d, m.l_q, m.psi_f, m.p, m.rated_torque) == (
        0.25,
        0.0033,
        0.0073,
        0.2264,
        3,
        15.0,
    )
    assert ip.plant.load_values == (15.0, -15.0, 15.0) and ip.plant.load_times == (0, 0.5, 1.5)
    assert ip.speed_pi.speed_values_rpm == (1000.0, -1000.0) and ip.run.duration == 2.0
    assert ip.controller.torque_threshold == 0.75 and ip.controller.t_floor == 0.15


def test_pmsm_threshold_defaults_to_a_share_of_rated_torque(tmp_path):
    text = (config_dir() / "ipmsm_short.yaml").read_text()
    text = text.replace("    torque_threshold: 0.75", "    # no threshold: 5 % of rated")
    text = text.replace("    t_floor: 0.15", "    # no floor: 1 % of rated")
    p = tmp_path / "x.yaml"
    p.write_text(text)
    c = load_scenario(p).controller
    assert c.torque_threshold == pytest.approx(0.75) and c.t_floor == pytest.approx(0.15)


@pytest.mark.parametrize(
    "old, new, words",
    [
        ("strategy: mptc ", "strategy: db_mptc ", ["db_mptc", "simplified3", "strategy"]),
        ("torque_threshold: 0.75", "torque_threshold: -1.0", ["torque_threshold", ">= 0"]),
        ("l_q: 0.0073 ", "l_q: -0.0073 ", ["/drive/plant.motor: l_q", "> 0 H", "-0.0073"]),
        ("machine: pmsm", "machine: dc", ["machine", "induction", "pmsm"]),
        ("      rated_torque: 15.0\n", "", ["rated_torque", "missing"]),
    ],
    ids=["im-strategy-on-pmsm", "negative-threshold", "negative-lq", "machine", "no-rated"],
)
def test_pmsm_config_errors_name_the_key(tmp_path, old, new, words):
    text = (config_dir() / "ipmsm_short.yaml").read_text()
    assert old in text
    p = tmp_path / "bad.yaml"
    p.write_text(text.replace(old, new, 1))
    with pytest.raises(ConfigError) as e:
        load_scenario(p)
    for w in [str(p), *words]:
        assert w in str(e.value)


def _edit(tmp_path: Path, edit) -> Path:
    doc = yaml.safe_load((config_dir() / "im_short.yaml").read_text())
    edit(doc)
    p = tmp_path / "bad.yaml"
    p.write_text(yaml.safe_dump(doc))
    return p


def _plant(doc):
    return doc["/drive/plant"]["ros__parameters"]


CASES = {
    "wrong key": (
        lambda d: _plant(d).update(udc=1.0),
        r"/drive/plant: unknown key 'udc'; allowed keys: motor, u_dc",
    ),
    "missing key": (lambda d: _plant(d).pop("u_dc"), r"/drive/plant: missing key 'u_dc'"),
    "negative inductance": (
        lambda d: _plant(d)["motor"].update(l_s=-0.28),
        r"/drive/plant.motor: l_s must be a finite number > 0 H, got -0.28",
    ),
    "unknown strategy": (
        lambda d: d["/drive/torque_controller"]["ros__parameters"].update(strategy="dtc"),
        r"/drive/torque_controller: strategy: 'dtc' is not one of "
        r"mptc, mptc_db, db_mptc",
    ),
    "wrong type": (
        lambda d: _plant(d).update(u_dc="high"),
        r"/drive/plant.u_dc: expected a number, got 'high'",
    ),
    "missing section": (lambda d: d.pop("/drive/speed_pi"), r"missing section '/drive/speed_pi'"),
    "mixed list": (  # rcl's parser refuses it: the nodes could not start
        lambda d: _plant(d).update(load_times=[0, 0.15, 0.3]),
        r"/drive/plant.load_times: \[0, 0.15, 0.3\] mixes float and int; a ROS 2 parameter "
        r"file's list holds one type",
    ),
    "unknown family": (
        lambda d: d["/drive/torque_controller"]["ros__parameters"].update(family="dtc_im"),
        r"/drive/torque_controller.family: 'dtc_im' is not one of mptc_im, mptc_pmsm",
    ),
    "no family": (
        lambda d: d["/drive/torque_controller"]["ros__parameters"].pop("family"),
        r"/drive/torque_controller: missing key 'family'; one of mptc_im, mptc_pmsm",
    ),
    "family of another machine": (
        lambda d: d["/drive/torque_controller"]["ros__parameters"].update(family="mptc_pmsm"),
        r"torque_controller.family: 'mptc_pmsm' controls a pmsm machine, but the scenario's "
        r"machine is 'induction'",
    ),
    "unknown machine": (
        lambda d: d["/**"]["ros__parameters"].update(machine="dc"),
        r"machine: 'dc' is not one of induction",
    ),
}


@pytest.mark.parametrize("case", CASES, ids=list(CASES))
def test_bad_scenario_errors_name_file_and_key(tmp_path, case):
    edit, message = CASES[case]
    path = _edit(tmp_path, edit)
    with pytest.raises(ConfigError, match=message) as e:
        load_scenario(path)
    assert str(path) in str(e.value)


def test_unknown_scenario_name_lists_available():
    with pytest.raises(
        ConfigError, match="available: hs_ipmsm_mtpa, hs_ipmsm_mtpa_short, hs_ipmsm_steady, "
    ) as e:
        load_scenario("nope")
    assert ", im_paper, im_short, " in str(e.value)


def test_dataclasses_are_frozen():
    sc = load_scenario("im_short")
    with pytest.raises(dataclasses.FrozenInstanceError):
        sc.plant.u_dc = 1.0  # type: ignore[misc]


def test_mtpa_scenarios_have_the_papers_values():
    hs = load_scenario("hs_ipmsm_mtpa")
    m = hs.plant.motor
    assert (m.r_s, m.l_d, m.l_q, m.psi_f, m.p, m.rated_torque, m.rated_speed_rpm) == (
        0.78, 0.0045, 0.0085, 0.303, 3, 6.5, 2000.0,
    )  # fmt: skip
    assert (hs.ts, hs.run.duration) == (2e-4, 3.0)
    assert hs.plant.load_times == (0.0, 1.0, 2.0) and hs.plant.load_values == (2.0, 4.0, 6.0)
    assert hs.speed_pi.speed_values_rpm[0] * 2 * 3.141592653589793 / 60 == pytest.approx(100.0)
    c = hs.controller
    assert (c.injection_amplitude, c.injection_hz, c.injection_form) == (0.05, 500.0, "corrected")
    assert hs.family == "foc_pmsm" and c.motor == m
    ip = load_scenario("ipmsm_mtpa")
    assert ip.plant.motor == load_scenario("ipmsm_validation").plant.motor  # paper 001's IPMSM
    assert ip.plant.load_values == (5.0, 10.0, 15.0)
    assert all(b - a >= 1.0 for a, b in zip(ip.plant.load_times, (*ip.plant.load_times[1:], 4.5)))


@pytest.mark.parametrize("value", [-0.1, math.nan, math.inf], ids=["negative", "nan", "inf"])
@pytest.mark.parametrize("scenario", ["im_short", "ipmsm_short"])
def test_a_switching_effort_must_be_a_finite_number_not_below_zero(scenario, value):
    from predictive_drive.config import apply_settings, load_scenario_text, resolve_scenario_path

    path = resolve_scenario_path(scenario)
    text = apply_settings(path.read_text(), {"torque_controller.lambda_sw": value}, path)
    with pytest.raises(ConfigError, match=r"lambda_sw must be a finite number >= 0") as e:
        load_scenario_text(text, path)
    assert str(path) in str(e.value)


def test_a_switching_effort_is_refused_where_no_finite_control_set_chooses():
    """Field-oriented control modulates: it has no candidates to weigh, so no lambda_sw."""
    from predictive_drive.config import apply_settings, load_scenario_text, resolve_scenario_path

    path = resolve_scenario_path("ipmsm_mtpa_short")
    hint = r"lambda_sw is a setting of the controller families mptc_im, mptc_pmsm; this "
    with pytest.raises(ConfigError, match=hint + "scenario's torque controller is foc_pmsm"):
        apply_settings(path.read_text(), {"torque_controller.lambda_sw": 0.1}, path)
    text = path.read_text().replace(
        "    strategy: foc_injection", "    lambda_sw: 0.1\n    strategy: foc_injection"
    )
    assert "lambda_sw" in text
    with pytest.raises(ConfigError, match=r"unknown key 'lambda_sw'; allowed keys: .*" + hint):
        load_scenario_text(text, path)


STEADY = ("im_steady", "ipmsm_steady", "hs_ipmsm_steady")


@pytest.mark.parametrize("name", STEADY)
def test_a_steady_point_is_the_same_drive_for_mptc_and_field_orientation(name):
    """<name> and <name>_foc: the same machine, inverter, held speed, torque and flux
    references and windows; they differ in the control period and the torque controller alone
    (the fronts compare the two at the same operating point)."""
    fcs, foc = load_scenario(name), load_scenario(f"{name}_foc")
    assert fcs.plant == foc.plant and fcs.speed_pi == foc.speed_pi and fcs.logger == foc.logger
    assert fcs.run.machine == foc.run.machine and fcs.run.duration == foc.run.duration
    assert fcs.family.startswith("mptc_") and foc.family.startswith("foc_")
    assert fcs.plant.held and fcs.speed_pi.torque_control and fcs.plant.period_means
    assert fcs.logger.thd_window == (fcs.logger.window_start, fcs.logger.window_end)


def test_a_held_shaft_refuses_a_load_profile(tmp_path):
    from predictive_drive.config import apply_settings, load_scenario_text, resolve_scenario_path

    path = resolve_scenario_path("ipmsm_steady")
    text = apply_settings(path.read_text(), {"plant.load_values": [5.0]}, path)
    with pytest.raises(ConfigError, match=r"plant.load_values: \[5.0\] with a held speed"):
        load_scenario_text(text, path)
