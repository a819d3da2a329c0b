"""Losses and temperatures in the plant (docs/physics.md#losses-and-temperature): the energy
balance of every family, the SVPWM losses against the textbook's average-loss formulas, one
model of a conducting device, the temperatures fed back, and the figures a recording gives."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from predictive_drive.core.devices import Device, Line, Part, load_device
from predictive_drive.core.losses import LossParams
from predictive_drive.core.metrics import compute_metrics, whole_cycles
from predictive_drive.core.runner import build, run_inprocess
from predictive_drive.core.signals import DEVICES, LOSS_FIELDS, Losses, State
from predictive_drive.core.thermal import COPPER_ALPHA, resistance_at
from test_devices import IGBT_MODULE, LINEAR, SIC_MOSFET, scenario

LOSSES_FIELDS = Losses._fields

pytestmark = pytest.mark.core


# -- the plant's losses -------------------------------------------------------------------------

#: every family on a real drive with losses: IM and PMSM, MPTC, FOC and direct MPC, free shafts
#: and held ones, dead time, device files, machine losses with iron losses
FAMILIES = [
    ("im_short", "db_mptc", IGBT_MODULE, 0.1),
    ("im_steady_foc", "ifoc", IGBT_MODULE, 0.1),
    ("ipmsm_short", "mptc", SIC_MOSFET, 0.1),
    ("ipmsm_steady_foc", "foc_formula", SIC_MOSFET, 0.08),
    ("ipmsm_steady_mpc", "direct_mpc", SIC_MOSFET, 0.05),
    ("hs_ipmsm_mtpa_short", "foc_injection", SIC_MOSFET, 0.3),
]


def _stored_magnetic_energy(tr, sc) -> np.ndarray:
    """(3/2)·½·Σψ·i of the machine, from the recorded state (the inductances do not follow
    temperature)."""
    m = sc.plant.motor
    i = tr.truth("i_alpha") + 1j * tr.truth("i_beta")
    if sc.machine.value == "pmsm":
        i_dq = i * np.exp(-1j * tr.truth("theta_e"))
        return 0.75 * (m.l_d * i_dq.real**2 + m.l_q * i_dq.imag**2)
    psi = tr.col("state", "psi_alpha") + 1j * tr.col("state", "psi_beta")
    i_r = (psi - m.l_s * i) / m.l_m
    psi_r = m.l_m * i + m.l_r * i_r
    return 0.75 * ((psi * np.conj(i)).real + (psi_r * np.conj(i_r)).real)


@pytest.mark.parametrize(("name", "strategy", "device", "duration"), FAMILIES,
                         ids=[f[1] for f in FAMILIES])  # fmt: skip
def test_the_energy_drawn_from_the_dc_link_is_every_loss_work_and_stored_energy(
    name, strategy, device, duration
):
    """∫u_dc·i_dc = into the load + friction + copper + conduction + Δ(½Jω²) + Δ(magnetic energy),
    within 0.1 % of the DC link's energy: the losses the plant's equations contain booked as
    they act (switching and iron losses, drawn from the waveforms, are on both sides)."""
    settings = {
        "plant.dead_time": 1e-6,
        "plant.losses.device": device,
        "plant.losses.machine": True,
        "plant.losses.iron_hysteresis": 2.0,
        "plant.losses.iron_eddy": 0.02,
        "plant.losses.winding_tau": 0.05,  # hot within the run: R_s moves under the balance
        "plant.losses.winding_r_th": 2.0,
    }
    sc = scenario(name, settings, strategy)
    tr = run_inprocess(sc, steps=round(duration / sc.ts))
    energy = {f: float(np.sum(tr.col("losses", f)[1:])) * sc.ts for f in LOSS_FIELDS[:9]}
    m = sc.plant.motor
    w = tr.truth("omega_m")
    kinetic = 0.0 if sc.plant.held else 0.5 * m.j * (w[-1] ** 2 - w[0] ** 2)
    magnetic = _stored_magnetic_energy(tr, sc)
    spent = (
        energy["p_shaft"] + energy["p_friction"] + energy["p_copper"] + energy["p_cond_t"]
        + energy["p_cond_d"] + kinetic + magnetic[-1] - magnetic[0]
    )  # fmt: skip
    drawn = float(np.sum(np.abs(tr.col("losses", "p_dc")[1:]))) * sc.ts
    assert abs(energy["p_dc"] - spent) < 1e-3 * drawn, (energy, kinetic, magnetic[-1])
    assert energy["p_copper"] > 0 and energy["p_cond_t"] > 0 and energy["p_sw_t"] > 0
    assert energy["p_iron"] > 0
    assert tr.col("losses", "t_winding")[-1] > sc.plant.losses.coolant + 0.5


def _linear_device() -> Device:
    return load_device(LINEAR)


#: steady points of the IPMSM under FOC + SVPWM (20 kHz): torque N·m, speed r/min
SVPWM_POINTS = [(5.0, 1000.0), (15.0, 1000.0), (10.0, 500.0), (15.0, 300.0)]


@pytest.mark.parametrize(
    ("torque", "rpm"), SVPWM_POINTS, ids=[f"{t:g}Nm-{n:g}rpm" for t, n in SVPWM_POINTS]
)
def test_svpwm_losses_agree_with_the_closed_form_average_losses(torque, rpm):
    """Per device, with Î the current's fundamental amplitude, m = 2Û/U_dc and cos φ measured
    from the run (textbook average-loss formulas for sinusoidal PWM):
    P_cond,T = V_CE0·Î(1/2π + m cos φ/8) + r_CE·Î²(1/8 + m cos φ/3π),
    P_cond,D = V_F0·Î(1/2π - m cos φ/8) + r_F·Î²(1/8 - m cos φ/3π),
    P_sw,T = f_sw·(E_on + E_off)(Î)/π, P_sw,D = f_sw·E_rr(Î)/π (E ∝ i, at U_dc) — within 3 %."""
    settings = {
        "ts": 5e-5,
        "plant.losses.device": str(LINEAR),
        "speed_pi.torque_times": [0.0],
        "speed_pi.torque_values": [torque],
        "plant.held_speed_rpm": [rpm],
        "speed_pi.speed_values_rpm": [rpm],
    }
    sc = scenario("ipmsm_steady_foc", settings, "foc_formula")
    tr = run_inprocess(sc, steps=3000)
    w = whole_cycles(tr, 0.05, 0.15)
    sl, n = slice(w.k0, w.k0 + w.n), w.n
    turn = np.exp(-1j * w.direction * 2 * np.pi * w.cycles / n * np.arange(n))
    i1 = 2 / n * np.sum(tr.truth("i_alpha")[sl] * turn)
    da, db, dc = (tr.col("command", f"duty_{x}")[sl] for x in "abc")
    v_a = sc.plant.u_dc * (da - (da + db + dc) / 3)  # period k's mean, centred at k + 1/2
    v1 = 2 / n * np.sum(v_a * turn * np.exp(-1j * w.direction * np.pi * w.cycles / n))
    peak, m = abs(i1), 2 * abs(v1) / sc.plant.u_dc
    mc = m * math.cos(np.angle(v1) - np.angle(i1))
    d = _linear_device()
    (v_t, r_t), (v_d, r_d) = d.switch.line(25.0), d.diode.line(25.0)
    f_sw = 1.0 / sc.ts
    expected = {
        "p_cond_t": v_t * peak * (1 / (2 * np.pi) + mc / 8) + r_t * peak**2 * (1 / 8 + mc / (3 * np.pi)),
        "p_cond_d": v_d * peak * (1 / (2 * np.pi) - mc / 8) + r_d * peak**2 * (1 / 8 - mc / (3 * np.pi)),
        "p_sw_t": f_sw * sum(d.switch.energy(e, peak, 25, 312) for e in ("e_on", "e_off")) / np.pi,
        "p_sw_d": f_sw * d.diode.energy("e_rr", peak, 25, 312) / np.pi,
    }  # fmt: skip
    periods = slice(w.k0 + 1, w.k0 + w.n + 1)
    for field, value in expected.items():
        per_device = float(np.mean(tr.col("losses", field)[periods])) / 6
        assert per_device == pytest.approx(value, rel=0.03), field


def test_a_device_of_constant_on_state_voltage_is_the_plants_device_drop_bit_for_bit():
    """One model of a conducting device: the device file's on-state voltage is the drop the
    plant's equations contain — a device of 1.5 V at every current and temperature gives the
    trajectory of ``device_drop: 1.5`` to the bit."""
    flat = Part(175.0, (0.1,), (0.01,), (Line(25.0, 1.5, 0.0),))
    device = dataclasses.replace(_linear_device(), switch=flat, diode=flat)
    real = {"plant.dead_time": 2e-6, "plant.device_drop": 1.5}
    dropped = run_inprocess(scenario("im_short", real, "mptc"), steps=2000)
    sc = scenario("im_short", {**real, "plant.device_drop": 0.0}, "mptc")
    sc = dataclasses.replace(
        sc, plant=dataclasses.replace(sc.plant, losses=LossParams(device="flat")), device=device
    )
    booked = run_inprocess(sc, steps=2000)
    assert np.array_equal(dropped.state, booked.state, equal_nan=True)
    assert np.array_equal(dropped.command[:, :-1], booked.command[:, :-1], equal_nan=True)
    assert not dropped.has_losses and len(booked.losses) == len(booked.state)
    assert np.isfinite(booked.col("losses", "p_cond_d")[1:]).all()


def test_junction_and_winding_temperatures_set_the_devices_and_the_plants_parameters():
    """Every thermal step the devices' lines follow their T_j and the plant's R_s and ψ_f its
    winding and rotor temperatures; the controller keeps its nominal model."""
    settings = {
        "plant.losses.device": SIC_MOSFET,
        "plant.losses.machine": True,
        "plant.losses.winding_tau": 0.02,
        "plant.losses.rotor_tau": 0.02,
        "plant.losses.winding_r_th": 1.0,
        "plant.losses.heatsink_r_th": 2.0,
        "plant.losses.heatsink_tau": 0.05,
    }
    sc = scenario("ipmsm_short", settings, "mptc")
    c = build(sc)
    state = c.plant.state()
    ref = c.speed_pi.initial()
    for _ in range(2000):
        cmd = c.controller.step(state, ref)
        ref = c.speed_pi.step(state)
        state = c.plant.step(cmd)
    p, m, d = c.plant, sc.plant.motor, sc.device
    s = p.losses()._asdict()
    assert s["k"] == state.k and s["t_winding"] > 60.0 and s["t_rotor"] > 45.0
    t_ref = sc.plant.losses.motor_temperature
    assert p._coef.r_s == pytest.approx(resistance_at(m.r_s, s["t_winding"], t_ref, COPPER_ALPHA))
    assert p._coef.psi_f == pytest.approx(m.psi_f * (1 - 0.0011 * (s["t_rotor"] - t_ref)))
    assert c.controller.params.motor == sc.controller.motor  # nominal, untouched
    for k, name in enumerate(DEVICES):
        part = d.switch if name.startswith("t") else d.diode
        assert (p._v0[k], p._r[k]) == pytest.approx(part.line(s[f"tj_{name}"]))
    assert min(s[f"tj_{n}"] for n in DEVICES) > s["t_sink"] > sc.plant.losses.coolant


def test_a_run_without_losses_has_no_loss_figures_and_one_with_them_reads_them_back(tmp_path):
    from predictive_drive.api.report import report
    from predictive_drive.api.run import run_inprocess_to_bag

    plain = compute_metrics(run_inprocess(scenario("ipmsm_short", {}), steps=400))
    assert math.isnan(plain.p_in) and plain.tj_max_device == ""
    settings = {"plant.losses.device": SIC_MOSFET, "plant.losses.machine": True}
    sc = scenario("ipmsm_short", settings).with_duration(0.05)
    run_inprocess_to_bag(sc, tmp_path / "bag")
    r = report(tmp_path / "bag")
    tr = run_inprocess(sc)
    k0, k1 = round(r.metrics.t_start / sc.ts), round(r.metrics.t_end / sc.ts)
    periods = slice(k0 + 1, k1 + 1)
    inverter = sum(float(np.mean(tr.col("losses", f)[periods])) for f in LOSS_FIELDS[5:9])
    assert r.metrics.p_inverter == pytest.approx(inverter, rel=1e-12)
    tj = np.array([tr.col("losses", f"tj_{n}")[k0:k1] for n in DEVICES])
    assert r.metrics.tj_max == pytest.approx(float(tj.max()))
    assert r.metrics.tj_max_device == DEVICES[int(np.argmax(tj.max(axis=1)))]
    assert 0.0 < r.metrics.efficiency < 1.0 or math.isnan(r.metrics.efficiency)
    assert r.details.device == "C3M0065100J" and r.details.rated_tj == (150.0, 150.0)
    from predictive_drive.core.metrics import METRICS

    for m in (plain, r.metrics):  # every declared figure formats, a sweep's or a table's
        scalars = {k: v for k, v in m.as_dict().items() if isinstance(v, (int, float, str))}
        shown = {k: METRICS[k].with_unit(v) for k, v in scalars.items()}
        assert shown["tj_max_device"] == (r.metrics.tj_max_device if m is r.metrics else "-")
    # an independent reader sees them on /drive/losses, one message a step, by label; the
    # state is as without losses, and a run without them has no such topic
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    run_inprocess_to_bag(scenario("ipmsm_short", {}).with_duration(0.005), tmp_path / "plain")
    rows: dict[str, list[dict[str, float]]] = {}
    store = get_typestore(Stores.ROS2_JAZZY)
    for bag in ("bag", "plain"):
        with AnyReader([tmp_path / bag], default_typestore=store) as rd:
            topics = {c.topic for c in rd.connections}
            assert ("/drive/losses" in topics) == (bag == "bag"), topics
            conns = [c for c in rd.connections if c.topic in ("/drive/losses", "/drive/state")]
            for conn, _, raw in rd.messages(connections=conns):
                msg = rd.deserialize(raw, conn.msgtype)
                labels = msg.layout.dim[0].label.split(",")
                rows.setdefault(f"{bag}{conn.topic}", []).append(dict(zip(labels, msg.data)))
    losses = rows["bag/drive/losses"]
    assert len(losses) == len(tr.state) == len(rows["bag/drive/state"])
    assert list(losses[0]) == list(LOSSES_FIELDS)
    for field in ("k", "p_dc", "p_sw_t", "tj_ta_hi", "t_sink", "t_winding"):
        assert [row[field] for row in losses] == tr.col("losses", field).tolist()
    for bag in ("bag", "plain"):
        assert list(rows[f"{bag}/drive/state"][0]) == list(State._fields)


def test_a_recording_that_sent_the_losses_in_the_state_reads_them_back(tmp_path):
    """A bag of the version whose state carried the losses (``p_dc`` … ``t_rotor`` after the
    state's fields) reads back with its losses, by label."""
    from predictive_drive.bag import BagWriter
    from predictive_drive.codec import CODECS, MultiArrayCodec, stamp_ns
    from predictive_drive.readback import read_bag
    from predictive_drive.recording import bag_info

    sc = scenario("ipmsm_short", {"plant.losses.device": SIC_MOSFET}).with_duration(0.005)
    tr = run_inprocess(sc)
    old = MultiArrayCodec(State._fields + LOSS_FIELDS)
    with BagWriter(tmp_path / "old", info=bag_info(sc, "inprocess")) as w:
        for k in range(len(tr.state)):
            ns = stamp_ns(tr.state[k, 1])
            w.write("state", ns, old.encode((*tr.state[k], *tr.losses[k, 2:])))
            w.write("reference", ns, CODECS["reference"].encode(tuple(tr.reference[k])))
            if k < tr.steps:
                w.write("command", ns, CODECS["command"].encode(tuple(tr.command[k])))
    back, _ = read_bag(tmp_path / "old")
    np.testing.assert_array_equal(back.state, tr.state)
    np.testing.assert_array_equal(back.losses, tr.losses)


def test_a_device_above_its_rated_junction_temperature_is_named_with_when(tmp_path):
    from predictive_drive.core.losses import overheats

    settings = {
        "plant.losses.device": SIC_MOSFET,
        "plant.losses.mounting_r_th": 30.0,  # a device hung in the air
        "plant.losses.thermal_step": 5e-5,
    }
    sc = scenario("ipmsm_short", settings, "mptc")
    tr = run_inprocess(sc, steps=3000)
    over = overheats(tr, sc.device)
    assert over, "no device ran hot"
    first = over[0]
    tj = tr.col("losses", f"tj_{first.device}")
    k = round(first.t_first / sc.ts)
    assert tj[k] > 150.0 >= np.max(tj[:k]) and first.tj_max == pytest.approx(np.max(tj))


def test_the_losses_figure_draws_the_recorded_losses_and_temperatures():
    pytest.importorskip("matplotlib")
    from predictive_drive.reports.figures import Run, run_figures

    settings = {"plant.losses.device": IGBT_MODULE, "plant.losses.machine": True}
    sc = scenario("im_short", settings, "db_mptc")
    tr = run_inprocess(sc, steps=1000)
    fig = run_figures(Run(tr, sc, "im_short"))["losses"]
    ax, tx = fig.axes
    lines = {ln.get_label(): ln for ln in ax.get_lines()}
    m = round(sc.plant.losses.thermal_step / sc.ts)
    p = tr.col("losses", "p_sw_t")[1:]
    drawn = lines["switching, transistors"]
    np.testing.assert_allclose(drawn.get_xdata(), tr.col("state", "t")[m:])
    np.testing.assert_allclose(drawn.get_ydata()[5], p[5 : 5 + m].mean(), rtol=1e-12)
    temps = {ln.get_label(): ln for ln in tx.get_lines()}
    assert len(temps) == len(DEVICES) + 3
    np.testing.assert_array_equal(temps["T_j ta_hi"].get_ydata(), tr.col("losses", "tj_ta_hi"))
    np.testing.assert_array_equal(temps["winding"].get_ydata(), tr.col("losses", "t_winding"))
    looks = {(str(ln.get_color()), ln.get_linestyle()) for ln in temps.values()}
    assert len(looks) == len(temps)  # every temperature told apart (was: 13 lines, 10 colours)


def test_the_live_views_layout_plots_every_junction_temperature():
    from predictive_drive.interface import TOPICS
    from predictive_drive.reports.layout import foxglove_layout

    panels = foxglove_layout()["configById"].values()
    (temps,) = [p for p in panels if p.get("title", "").startswith("temperatures")]
    fields = TOPICS["losses"].fields
    named = [fields[int(p["value"].split("[")[1].rstrip("]"))] for p in temps["paths"]]
    assert named == [*(f"tj_{d}" for d in DEVICES), "t_sink", "t_winding", "t_rotor"]


def test_the_drive_cycle_heats_the_plant_away_from_the_controllers_model():
    """ipmsm_drive_cycle (docs/physics.md#a-drive-cycle): 60 s with the SiC devices and the
    machine's losses; its first tenth of a second, the winding's time constant shortened so it
    heats within it: the plant's R_s leaves the controller's, which stays at 20 °C."""
    sc = scenario("ipmsm_drive_cycle", {"plant.losses.winding_tau": 0.05})
    assert sc.run.duration >= 60.0 and sc.device is not None and sc.device.type == "SiC-MOSFET"
    assert len(set(sc.speed_pi.speed_values_rpm)) >= 5 and len(set(sc.plant.load_values)) >= 5
    c = build(sc)
    state, ref = c.plant.state(), c.speed_pi.initial()
    for _ in range(2000):
        cmd = c.controller.step(state, ref)
        ref = c.speed_pi.step(state)
        state = c.plant.step(cmd)
    s = c.plant.losses()._asdict()
    assert (
        s["k"] == state.k
        and s["t_winding"] > 21.0
        and c.plant._coef.r_s > 1.003 * sc.controller.motor.r_s
    )
    assert sc.controller.motor == sc.plant.motor  # the controller's model is the plant's at 20 °C
    assert all(math.isfinite(s[f]) for f in LOSS_FIELDS) and s["p_iron"] > 0


def test_report_prints_the_losses_efficiency_and_a_device_above_its_rating(tmp_path, capsys):
    from predictive_drive.api.report import report
    from predictive_drive.api.run import run_inprocess_to_bag
    from predictive_drive.cli.common import print_recording

    settings = {
        "plant.losses.device": SIC_MOSFET,
        "plant.losses.machine": True,
        "plant.losses.mounting_r_th": 30.0,  # a device hung in the air: it runs hot
        "plant.losses.thermal_step": 5e-5,
    }
    run_inprocess_to_bag(scenario("ipmsm_short", settings).with_duration(0.15), tmp_path / "b")
    r = report(tmp_path / "b")
    print_recording(r)
    out = capsys.readouterr().out
    m = r.metrics
    assert f"T {m.p_cond_t:.3g} W  D {m.p_cond_d:.3g} W" in out
    assert f"{100 * m.efficiency:.2f} %" in out and "into the load of" in out
    assert f"{m.tj_max:.1f} °C" in out and f"{m.tj_max_device} at" in out and "(rated 150" in out
    (o, *_) = r.details.overheats
    assert f"{'OVER T_j':<11}{o.device:>16}   above its rated 150 °C from {o.t_first:.4g} s" in out


#: runs of every way the ledger books: both devices, a machine's losses with and without a device
#: file, iron losses, an induction motor's rotor copper, a speed a load machine holds, dead time,
#: the thermal step every period
BOOKED = [
    ("im_short", "db_mptc", {"plant.losses.device": IGBT_MODULE, "plant.losses.machine": True,
                             "plant.losses.iron_hysteresis": 1.0, "plant.losses.iron_eddy": 0.01}),
    ("im_steady_foc", "ifoc", {"plant.losses.device": IGBT_MODULE, "plant.dead_time": 2e-6,
                               "plant.losses.thermal_step": 0.0}),
    ("ipmsm_short", "mptc", {"plant.losses.device": SIC_MOSFET, "plant.losses.machine": True,
                             "plant.losses.iron_hysteresis": 2.0}),
    ("ipmsm_steady_foc", "foc_formula", {"plant.losses.device": LINEAR.name and str(LINEAR)}),
    ("spmsm_short", "mptc", {"plant.losses.machine": True}),
]  # fmt: skip


def _booked(monkeypatch, booking, thermal, steps=600):
    """The BOOKED runs with the ledger's booking ``booking`` and thermal step ``thermal`` (None:
    the per-period reference in Python)."""
    from predictive_drive.core import losses

    monkeypatch.setattr(losses, "compiled_booking", lambda: booking)
    monkeypatch.setattr(losses, "compiled_thermal", lambda: thermal)
    return [run_inprocess(scenario(n, s, st), steps=steps) for n, st, s in BOOKED]


@pytest.mark.parametrize("how", ["python", "compiled"])
def test_the_compiled_booking_is_the_reference_bit_for_bit(monkeypatch, how):
    """The kernel (core/losses_kernel.py) books a thermal step's periods at once with the
    reference's arithmetic in its order: the same losses, temperatures and trajectory, bit for
    bit — run as plain Python (no numba needed) and compiled."""
    from predictive_drive.core import losses_kernel as lk

    if how == "compiled":
        if lk.kernel_unavailable():
            pytest.skip(lk.kernel_unavailable())
        booking, thermal = lk.compiled_booking(), lk.compiled_thermal()
    else:
        booking, thermal = lk.book, lk.thermal
    kernel = _booked(monkeypatch, booking, thermal)
    reference = _booked(monkeypatch, None, None)
    for a, b, (name, _, _) in zip(kernel, reference, BOOKED):
        assert a.has_losses and len(a.losses) == len(a.state), name
        np.testing.assert_array_equal(a.losses, b.losses, err_msg=name)
        np.testing.assert_array_equal(a.state, b.state, err_msg=name)


def test_a_window_without_an_efficiency_says_why():
    """Where the powers in and out flow opposite ways over the window (im_short's load reverses:
    -42 W into the load, 349 W from the DC link) η is '-' and the printout says why."""
    from types import SimpleNamespace

    from predictive_drive.cli.common import _no_efficiency

    assert _no_efficiency(SimpleNamespace(efficiency=0.9, p_in=100.0, p_out=90.0)) == ""
    driven = _no_efficiency(SimpleNamespace(efficiency=math.nan, p_in=348.5, p_out=-42.44))
    assert "the load drives the machine" in driven
    giving = _no_efficiency(SimpleNamespace(efficiency=math.nan, p_in=-10.0, p_out=20.0))
    assert "stored energy" in giving
