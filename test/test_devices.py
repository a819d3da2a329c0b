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
IGBT_MODULE = "semikron_skm150gb124d"
SIC_MOSFET = "wolfspeed_c3m0065100j"


def scenario(name: str, settings: dict, strategy: str | None = None):
    p = resolve_scenario_path(name)
    return load_scenario_text(apply_settings(p.read_text(), settings, p), p).with_strategy(strategy)


# -- device files -------------------------------------------------------------------------------


def test_the_shipped_devices_load_with_their_datasheets_named():
    assert {IGBT_MODULE, SIC_MOSFET} <= set(device_names())
    for name, kind in ((IGBT_MODULE, "IGBT"), (SIC_MOSFET, "SiC-MOSFET")):
        d = scenario("ipmsm_short", {"plant.losses.device": name}).device
        assert d is not None and d.type == kind
        assert d.datasheet_date and d.datasheet_version and d.comment
        assert len(d.switch.lines) == 2 and set(d.switch.energies) == {"e_on", "e_off"}
        assert len(d.switch.r_th) == 1 and "e_rr" in d.diode.energies


@pytest.mark.parametrize(
    ("name", "switch", "diode"),
    [
        # the tables' typical values: per temperature the line through V_CEsat (V_F) at 100 A
        # and 150 A, V = v0 + r i; the energies' one point each (J at A, V, degC)
        (IGBT_MODULE, {25.0: (1.1, 0.010, 2.1), 125.0: (1.0, 0.014, 2.4)},
         {25.0: (1.5, 0.005, 2.0), 125.0: (1.2, 0.006, 1.8)}),
        # R_DS(on) at 20 A; the body diode's V_SD at 10 A on a line from its 3.0 V knee
        (SIC_MOSFET, {25.0: (0.0, 0.065, 1.3), 150.0: (0.0, 0.090, 1.8)},
         {25.0: (3.0, 0.18, 4.8), 150.0: (3.0, 0.14, 4.4)}),
    ],
    ids=["igbt_module", "sic_mosfet"],
)  # fmt: skip
def test_a_shipped_device_holds_its_datasheets_typical_values(name, switch, diode):
    d = load_device(resolve_scenario_path("im_short").parent / "devices" / f"{name}.json")
    at = 100.0 if d.type == "IGBT" else None
    for part, table in ((d.switch, switch), (d.diode, diode)):
        for t_j, (v0, r, v_at) in table.items():
            assert part.line(t_j) == pytest.approx((v0, r), abs=1e-12)
            i = at or (20.0 if part is d.switch else 10.0)
            assert v0 + r * i == pytest.approx(v_at, abs=1e-12)
    energies = {  # (E at the test point, its current, voltage)
        IGBT_MODULE: {"e_on": (0.012, 100.0, 600.0), "e_off": (0.013, 100.0, 600.0)},
        SIC_MOSFET: {"e_on": (157e-6, 20.0, 700.0), "e_off": (35e-6, 20.0, 700.0)},
    }[name]
    for e, (joules, i, v) in energies.items():
        for t_j in (25.0, 150.0):  # one temperature in the table: held
            assert d.switch.energy(e, i, t_j, v) == pytest.approx(joules, rel=1e-12)
            assert d.switch.energy(e, i / 4, t_j, v) == pytest.approx(joules / 4, rel=1e-12)
    q_rr, i_rr, v_rr = (12e-6, 100.0, 600.0) if name == IGBT_MODULE else (310e-9, 20.0, 700.0)
    assert d.diode.energy("e_rr", i_rr, 125.0, v_rr) == pytest.approx(q_rr * v_rr / 4, rel=1e-12)


def test_a_straight_output_curve_gives_its_own_line_and_energies_scale_with_voltage():
    d = load_device(LINEAR)
    assert d.switch.line(25.0) == pytest.approx((0.8, 0.01), abs=1e-12)
    assert d.diode.line(100.0) == pytest.approx((1.0, 0.012), abs=1e-12)  # one temperature: held
    assert d.switch.energy("e_on", 20.0, 25.0, 312.0) == pytest.approx(0.002 * 20 / 50, rel=1e-12)
    # (U_dc/V_ref)^K_v with the file's default K_v = 1, and beyond the curve its slope goes on
    assert d.switch.energy("e_off", 80.0, 25.0, 624.0) == pytest.approx(2 * 0.0015 * 80 / 50)
    assert d.diode.energy("e_on", 20.0, 25.0, 312.0) == 0.0  # a diode has none


def test_energies_and_lines_are_linear_in_junction_temperature_between_the_curves(tmp_path):
    d = load_device(resolve_scenario_path("im_short").parent / "devices" / f"{IGBT_MODULE}.json")
    at = {ln.t_j: (ln.v0, ln.r) for ln in d.switch.lines}
    mid = d.switch.line(75.0)
    assert mid == pytest.approx([(a + b) / 2 for a, b in zip(at[25.0], at[125.0])], rel=1e-12)
    assert d.switch.line(200.0) == d.switch.line(125.0)  # held beyond the curves
    # energies given at two temperatures (the test device's E_on again at 125 degC, doubled)
    doc = json.loads(LINEAR.read_text())
    hot = json.loads(json.dumps(doc["switch"]["e_on"][0]))
    hot["t_j"], hot["graph_i_e"][1] = 125, [0.0, 0.004]
    doc["switch"]["e_on"].append(hot)
    (tmp_path / "two.json").write_text(json.dumps(doc))
    two = load_device(tmp_path / "two.json")
    e25, e125 = (two.switch.energy("e_on", 30.0, t, 312.0) for t in (25.0, 125.0))
    assert e125 == pytest.approx(2 * e25, rel=1e-12)
    assert two.switch.energy("e_on", 30.0, 75.0, 312.0) == pytest.approx((e25 + e125) / 2)
    assert two.switch.energy("e_on", 30.0, 200.0, 312.0) == pytest.approx(e125, rel=1e-12)


def _mutated(tmp_path: Path, change) -> Path:
    doc = json.loads(LINEAR.read_text())
    change(doc)
    p = tmp_path / "device.json"
    p.write_text(json.dumps(doc))
    return p


def _parent(doc, path: str):
    """(the object holding the field at dotted ``path``, the field's last key)."""
    *keys, last = path.split(".")
    node = doc
    for k in keys:
        node = node[int(k)] if k.isdigit() else node[k]
    return node, last


def _set(path: str, value):
    def change(doc):
        node, last = _parent(doc, path)
        if value is _DELETE:
            del node[last]
        else:
            node[int(last) if last.isdigit() else last] = value

    return change


_DELETE = object()


def _rename(path: str, new: str):
    """A change that renames the field at ``path`` to ``new`` (a misspelling)."""

    def change(doc):
        node, last = _parent(doc, path)
        node[new] = node.pop(last)

    return change


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
    ("missing-e-off", _set("switch.e_off", _DELETE), "switch.e_off: missing field"),
    ("missing-e-on", _set("switch.e_on", _DELETE), "switch.e_on: missing field"),
    ("missing-e-rr", _set("diode.e_rr", _DELETE), "diode.e_rr: missing field"),
    ("misspelt-e-off", _rename("switch.e_off", "e_of"),
     "switch.e_of: unknown field; the allowed ones: comment, manufacturer, technology, t_j_max, "
     "thermal_foster, channel, e_on, e_off, e_on_meas"),
    ("misspelt-in-energy", _rename("switch.e_on.0.v_supply", "v_suply"),
     "switch.e_on[0].v_suply: unknown field; the allowed ones: dataset_type"),
    ("misspelt-in-channel", _rename("diode.channel.0.t_j", "tj"),
     "diode.channel[0].tj: unknown field; the allowed ones: t_j, v_g, graph_v_i"),
    ("misspelt-own", _rename("predictive_drive.fit_current", "fit_currents"),
     "predictive_drive.fit_currents: unknown field; the allowed ones: fit_current, "
     "voltage_exponent"),
    ("energy-without-a-curve",
     _set("switch.e_off", [{"dataset_type": "single", "t_j": 25, "v_supply": 312, "v_g": 15,
                            "e_x": 0.001, "i_x": 50, "r_g": 5}]),
     "switch.e_off: no dataset of dataset_type graph_i_e"),
    ("unknown-dataset-type", _set("switch.e_off.0.dataset_type", "graph_i_x"),
     "switch.e_off[0].dataset_type: 'graph_i_x' is not one of graph_i_e, single"),
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
    with pytest.raises(
        ConfigError, match=r"v_abs_max 1000 V is below the DC link \(plant.u_dc 1100"
    ):
        scenario("ipmsm_short", {"plant.losses.device": SIC_MOSFET, "plant.u_dc": 1100.0})


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
        scenario("im_short", {"plant.losses.device": IGBT_MODULE, "plant.device_drop": 1.0})


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
