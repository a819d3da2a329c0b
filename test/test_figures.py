"""Figures (docs/recordings.md): what each draws is the recording's own data, read back from the artists."""

from __future__ import annotations

import numpy as np
import pytest

from predictive_drive.config import load_scenario
from predictive_drive.core.metrics import phase_a_spectrum
from predictive_drive.core.runner import run_inprocess
from predictive_drive.reports.figures import Run, compare_figures, run_figures, save

pytestmark = pytest.mark.core

RPM = 60 / (2 * np.pi)
THD = (0.04, 0.1)  #: ipmsm_short's THD window


@pytest.fixture(scope="module")
def runs():
    out = {}
    for scenario, strategy in (("ipmsm_short", "mptc"), ("ipmsm_short", "simplified3"),
                               ("hs_ipmsm_mtpa_short", "foc_injection")):  # fmt: skip
        sc = load_scenario(scenario, strategy=strategy, duration=0.3)
        out[strategy] = Run(run_inprocess(sc), sc, f"{scenario} {strategy}")
    return out


def lines(fig, axis=0):
    return [
        (np.asarray(ln.get_xdata()), np.asarray(ln.get_ydata()))
        for ln in fig.axes[axis].get_lines()
    ]  # noqa: E501


def test_each_figure_draws_the_recorded_samples(runs, tmp_path):
    r = runs["mptc"]
    tr = r.trace
    t = tr.col("state", "t")
    figs = run_figures(r)
    assert set(figs) == {"speed", "torque", "flux", "current", "vectors"}
    (x, w), (_, w_ref) = lines(figs["speed"])
    np.testing.assert_array_equal(x, t)
    np.testing.assert_array_equal(w, tr.col("state", "omega_m") * RPM)
    np.testing.assert_array_equal(w_ref, tr.col("reference", "speed_ref") * RPM)
    for axis in (0, 1):  # the whole run and the zoomed window hold the same data
        (_, te), (_, t_ref) = lines(figs["torque"], axis)
        np.testing.assert_array_equal(te, tr.col("state", "torque"))
        np.testing.assert_array_equal(t_ref, tr.col("reference", "torque_ref"))
    (_, psi), _ = lines(figs["flux"])
    pa, pb = tr.col("state", "psi_alpha"), tr.col("state", "psi_beta")
    np.testing.assert_array_equal(psi, np.hypot(pa, pb))
    ((lx, ly),) = lines(figs["flux"], 1)
    np.testing.assert_array_equal(lx, pa)
    np.testing.assert_array_equal(ly, pb)
    ((_, ia),) = lines(figs["current"])
    np.testing.assert_array_equal(ia, tr.col("state", "i_alpha"))
    ((_, amp),) = lines(figs["current"], 1)
    np.testing.assert_array_equal(amp, phase_a_spectrum(tr, *THD).amplitude)
    heights = [b.get_height() for b in figs["vectors"].axes[0].patches]
    vec = tr.col("command", "vector").astype(int)
    np.testing.assert_allclose(heights, np.bincount(vec, minlength=7) / vec.size, rtol=1e-12)
    files = save(figs, tmp_path)
    assert {f.name for f in files} == {f"{n}.png" for n in figs}
    assert all(f.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for f in files)


def test_the_field_oriented_figure_draws_angle_and_currents(runs):
    r = runs["foc_injection"]
    tr = r.trace
    figs = run_figures(r)
    assert "foc" in figs and "vectors" not in figs
    (_, theta), _ = lines(figs["foc"])
    np.testing.assert_array_equal(theta, np.degrees(tr.col("command", "current_angle")))
    (_, i_d), (_, i_q), (_, d_ref), (_, q_ref) = lines(figs["foc"], 1)
    n = tr.steps
    i = (tr.col("state", "i_alpha") + 1j * tr.col("state", "i_beta"))[:n]
    i_dq = i * np.exp(-1j * tr.col("state", "theta_e")[:n])
    np.testing.assert_allclose(i_d, i_dq.real, rtol=0, atol=1e-12)
    np.testing.assert_allclose(i_q, i_dq.imag, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(d_ref, tr.col("command", "i_d_ref"))
    np.testing.assert_array_equal(q_ref, tr.col("command", "i_q_ref"))


def test_compare_overlays_each_run(runs):
    both = [runs["mptc"], runs["simplified3"]]
    figs = compare_figures(both)
    got = lines(figs["torque"])
    assert len(got) == 2
    for (_, te), r in zip(got, both):
        np.testing.assert_array_equal(te, r.trace.col("state", "torque"))
    labels = [ln.get_label() for ln in figs["torque"].axes[0].get_lines()]
    assert labels == ["ipmsm_short mptc", "ipmsm_short simplified3"]


def test_the_foxglove_layout_is_generated_and_names_the_right_fields():
    """Every plotted path's position holds the field its label names, and the shipped layout
    file is what the command writes now."""
    import json
    from pathlib import Path

    from predictive_drive.interface import TOPICS
    from predictive_drive.reports.layout import PLOTS, foxglove_layout

    layout = foxglove_layout()
    by_name = {t.name: t for t in TOPICS.values()}
    plots = [c for k, c in layout["configById"].items() if k.startswith("Plot!")]
    assert len(plots) == len(PLOTS)
    seen = 0
    for plot in plots:
        for p in plot["paths"]:
            topic, _, index = p["value"].partition(".data[")
            field = by_name[topic].fields[int(index.rstrip("]"))]
            assert p["label"].endswith(f".{field}"), (p["value"], p["label"])
            seen += 1
    assert seen == sum(len(s) for s in PLOTS.values())
    shipped = Path(__file__).parents[1] / "layouts" / "drive.foxglove.json"
    # regenerate: predictive-drive layout --out layouts/drive.foxglove.json
    assert json.loads(shipped.read_text()) == layout
