"""Paper-style figures of a recording (matplotlib, no display): speed, torque (with a zoomed
window), stator-flux magnitude and locus, phase-a current with its spectrum and THD, vector
utilization (MPTC), current angle and dq currents (field-oriented control), losses and
temperatures (a run with losses); and the same overlaid for several runs.

Every line plots the recording's own samples, undecimated (a test reads them back from the
artists and compares them with the recording).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.machines import Machine
from ..core.metrics import METRICS, phase_a_spectrum
from ..core.scenario import Scenario
from ..core.signals import DEVICES
from ..core.trace import Trace
from ..dependencies import missing

__all__ = [
    "Run",
    "compare_figures",
    "efficiency_figures",
    "fronts_figures",
    "losses_figure",
    "realism_figures",
    "robustness_figures",
    "run_figures",
    "save",
    "sweep_figures",
]

RPM = 60.0 / (2.0 * math.pi)


@dataclass(frozen=True)
class Run:
    """A recording to draw: its trace, scenario and a label for legends."""

    trace: Trace
    scenario: Scenario
    label: str


def _pyplot() -> Any:
    try:
        import matplotlib
    except ImportError:
        raise missing("matplotlib", "--figures") from None

    matplotlib.use("Agg")  # files only: no display here, nor wanted
    import matplotlib.pyplot as plt

    return plt


def _time(tr: Trace, rec: str) -> np.ndarray:
    rows = tr.state if rec == "state" else tr.reference if rec == "reference" else tr.command
    return np.asarray(rows[:, 1])


def zoom_window(tr: Trace, sc: Scenario) -> tuple[float, float]:
    """A short window to look into the ripple: 20 ms (or 40 periods) from the THD window's start
    (a steady stretch) or from 3/4 of the run."""
    end = tr.steps * tr.ts
    start = sc.logger.thd_window[0] if sc.logger.thd_window else 0.75 * end
    width = max(0.02, 40 * tr.ts)
    return start, min(end, start + width)


def steady_window(tr: Trace, sc: Scenario) -> tuple[float, float]:
    """The second half of the last load step the run reaches: where it has settled."""
    end = tr.steps * tr.ts
    last = max((t for t in sc.plant.load_times if t < end), default=0.0)
    return 0.5 * (last + end), end


def _zoom(ax: Any, x0: float, x1: float) -> None:
    """Limit the axes to [x0, x1] and the y range to what its lines show there."""
    ax.set_xlim(x0, x1)
    lo, hi = math.inf, -math.inf
    for line in ax.get_lines():
        x, y = np.asarray(line.get_xdata()), np.asarray(line.get_ydata())
        inside = y[(x >= x0) & (x <= x1)]
        if inside.size:
            lo, hi = min(lo, float(inside.min())), max(hi, float(inside.max()))
    if lo < hi:
        pad = 0.05 * (hi - lo)
        ax.set_ylim(lo - pad, hi + pad)


def run_figures(run: Run) -> dict[str, Any]:
    """The figures of one run, by name: speed, torque, flux, current, and vectors (a
    finite-control-set run) or foc (a field-oriented one)."""
    plt = _pyplot()
    tr, sc = run.trace, run.scenario
    t_s, t_r = _time(tr, "state"), _time(tr, "reference")
    figs: dict[str, Any] = {}

    fig, ax = plt.subplots(figsize=(8, 4))
    ax.plot(t_s, tr.col("state", "omega_m") * RPM, label="ω_m")
    ax.plot(t_r, tr.col("reference", "speed_ref") * RPM, "--", label="ω_m*")
    ax.set(xlabel="t / s", ylabel="speed / (r/min)", title=f"{run.label}: speed")
    ax.legend()
    figs["speed"] = fig

    fig, (ax, zx) = plt.subplots(2, 1, figsize=(8, 6))
    for a in (ax, zx):
        a.plot(t_s, tr.col("state", "torque"), label="T_e", linewidth=0.6)
        a.plot(t_r, tr.col("reference", "torque_ref"), "--", label="T*", linewidth=0.8)
        a.set(xlabel="t / s", ylabel="torque / N·m")
    z0, z1 = zoom_window(tr, sc)
    _zoom(zx, z0, z1)
    ax.set_title(f"{run.label}: torque (below: {1e3 * (z1 - z0):.0f} ms from {z0:g} s)")
    ax.legend()
    fig.tight_layout()
    figs["torque"] = fig

    fig, (ax, lx) = plt.subplots(1, 2, figsize=(11, 4.5))
    pa, pb = tr.col("state", "psi_alpha"), tr.col("state", "psi_beta")
    ax.plot(t_s, np.hypot(pa, pb), label="|ψ_s|", linewidth=0.6)
    ax.plot(t_r, tr.col("reference", "flux_ref"), "--", label="ψ*")
    ax.set(xlabel="t / s", ylabel="stator flux / Wb", title=f"{run.label}: stator flux")
    ax.legend()
    lx.plot(pa, pb, linewidth=0.4)
    lx.set(xlabel="ψ_α / Wb", ylabel="ψ_β / Wb", title="flux locus", aspect="equal")
    fig.tight_layout()
    figs["flux"] = fig

    fig, (ax, sx) = plt.subplots(2, 1, figsize=(8, 6))
    ax.plot(t_s, tr.col("state", "i_alpha"), linewidth=0.5)
    _zoom(ax, z0, z1)
    ax.set(xlabel="t / s", ylabel="i_a / A", title=f"{run.label}: phase-a current")
    window = sc.logger.thd_window or steady_window(tr, sc)
    try:
        sp = phase_a_spectrum(
            tr, window[0], min(window[1], tr.steps * tr.ts), slips=sc.machine is Machine.INDUCTION
        )
        freq = np.arange(sp.amplitude.size) / sp.period
        sx.plot(freq, sp.amplitude, linewidth=0.6)
        sx.set_xscale("symlog", linthresh=max(freq[1], 1.0) if freq.size > 1 else 1.0)
        sx.set(
            xlabel="f / Hz",
            ylabel="amplitude / A",
            title=f"spectrum over {sp.cycles} cycles of {sp.fundamental_hz:.1f} Hz: "
            f"THD {100 * sp.thd:.2f} % (harmonics alone {100 * sp.thd_harmonics:.2f} %)",
        )
    except ValueError as e:  # no whole electrical cycle in the window
        sx.set_title(f"no spectrum: {e}")
    fig.tight_layout()
    figs["current"] = fig

    vec = tr.col("command", "vector")
    if np.any(np.isfinite(vec)):
        fig, ax = plt.subplots(figsize=(6, 4))
        counts = np.bincount(vec[np.isfinite(vec)].astype(int), minlength=7)[:7]
        ax.bar([f"V{i}" for i in range(7)], counts / vec.size)
        ax.set(ylabel="share of steps", title=f"{run.label}: vector utilization")
        figs["vectors"] = fig
    theta = tr.col("command", "current_angle")
    if np.any(np.isfinite(theta)):
        fig, (ax, dx) = plt.subplots(2, 1, figsize=(8, 6))
        t_c = _time(tr, "command")
        ax.plot(t_c, np.degrees(theta), linewidth=0.5, label="θ")
        if sc.family == "foc_pmsm":  # the dither averaged out over its period
            m = max(1, round(1.0 / (sc.controller.injection_hz * tr.ts)))
            mean = np.convolve(np.degrees(theta), np.ones(m) / m, mode="same")
            ax.plot(t_c, mean, linewidth=1.0, label=f"θ averaged over {m} steps")
        ax.set(xlabel="t / s", ylabel="θ / °", title=f"{run.label}: current angle (from q)")
        ax.legend()
        n = tr.steps
        i = (tr.col("state", "i_alpha") + 1j * tr.col("state", "i_beta"))[:n]
        i_dq = i * np.exp(-1j * tr.col("state", "theta_e")[:n])
        dx.plot(t_c, i_dq.real, label="i_d", linewidth=0.5)
        dx.plot(t_c, i_dq.imag, label="i_q", linewidth=0.5)
        dx.plot(t_c, tr.col("command", "i_d_ref"), "--", label="i_d*", linewidth=0.8)
        dx.plot(t_c, tr.col("command", "i_q_ref"), "--", label="i_q*", linewidth=0.8)
        dx.set(xlabel="t / s", ylabel="current / A")
        dx.legend()
        fig.tight_layout()
        figs["foc"] = fig
    if tr.has_losses:
        figs["losses"] = losses_figure(run)
    return figs


#: the loss fields a losses figure draws, by label
LOSS_LINES = {
    "conduction, transistors": "p_cond_t",
    "conduction, diodes": "p_cond_d",
    "switching, transistors": "p_sw_t",
    "switching, diodes": "p_sw_d",
    "copper": "p_copper",
    "iron": "p_iron",
    "friction": "p_friction",
}


def losses_figure(run: Run) -> Any:
    """Losses and temperatures over time (docs/physics.md#losses-and-temperature): each loss as
    its mean over the thermal step (what the thermal networks are fed: a period's switching
    losses come in bursts), and every junction, the heatsink, the winding and the rotor."""
    plt = _pyplot()
    tr, sc = run.trace, run.scenario
    t = tr.col("losses", "t")
    m = max(1, round(sc.plant.losses.thermal_step / tr.ts))
    fig, (ax, tx) = plt.subplots(2, 1, figsize=(9, 7), sharex=True)
    for label, field in LOSS_LINES.items():
        p = tr.col("losses", field)[1:]
        if not np.any(p):
            continue
        mean = np.convolve(p, np.ones(m) / m, mode="valid")
        ax.plot(t[m:], mean, linewidth=0.8, label=label)  # the mean of periods k-m..k-1 at k
    ax.set(ylabel="P / W", title=f"{run.label}: losses, means over {m} periods")
    ax.legend(fontsize="small", ncol=2)
    # a junction's colour is its leg's, its line its part and position: twelve told apart
    legs = {"a": "tab:blue", "b": "tab:orange", "c": "tab:green"}
    lines = {("t", "hi"): "-", ("t", "lo"): "--", ("d", "hi"): ":", ("d", "lo"): "-."}
    for name in DEVICES:  # e.g. "ta_hi": transistor, leg a, upper
        tj = tr.col("losses", f"tj_{name}")
        if np.isfinite(tj).any():
            style = {"color": legs[name[1]], "linestyle": lines[(name[0], name[3:])]}
            tx.plot(t, tj, linewidth=0.8, label=f"T_j {name}", **style)
    for field, label, colour in (("t_sink", "heatsink", "black"), ("t_winding", "winding",
                                 "tab:red"), ("t_rotor", "rotor", "tab:purple")):  # fmt: skip
        temp = tr.col("losses", field)
        if np.isfinite(temp).any():
            tx.plot(t, temp, linewidth=1.6, color=colour, label=label)
    tx.set(xlabel="t / s", ylabel="T / °C", title="temperatures")
    tx.legend(fontsize="x-small", ncol=4)
    fig.tight_layout()
    return fig


def compare_figures(runs: Sequence[Run]) -> dict[str, Any]:
    """Runs overlaid (e.g. the strategies of one scenario): speed, torque, flux magnitude, and
    the phase-a spectra."""
    plt = _pyplot()
    figs: dict[str, Any] = {}
    panels = {
        "speed": ("omega_m", RPM, "speed / (r/min)"),
        "torque": ("torque", 1.0, "torque / N·m"),
    }
    for name, (field, scale, ylabel) in panels.items():
        fig, ax = plt.subplots(figsize=(8, 4))
        for r in runs:
            ax.plot(_time(r.trace, "state"), r.trace.col("state", field) * scale,
                    label=r.label, linewidth=0.6)  # fmt: skip
        ax.set(xlabel="t / s", ylabel=ylabel, title=f"{name}: {len(runs)} runs")
        ax.legend()
        figs[name] = fig
    fig, ax = plt.subplots(figsize=(8, 4))
    for r in runs:
        psi = np.hypot(r.trace.col("state", "psi_alpha"), r.trace.col("state", "psi_beta"))
        ax.plot(_time(r.trace, "state"), psi, label=r.label, linewidth=0.6)
    ax.set(xlabel="t / s", ylabel="|ψ_s| / Wb", title=f"stator flux: {len(runs)} runs")
    ax.legend()
    figs["flux"] = fig
    return figs


#: the metrics a sweep's figures plot (their axes from :data:`~..core.metrics.METRICS`)
SWEEP_METRICS = ("t_rmse", "psi_rmse", "f_ave_hz", "f_sw_hz", "thd", "speed_rmse")


def _sweep_x(value: Any) -> float:
    """A swept value on an axis: a factor ``*f`` as f, a number as itself."""
    if isinstance(value, str) and value.startswith("*"):
        return float(value[1:])
    return float(value)


def sweep_figures(rows: Sequence[Any], keys: Sequence[str]) -> dict[str, Any]:
    """One figure per swept key: each metric against the key's values (factors as numbers), a
    line per strategy and combination of the other keys; rows with an error are left out."""
    plt = _pyplot()
    ok = [r for r in rows if r.error is None and r.metrics]
    figs: dict[str, Any] = {}
    metrics = [m for m in SWEEP_METRICS if any(math.isfinite(getattr(r.metrics, m)) for r in ok)]
    if not metrics:
        return figs  # no run finished: nothing to draw
    for key in keys:
        try:
            xs = {id(r): _sweep_x(r.settings[key]) for r in ok}
        except (TypeError, ValueError):
            continue  # a key of names, not numbers: no axis to plot it on
        fig, axes = plt.subplots(len(metrics), 1, figsize=(7, 2.2 * len(metrics)), sharex=True)
        axes = np.atleast_1d(axes)
        groups: dict[str, list[Any]] = {}
        for r in ok:
            others = ", ".join(f"{k.rsplit('.', 1)[-1]}={r.settings[k]}" for k in keys if k != key)
            groups.setdefault(r.strategy + (f" ({others})" if others else ""), []).append(r)
        for ax, name in zip(axes, metrics):
            shown = METRICS[name]
            for glabel, group in groups.items():
                group = sorted(group, key=lambda r: xs[id(r)])
                ax.plot(
                    [xs[id(r)] for r in group],
                    [shown.scale * getattr(r.metrics, name) for r in group],
                    marker="o",
                    label=glabel,
                )
            ax.set_ylabel(shown.axis)
            ax.grid(True, alpha=0.3)
        axes[-1].set_xlabel(key + (" (factor)" if any(
            isinstance(r.settings[key], str) for r in ok) else ""))  # fmt: skip
        axes[0].legend(fontsize=7)
        fig.tight_layout()
        figs[f"sweep_{key.replace('.', '_')}"] = fig
    return figs


def realism_figures(
    table: dict[str, dict[str, dict[str, list[float]]]], conditions: Sequence[str]
) -> dict[str, Any]:
    """The realism study, one figure per scenario: a panel per metric, each strategy's figure
    under every column's conditions (``table[scenario][strategy][metric]``, one value per
    condition); a metric with no number in a scenario is left out."""
    plt = _pyplot()
    figs: dict[str, Any] = {}
    x = np.arange(len(conditions))
    for scenario, by_strategy in table.items():
        keys = list(dict.fromkeys(k for v in by_strategy.values() for k in v))
        keys = [k for k in keys if any(np.isfinite(v[k]).any() for v in by_strategy.values())]
        if not keys:
            continue
        fig, axes = plt.subplots(len(keys), 1, figsize=(7, 2.2 * len(keys)), sharex=True)
        axes = np.atleast_1d(axes)
        width = 0.8 / max(1, len(by_strategy))
        for ax, key in zip(axes, keys):
            shown = METRICS[key]
            for j, (strategy, values) in enumerate(by_strategy.items()):
                ax.bar(
                    x + (j - (len(by_strategy) - 1) / 2) * width,
                    [shown.scale * v for v in values[key]],
                    width,
                    label=strategy,
                )
            ax.set_ylabel(shown.axis)
            ax.grid(True, axis="y", alpha=0.3)
        axes[-1].set_xticks(x, list(conditions))
        axes[0].set_title(scenario)
        axes[0].legend(fontsize=7)
        fig.tight_layout()
        figs[scenario] = fig
    return figs


def robustness_figures(
    table: dict[str, dict[str, dict[str, list[float]]]], keys: Sequence[str]
) -> dict[str, Any]:
    """The robustness study, one figure per point: a panel per metric (``keys``), each
    strategy's figure over the drawn drives (``table[point][strategy][metric]``, one value per
    drive) as a violin with its box (quartiles, whiskers to 1.5 IQR) and mean (a dot); failed
    drives (NaN) are left out, a metric with no number at a point too."""
    plt = _pyplot()
    figs: dict[str, Any] = {}
    for point, by_strategy in table.items():
        names = list(by_strategy)
        shown_keys = [k for k in keys if any(np.isfinite(by_strategy[s][k]).any() for s in names)]
        if not shown_keys:
            continue
        fig, axes = plt.subplots(1, len(shown_keys), figsize=(3.6 * len(shown_keys), 3.8))
        for ax, key in zip(np.atleast_1d(axes), shown_keys):
            shown = METRICS[key]
            data = [
                [shown.scale * v for v in by_strategy[s][key] if math.isfinite(v)] for s in names
            ]
            pos = [i + 1 for i, d in enumerate(data) if d]
            kept = [d for d in data if d]
            if kept and all(len(d) > 1 for d in kept):
                ax.violinplot(kept, positions=pos, showextrema=False)
            ax.boxplot(kept, positions=pos, widths=0.25, showfliers=False)
            ax.plot(pos, [float(np.mean(d)) for d in kept], "o", color="black", markersize=3)
            ax.set_xticks(range(1, len(names) + 1), names, rotation=30, fontsize=7)
            ax.set_ylabel(shown.axis)
            ax.grid(True, axis="y", alpha=0.3)
        fig.suptitle(point, fontsize=9)
        fig.tight_layout()
        figs[point] = fig
    return figs


#: each curve of a fronts figure its own colour and marker (up to 16 curves an operating point)
CURVE_COLOURS = (
    "#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
    "#bcbd22", "#17becf", "#000000", "#d4a017", "#008080", "#000080", "#ff00ff", "#32cd32",
)  # fmt: skip
CURVE_MARKERS = ("o", "s", "^", "v", "D", "P", "X", "*", "<", ">", "h", "p", "d", "8", "H", "+")


def fronts_figures(result: Any, skipped: list[str] | None = None) -> dict[str, Any]:
    """Per operating point of a fronts study (``result.points``, each with ``point``,
    ``caption`` and ``curves`` of ``points``) a figure against f_sw (``<point>``) and, where its
    runs booked losses, one against the inverter's loss (``<point>_loss``): a panel per ranked
    figure (the torque's ripple about its mean and against T*, the current's THD and TDD), log
    axes; per curve, in its own colour and marker, its points (hollow where the run left the
    operating point) and its front as a line (dashed for field-oriented control) drawn only
    between the neighbours the table reads between (:func:`~.fronts.joined` on their f_sw and
    figure, against either axis): no line across a gap it leaves blank. A panel with no positive
    figure says so instead of a log axis (matplotlib cannot scale one), and a figure with nothing
    in any panel is not drawn: ``skipped`` takes a note naming it."""
    from .fronts import LOSS, joined

    def one(a: Any, b: Any, key: str) -> bool:
        pa, pb = sorted([(a.figures["f_sw_hz"], a.figures[key]), (b.figures["f_sw_hz"],
                                                                  b.figures[key])])  # fmt: skip
        return joined(pa, pb)

    figs: dict[str, Any] = {}
    keys = tuple(result.points[0].at) if result.points else ()
    for table in result.points:
        drawable = {k: _positive(table, k, "f_sw_hz") for k in keys}
        if not any(drawable.values()):
            if skipped is not None:
                skipped.append(
                    f"{table.point}: no figure drawn: no run has a positive f_sw and figure to "
                    "put on log axes (a run too short to switch?)"
                )
            continue
        figs[table.point] = _fronts_figure(
            table, keys, drawable, "f_sw_hz", lambda c, k: c.front(k), one, "lines: the fronts"
        )
        by_loss = {k: _positive(table, k, LOSS) for k in keys}
        if any(by_loss.values()):
            figs[f"{table.point}_loss"] = _fronts_figure(
                table, keys, by_loss, LOSS, lambda c, k: c.loss_front(k), one,
                f"against the inverter's loss ({table.device}; the axis spans the held runs); "
                "lines: the fronts"
                if any(p.holds for c in table.curves for p in c.points)
                else f"against the inverter's loss ({table.device}); no run held the point",
            )  # fmt: skip
    return figs


def _positive(table: Any, key: str, x: str) -> bool:
    """Some run of a fronts table has a positive, finite ``x`` and ``key``: a log axis has
    something to scale."""
    return any(
        math.isfinite(p.figures[key])
        and p.figures[key] > 0
        and math.isfinite(p.figures.get(x, math.nan))
        and p.figures[x] > 0
        for c in table.curves
        for p in c.points
    )


def _fronts_figure(
    table: Any,
    keys: Sequence[str],
    drawable: dict[str, bool],
    x: str,
    front_of: Any,
    one: Any,
    what: str,
) -> Any:
    """One operating point's fronts against figure ``x`` (a metric key): ``front_of(curve,
    key)`` its front's points, ``one(a, b, key)`` whether two neighbours are one stretch; a
    panel whose key is not ``drawable`` says so in words."""
    plt = _pyplot()
    shown_x = METRICS[x]
    floor = 1.0 if x == "f_sw_hz" else 1e-2  #: a run that stopped switching, on log axes
    held_x = [
        v for c in table.curves for p in c.points if p.holds and math.isfinite(v := p.figures[x])
    ]
    fig, axes = plt.subplots(2, (len(keys) + 1) // 2, figsize=(12, 8.5), squeeze=False)
    for ax, key in zip(axes.flat, keys):
        shown = METRICS[key]
        if not drawable[key]:
            ax.text(0.5, 0.5, f"{shown.title}: no run has a positive, finite figure",
                    ha="center", va="center", transform=ax.transAxes, fontsize=8)  # fmt: skip
            ax.set(xlabel=shown_x.axis, ylabel=shown.axis)
            continue
        for i, curve in enumerate(table.curves):
            style = {
                "color": CURVE_COLOURS[i % len(CURVE_COLOURS)],
                "marker": CURVE_MARKERS[i % len(CURVE_MARKERS)],
            }
            held = [p for p in curve.points if p.holds]
            lost = [p for p in curve.points if not p.holds]
            ax.plot(
                [shown_x.scale * p.figures[x] for p in held],
                [shown.scale * p.figures[key] for p in held],
                ls="none", markersize=5, label=curve.name, **style,
            )  # fmt: skip
            if lost:
                ax.plot(
                    [shown_x.scale * max(p.figures[x], floor) for p in lost],
                    [shown.scale * p.figures[key] for p in lost],
                    ls="none", mfc="none", markersize=5, alpha=0.6, **style,
                )  # fmt: skip
            front = front_of(curve, key)
            dashed = "--" if curve.strategy.startswith(("foc", "ifoc")) else "-"
            for a, b in zip(front, front[1:]):
                if one(a, b, key):
                    ax.plot(
                        [shown_x.scale * a.figures[x], shown_x.scale * b.figures[x]],
                        [shown.scale * a.figures[key], shown.scale * b.figures[key]],
                        dashed, color=style["color"], lw=1.2,
                    )  # fmt: skip
        # a narrow range of losses (a SiC drive's, nearly all conduction) on a linear axis
        narrow = x != "f_sw_hz" and held_x and max(held_x) < 3.0 * min(held_x)
        ax.set_xscale("linear" if narrow else "log")
        ax.set_yscale("log")
        ax.set(xlabel=shown_x.axis, ylabel=shown.axis)
        ax.grid(True, which="both", alpha=0.3)
        if x != "f_sw_hz" and held_x:  # a run that lost the point may have lost the inverter
            ax.set_xlim(shown_x.scale * min(held_x) / 1.1, shown_x.scale * max(held_x) * 1.1)
    for ax in list(axes.flat)[len(keys) :]:
        ax.set_visible(False)
    axes.flat[0].legend(fontsize=7, ncol=2)
    fig.suptitle(f"{table.caption}\nhollow: left the operating point; {what}", fontsize=9)
    fig.tight_layout()
    return fig


def efficiency_figures(result: Any) -> dict[str, Any]:
    """The efficiency study's maps (``result.maps`` over ``result.speeds_rpm`` ×
    ``result.torques``): one column per map, η (%) above and the inverter's loss (W) below, as
    colour maps on one scale per row with each cell's value written in it; a point that left
    its operating point is blank."""
    plt = _pyplot()
    speeds, torques = list(result.speeds_rpm), list(result.torques)
    rows = (("efficiency", "viridis"), ("p_inverter", "magma_r"))
    n = max(len(result.maps), 1)
    fig, axes = plt.subplots(
        2, n, figsize=(4.6 * n + 1.2, 8.0), squeeze=False, layout="constrained"
    )
    for r, (key, cmap) in enumerate(rows):
        shown = METRICS[key]
        grids = [
            np.array(
                [
                    [np.nan if v is None else shown.scale * v for v in row]
                    for row in m.grid(key, speeds, torques)
                ]
            )  # fmt: skip
            for m in result.maps
        ]
        finite = [g[np.isfinite(g)] for g in grids]
        values = np.concatenate(finite) if finite else np.zeros(0)
        lo, hi = (float(values.min()), float(values.max())) if values.size else (0.0, 1.0)
        mesh = None
        for ax, m, g in zip(axes[r], result.maps, grids):
            mesh = ax.pcolormesh(
                _edges(speeds), _edges(torques), np.ma.masked_invalid(g), cmap=cmap, vmin=lo,
                vmax=hi,
            )  # fmt: skip
            for i, t in enumerate(torques):
                for j, s in enumerate(speeds):
                    if np.isfinite(g[i, j]):
                        red, green, blue, _ = mesh.cmap(mesh.norm(g[i, j]))
                        dark = 0.299 * red + 0.587 * green + 0.114 * blue < 0.5
                        ax.text(
                            s, t, f"{g[i, j]:.3g}", ha="center", va="center", fontsize=5.5,
                            color="white" if dark else "black",
                        )  # fmt: skip
            ax.set(title=f"{m.name}: {shown.title}", xlabel="speed (r/min)", ylabel="torque (N·m)")
        if mesh is not None:
            fig.colorbar(mesh, ax=list(axes[r]), label=shown.axis, shrink=0.9)
    fig.suptitle(f"{result.caption}; blank: left the operating point", fontsize=9)
    return {"maps": fig}


def _edges(centres: Sequence[float]) -> np.ndarray:
    """Cell edges around ascending grid ``centres``: midway between neighbours, the ends half a
    step out, not below zero for a positive grid (a single centre: ±10 %)."""
    c = np.asarray(centres, dtype=float)
    if c.size == 1:
        return np.array([0.9 * c[0], 1.1 * c[0]])
    mid = 0.5 * (c[1:] + c[:-1])
    first = c[0] - (mid[0] - c[0])
    if c[0] > 0.0:  # a positive grid's first cell stops at zero, not below
        first = max(first, 0.0)
    return np.concatenate(([first], mid, [c[-1] + (c[-1] - mid[-1])]))


def save(figs: dict[str, Any], directory: str | Path, prefix: str = "") -> list[Path]:
    """Write each figure as ``<prefix><name>.png`` into ``directory`` (made if need be); closes
    them. Returns the files."""
    plt = _pyplot()
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    out = []
    for name, fig in figs.items():
        path = d / f"{prefix}{name}.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        out.append(path)
    return out
