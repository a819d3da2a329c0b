"""Power devices from their datasheets and thermal networks (docs/physics.md#losses-and-temperature):
device files read and refused (naming the file, the field and the allowed range), conduction lines
and switching energies against their definitions, Foster and Cauer networks against their closed
forms."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from predictive_drive.config import (
    apply_settings,
    device_names,
    load_scenario_text,
    resolve_scenario_path,
)
from predictive_drive.core.devices import load_device
from predictive_drive.core.thermal import Cauer, Foster
from predictive_drive.errors import ConfigError

pytestmark = pytest.mark.core

DATA = Path(__file__).with_name("data")
LINEAR = DATA / "linear_igbt.json"  #: straight output lines, E ∝ i at 312 V, one temperature
FUJI = "fuji_2mbi100xaa120_50"
WOLFSPEED = "wolfspeed_c3m0060065j"


def scenario(name: str, settings: dict, strategy: str | None = None):
    p = resolve_scenario_path(name)
    return load_scenario_text(apply_settings(p.read_text(), settings, p), p).with_strategy(strategy)


# -- device files -------------------------------------------------------------------------------


def test_the_shipped_devices_load_with_their_datasheets_named():
    assert {FUJI, WOLFSPEED} <= set(device_names())
    for name, kind in ((FUJI, "IGBT"), (WOLFSPEED, "SiC-MOSFET")):
        d = scenario("ipmsm_short", {"plant.losses.device": name}).device
        assert d is not None and d.type == kind
        assert d.datasheet.startswith("https://") and d.datasheet_date and d.comment
        assert d.switch.lines and d.switch.energies and len(d.switch.r_th) == 4


def test_a_straight_output_curve_gives_its_own_line_and_energies_scale_with_voltage():
    d = load_device(LINEAR)
    assert d.switch.line(25.0) == pytest.approx((0.8, 0.01), abs=1e-12)
    assert d.diode.line(100.0) == pytest.approx((1.0, 0.012), abs=1e-12)  # one temperature: held
    assert d.switch.energy("e_on", 20.0, 25.0, 312.0) == pytest.approx(0.002 * 20 / 50, rel=1e-12)
    # (U_dc/V_ref)^K_v with the file's default K_v = 1, and beyond the curve its slope goes on
    assert d.switch.energy("e_off", 80.0, 25.0, 624.0) == pytest.approx(2 * 0.0015 * 80 / 50)
    assert d.diode.energy("e_on", 20.0, 25.0, 312.0) == 0.0  # a diode has none


def test_energies_and_lines_are_linear_in_junction_temperature_between_the_curves():
    d = load_device(resolve_scenario_path("im_short").parent / "devices" / f"{FUJI}.json")
    at = {ln.t_j: (ln.v0, ln.r) for ln in d.switch.lines}
    mid = d.switch.line(75.0)
    assert mid == pytest.approx([(a + b) / 2 for a, b in zip(at[25.0], at[125.0])], rel=1e-12)
    e25, e125 = (d.switch.energy("e_on", 30.0, t, 600.0) for t in (25.0, 125.0))
    assert d.switch.energy("e_on", 30.0, 75.0, 600.0) == pytest.approx((e25 + e125) / 2)
    assert d.switch.energy("e_on", 30.0, 200.0, 600.0) == d.switch.energy(
        "e_on", 30.0, 175.0, 600.0
    )


def _mutated(tmp_path: Path, change) -> Path:
    doc = json.loads(LINEAR.read_text())
    change(doc)
    p = tmp_path / "device.json"
    p.write_text(json.dumps(doc))
    return p


def _set(path: str, value):
    def change(doc):
        *keys, last = path.split(".")
        node = doc
        for k in keys:
            node = node[int(k)] if k.isdigit() else node[k]
        if value is _DELETE:
            del node[last]
        else:
            node[int(last) if last.isdigit() else last] = value

    return change


_DELETE = object()

BAD_DEVICES = [
    ("missing-field", _set("switch.channel", _DELETE), "switch.channel: missing field"),
    ("missing-type", _set("type", _DELETE), "type: missing field"),
    ("unknown-type", _set("type", "thyristor"), "is not one of IGBT, MOSFET, SiC-MOSFET"),
    ("negative-current", _set("switch.channel.0.graph_v_i", [[0.0, 0.8, 1.3], [0.0, -1.0, 50.0]]),
     "switch.channel[0].graph_v_i: point 1: -1.0 is not a finite number >= 0 A"),
    ("negative-energy", _set("diode.e_rr.0.graph_i_e", [[0.0, 50.0], [0.0, -0.001]]),
     "diode.e_rr[0].graph_i_e: point 1: -0.001 is not a finite number >= 0 J"),
    ("non-monotonic", _set("switch.e_on.0.graph_i_e", [[0.0, 30.0, 20.0], [0.0, 0.001, 0.002]]),
     "switch.e_on[0].graph_i_e: not monotonic: point 2 at 20 A after 30 A"),
    ("falling-output-curve",
     _set("switch.channel.0.graph_v_i", [[0.0, 0.8, 1.0, 1.3], [0.0, 30.0, 20.0, 50.0]]),
     "switch.channel[0].graph_v_i: not monotonic: the current falls from 30 A to 20 A"),
    ("millijoules", _set("switch.e_off.0.graph_i_e", [[0.0, 50.0], [0.0, 1.5]]),
     "energies are in J (not mJ)"),
    ("millivolts", _set("diode.channel.0.graph_v_i", [[0.0, 1000.0, 1600.0], [0.0, 0.0, 50.0]]),
     "diode.channel[0].graph_v_i: point 1: 1000.0 is not a finite number >= 0 and <= 50 V"),
    ("kelvin", _set("switch.channel.0.t_j", 298.15),
     "switch.channel[0].t_j: 298.15 is not a finite number >= -60 and <= 250 °C"),
    ("zero-r-th", _set("switch.thermal_foster.r_th_vector", [0.0, 0.3]),
     "switch.thermal_foster.r_th_vector[0]: 0.0 is not a finite number > 0 and <= 100 K/W"),
    ("negative-tau", _set("diode.thermal_foster.tau_vector", [0.01, -0.1]),
     "diode.thermal_foster.tau_vector[1]: -0.1 is not a finite number > 0 and <= 10000 s"),
    ("unequal-foster", _set("diode.thermal_foster.tau_vector", [0.01]),
     "r_th_vector has 2 terms, tau_vector 1"),
    ("curve-short-of-fit", _set("predictive_drive.fit_current", [2.0, 80.0]),
     "the conduction line is fitted over 2-80 A"),
]  # fmt: skip


@pytest.mark.parametrize(("change", "says"), [b[1:] for b in BAD_DEVICES],
                         ids=[b[0] for b in BAD_DEVICES])  # fmt: skip
def test_a_bad_device_file_is_refused_naming_file_field_and_range(tmp_path, change, says):
    path = _mutated(tmp_path, change)
    with pytest.raises(ConfigError) as e:
        scenario("ipmsm_short", {"plant.losses.device": str(path)})
    assert str(path) in str(e.value) and "plant.losses.device" in str(e.value)
    assert says in str(e.value), str(e.value)


def test_a_device_below_the_dc_links_voltage_is_refused():
    with pytest.raises(ConfigError, match=r"v_abs_max 650 V is below the DC link \(plant.u_dc 700"):
        scenario("ipmsm_short", {"plant.losses.device": WOLFSPEED, "plant.u_dc": 700.0})


@pytest.mark.parametrize(
    ("key", "value", "says"),
    [
        ("heatsink_r_th", 0.0, "heatsink_r_th must be a finite number > 0 K/W"),
        ("winding_tau", -5.0, "winding_tau must be a finite number > 0 s"),
        ("rotor_r_th", -1.0, "rotor_r_th must be a finite number > 0 K/W"),
        ("heatsink_tau", 0.0, "heatsink_tau must be a finite number > 0 s"),
    ],
)
def test_a_thermal_network_with_a_non_positive_r_or_tau_is_refused(key, value, says):
    with pytest.raises(ConfigError, match=r"im_short.yaml: /drive/plant.losses: " + says):
        scenario("im_short", {f"plant.losses.{key}": value, "plant.losses.machine": True})


def test_a_device_file_beside_a_constant_drop_is_refused():
    with pytest.raises(ConfigError, match="the device file gives the on-state voltages"):
        scenario("im_short", {"plant.losses.device": FUJI, "plant.device_drop": 1.0})


# -- thermal networks ---------------------------------------------------------------------------


def test_a_foster_network_follows_its_impedance_for_a_loss_step():
    f = Foster([[0.2, 0.3, 0.5]], [[0.002, 0.05, 1.0]], step=1e-3)
    rises = [float(f.advance(np.array([40.0]))[0]) for _ in range(3000)]
    for k in (1, 10, 100, 2999):
        t = (k + 1) * 1e-3
        z = sum(r * (1 - math.exp(-t / tau)) for r, tau in ((0.2, 0.002), (0.3, 0.05), (0.5, 1.0)))
        assert rises[k] == pytest.approx(40.0 * z, rel=1e-12)


def test_a_cauer_node_follows_its_step_response_and_a_ladder_settles_to_its_resistances():
    one = Cauer([120.0], [(0, None, 0.5)], coolant=40.0, step=0.1)
    for k in range(1, 3001):
        t = one.advance([30.0])[0]
        if k in (1, 100, 3000):  # τ = R·C = 60 s
            assert t - 40.0 == pytest.approx(
                30.0 * 0.5 * (1 - math.exp(-0.1 * k / 60.0)), rel=1e-10
            )
    fine = Cauer([100.0, 400.0], [(0, None, 0.5), (1, 0, 0.25)], coolant=40.0, step=0.001)
    coarse = Cauer([100.0, 400.0], [(0, None, 0.5), (1, 0, 0.25)], coolant=40.0, step=0.1)
    assert coarse.steady([20.0, 8.0]) == pytest.approx([54.0, 56.0])  # 40 + 0.5·28, + 0.25·8
    for _ in range(50):
        a = coarse.advance([20.0, 8.0])
        for _ in range(100):
            b = fine.advance([20.0, 8.0])
        assert a == pytest.approx(b, rel=1e-9)  # the same exact solution, in steps or at once
    for _ in range(100000):
        a = coarse.advance([20.0, 8.0])
    assert a == pytest.approx([54.0, 56.0], rel=1e-9)
