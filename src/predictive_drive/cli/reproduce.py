"""``predictive-drive reproduce SCENARIO``: a paper's table, or an MTPA study, run again; or the
realism study."""

from __future__ import annotations

import argparse
from typing import Any

from ..api.efficiency import EFFICIENCY_STUDY, EfficiencyChoice, EfficiencyResult
from ..api.fronts import FRONTS_STUDY, FrontsChoice, FrontsResult
from ..api.reproduce import (
    STUDIES,
    MTPAStudyResult,
    PaperTableResult,
    RealismResult,
    reproduce,
)
from ..api.robustness import ROBUSTNESS_STUDY, RobustnessResult
from ..api.run import ENGINES
from ..core.metrics import METRICS, Metric
from ..errors import ConfigError
from ..reports.efficiency import EFFICIENCY
from ..reports.fronts import FRONTS, LOSS, PERIODS
from ..reports.fronts import RANKED as FRONT_RANKED
from ..reports.papers import MTPA_STUDIES, PAPER_TABLES
from ..reports.realism import RANKED, SHOWN
from ..reports.robustness import DEFAULT_DRAWS, DEFAULT_SEED, ROBUSTNESS
from .common import refuse, runs_progress, say_json, seconds, single_settings
from .sweep import print_drawn

HELP = (
    "a paper's table side by side with our figures (or an MTPA study, the realism study, the "
    "fronts of distortion against switching frequency and loss, the robustness study, or the "
    "efficiency maps)"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("scenario", choices=sorted([*PAPER_TABLES, *MTPA_STUDIES, *STUDIES]))
    p.add_argument(
        "--engine",
        default="inprocess",
        choices=ENGINES,
        help="where each run is made (default: inprocess, the runs in parallel across the "
        "cores; ros, composed: one graph after another; the figures are the same on every "
        "engine, the measured compute times aside)",
    )
    p.add_argument(
        "--repeats", type=int, help="timing repeats for the compute ratios (median; default 5; "
        "ipmsm_validation only, the one table with compute ratios)",
    )  # fmt: skip
    p.add_argument(
        "--duration", type=seconds, help="shorten every run to this many simulated seconds"
    )
    p.add_argument("--figures", metavar="DIR", help="draw the table's runs, overlaid (PNG)")
    p.add_argument(
        "--bags",
        metavar="DIR",
        help="keep every run's bag in DIR (default: none kept; the bags the study needs for "
        "its figures or its timing are recorded to a temporary folder and removed)",
    )
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="a scenario setting for every run, e.g. speed_pi.speed_loop=immediate (repeatable); "
        "for realism, a setting of the real drive (plant.dead_time, ...) replaces the study's "
        "in the columns that have it",
    )
    p.add_argument(
        "--scheduler", metavar="ADDRESS", help="realism, fronts, robustness, efficiency: run on "
        "this Dask cluster (e.g. tcp://host:8786) instead of the local cores",
    )  # fmt: skip
    p.add_argument(
        "--lambda-sw", metavar="V1,V2,...", type=_numbers,
        help="fronts only: the switching-effort weights every finite-control-set curve is "
        "traced over (default: each curve's own)",
    )  # fmt: skip
    p.add_argument(
        "--lambda-u", metavar="V1,V2,...", type=_numbers,
        help="fronts only: the switching weights every direct_mpc curve is traced over "
        "(default: each curve's own)",
    )  # fmt: skip
    p.add_argument(
        "--fsw-khz", metavar="F1,F2,...", type=_numbers,
        help="fronts only: the carrier frequencies (kHz; ts = 1/f_sw) every FOC curve is "
        "traced over (default 0.5,1,2,3,5,7,10,15,20)",
    )  # fmt: skip
    p.add_argument(
        "--periods-us", metavar="T1,T2,...", type=_numbers_or_none,
        help="fronts only: the control periods (µs) besides the papers' 50 every "
        "finite-control-set curve also runs at, over its two smallest knob values (default "
        + ",".join(f"{1e6 * t:g}" for t in PERIODS) + "; none: 50 µs alone)",
    )  # fmt: skip
    p.add_argument(
        "--points", metavar="P1,P2", type=_names,
        help=f"fronts and robustness: the operating points to run (default all; fronts: "
        f"{', '.join(FRONTS)}; robustness: {', '.join(ROBUSTNESS)})",
    )  # fmt: skip
    p.add_argument(
        "--curves", metavar="C1,C2", type=_names,
        help="fronts only: the curves to run, by name (e.g. mptc,ifoc,'mptc N=2'; default "
        "all: " + "; ".join(f"{n}: {', '.join(c.name for c in op.curves)}"
                            for n, op in FRONTS.items()) + ")",
    )  # fmt: skip
    p.add_argument(
        "--no-horizons", dest="horizons", action="store_false",
        help="fronts only: without the long-horizon curves (N > 1), the study's slowest runs",
    )  # fmt: skip
    p.add_argument(
        "--external", metavar="torque_controller=COMMAND",
        help="fronts only: your own torque controller on the fronts of one operating point "
        "(--points), run through the ROS graph on its MPTC scenario and drawn and ranked beside "
        "ours with the same operating-point check (docs/ros.md, 'Your controller on the "
        "fronts')",
    )  # fmt: skip
    p.add_argument(
        "--label", metavar="NAME",
        help="with --external: your controller's name, external:NAME in the table, figures "
        "and bags (default torque_controller)",
    )  # fmt: skip
    p.add_argument(
        "--knob", action="append", metavar="KEY=V1,V2,...", type=_knob,
        help="with --external: what your controller is traced over, one of its own "
        "parameters (torque_controller.NAME=V1,V2,...) and/or its period (ts=T1,T2,... s), "
        "every value at every period (repeatable, once each; default: one run as its "
        "section says)",
    )  # fmt: skip
    p.add_argument(
        "--jobs", type=int, help="realism, fronts, robustness, efficiency: local processes "
        "(default: every core)",
    )  # fmt: skip
    p.add_argument(
        "--draws", type=int, metavar="N",
        help=f"robustness only: drives drawn per point (default {DEFAULT_DRAWS})",
    )  # fmt: skip
    p.add_argument(
        "--seed", type=int, help=f"robustness only: seed of the draws (default {DEFAULT_SEED})"
    )
    p.add_argument(
        "--spread", action="append", metavar="KEY=normal:S|uniform:S",
        help="robustness only: a parameter's spread, replacing a point's own for that key or "
        "added (repeatable)",
    )  # fmt: skip
    p.add_argument(
        "--maps", metavar="M1,M2", type=_names,
        help="efficiency only: the maps to run, by strategy (default all: "
        + ", ".join(m.name for m in EFFICIENCY.maps) + ")",
    )  # fmt: skip
    p.add_argument(
        "--speeds-rpm", metavar="N1,N2,...", type=_numbers,
        help="efficiency only: the grid's speeds, r/min (default "
        + ",".join(f"{n:g}" for n in EFFICIENCY.speeds_rpm) + ")",
    )  # fmt: skip
    p.add_argument(
        "--torques", metavar="T1,T2,...", type=_numbers,
        help="efficiency only: the grid's torques, N·m (default "
        + ",".join(f"{t:g}" for t in EFFICIENCY.torques) + ")",
    )  # fmt: skip


def _numbers_or_none(text: str) -> list[float]:
    return [] if text.strip().lower() == "none" else _numbers(text)


def _names(text: str) -> list[str]:
    return [n.strip() for n in text.split(",") if n.strip()]


def _knob(text: str) -> tuple[str, list[Any]]:
    key, sep, values = text.partition("=")
    if not sep or not key:
        raise argparse.ArgumentTypeError(f"expected KEY=V1,V2,..., got {text!r}")
    out: list[Any] = []
    for v in values.split(","):
        try:
            out.append(float(v))
        except ValueError:
            out.append(v.strip())
    return key.strip(), out


def _external(text: str | None) -> str | None:
    if text is None:
        return None
    name, sep, command = text.partition("=")
    if name != "torque_controller" or not sep or not command.strip():
        raise ConfigError(
            f"--external {text}: the fronts take a torque controller of your own with the "
            f"command that starts it, torque_controller=COMMAND"
        )
    return command


def _knobs(given: list[tuple[str, list[Any]]] | None) -> dict[str, list[Any]] | None:
    if not given:
        return None
    out: dict[str, list[Any]] = {}
    for key, values in given:
        if key in out:
            raise ConfigError(f"--knob {key}: given twice")
        out[key] = values
    return out


def _numbers(text: str) -> list[float]:
    try:
        return [float(v) for v in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected numbers separated by commas, got {text!r}"
        ) from None


def main(a: argparse.Namespace) -> int:
    table = PAPER_TABLES.get(a.scenario)
    if table is None or not table.compute_ratios:
        refuse(a, f"times the compute ratios, which {a.scenario} has none of", "repeats")
    if a.scenario not in STUDIES:
        studies = "the realism, fronts, robustness and efficiency studies only"
        refuse(a, f"serves {studies}, not {a.scenario}", "scheduler")
        refuse(a, f"runs {studies}, not {a.scenario}", "jobs")
    if a.scenario != ROBUSTNESS_STUDY:
        refuse(
            a, f"chooses the robustness study's drives, not {a.scenario}'s",
            "draws", "seed", "spread",
        )  # fmt: skip
    if a.scenario not in (FRONTS_STUDY, ROBUSTNESS_STUDY):
        refuse(a, f"chooses a study's operating points, not {a.scenario}'s", "points")
    if a.scenario != FRONTS_STUDY:
        refuse(
            a, f"chooses the fronts study's runs, not {a.scenario}'s",
            "lambda_sw", "lambda_u", "fsw_khz", "periods_us", "curves", "external",
            "label", "knob",
        )  # fmt: skip
        if not a.horizons:
            raise ConfigError(f"--no-horizons chooses the fronts study's runs, not {a.scenario}'s")
    if a.scenario != EFFICIENCY_STUDY:
        refuse(
            a, f"chooses the efficiency study's runs, not {a.scenario}'s",
            "maps", "speeds_rpm", "torques",
        )  # fmt: skip
    settings = single_settings(a.set)
    update, close = runs_progress(f"reproduce {a.scenario}", quiet=a.json)
    try:
        d = reproduce(
            a.scenario,
            engine=a.engine,
            out_root=a.bags,
            repeats=5 if a.repeats is None else a.repeats,
            duration=a.duration,
            figures=a.figures,
            settings=settings,
            scheduler=a.scheduler,
            jobs=a.jobs,
            draws=a.draws,
            seed=a.seed,
            points=a.points if a.scenario == ROBUSTNESS_STUDY else None,
            spreads=a.spread or [],
            fronts=FrontsChoice(
                lambda_sw=a.lambda_sw,
                lambda_u=a.lambda_u,
                fsw_khz=a.fsw_khz,
                periods_us=a.periods_us,
                points=a.points,
                curves=a.curves,
                horizons=a.horizons,
                external=_external(a.external),
                label=a.label,
                knobs=_knobs(a.knob),
            )
            if a.scenario == FRONTS_STUDY
            else None,
            efficiency=EfficiencyChoice(a.maps, a.speeds_rpm, a.torques)
            if a.scenario == EFFICIENCY_STUDY
            else None,
            progress=update,
        )
    finally:
        close()
    if a.json:
        return say_json(d)
    if isinstance(d, MTPAStudyResult):
        print_mtpa(d)
    elif isinstance(d, RealismResult):
        print_realism(d)
    elif isinstance(d, FrontsResult):
        print_fronts(d)
    elif isinstance(d, RobustnessResult):
        print_robustness(d)
    elif isinstance(d, EfficiencyResult):
        print_efficiency(d)
    else:
        print_table(d)
    for f in d.figures:
        print(f"figure {f}")
    for note in getattr(d, "figure_notes", []):
        print(f"figure {note}")
    if d.bags is not None:
        print(f"bags   {d.bags.count} in {d.bags.folder} ({d.bags.bytes / 1e6:.1f} MB)")
    return 0


def _settings(
    d: PaperTableResult | MTPAStudyResult | RealismResult | FrontsResult | RobustnessResult
    | EfficiencyResult,
) -> None:  # fmt: skip
    if d.duration is not None:
        windows = "; ".join(
            (f"{name} " if len(d.windows) > 1 else "")
            + ", ".join(f"{lo:.4g}-{hi:.4g} s" for lo, hi in spans)
            for name, spans in d.windows.items()
        )
        print(
            f"NOTE: runs shortened to {d.duration:g} s, so the figures are over the window "
            f"{windows}, not the paper's; not comparable with the paper"
        )
    if d.settings:
        print("every run with " + ", ".join(f"{k} = {v}" for k, v in d.settings.items()))


def print_table(d: PaperTableResult) -> None:
    print(f"{d.scenario} vs {d.paper}  (engine {d.engine})")
    _settings(d)
    width = max(len(r.label) for r in d.rows) + 1
    print(f"{'':<{width}}" + "".join(f" {c.heading:>17}" for c in d.columns))
    print(f"{'':<{width}}" + "".join(f" {'ours':>8} {'paper':>8}" for _ in d.columns))
    for r in d.rows:
        line = f"{r.label:<{width}}"
        for c in d.columns:
            line += f" {c.metric.format(r.figures.get(c.key)):>8}"
            line += f" {c.metric.format(r.paper.get(c.key)):>8}"
        print(line)
    print(f"How computed: {d.how}")


def print_mtpa(d: MTPAStudyResult) -> None:
    print(f"{d.scenario}: {d.paper}  (engine {d.engine})")
    _settings(d)
    print(
        f"{'strategy':<14} {'form':<10} {'L_d':>4} {'L_q':>4} {'T_L':>5} {'theta':>7} "
        f"{'MTPA':>7} {'error':>6} {'|i_s|':>8} {'MTPA':>8} {'excess':>7} {'i_d=0':>8} "
        f"{'settle':>7}"
    )
    print(
        f"{'':<14} {'':<10} {'x':>4} {'x':>4} {'N·m':>5} {'deg':>7} {'deg':>7} {'deg':>6} "
        f"{'A':>8} {'A':>8} {'%':>7} {'A':>8} {'s':>7}"
    )
    for r in d.rows:
        m = r.mismatch
        err = r.theta_deg - r.theta_mtpa_deg
        excess = 100.0 * (r.i_s / r.i_s_mtpa - 1.0)
        print(
            f"{r.strategy:<14} {r.form or '':<10} {m['l_d']:>4g} {m['l_q']:>4g} "
            f"{r.load_torque:>5g} {r.theta_deg:>7.2f} {r.theta_mtpa_deg:>7.2f} "
            f"{err:>+6.2f} {r.i_s:>8.4f} {r.i_s_mtpa:>8.4f} {excess:>+7.3f} "
            f"{r.i_s_zero_d:>8.4f} {r.settle_s:>7.3f}"
        )
    for c in d.claims:
        print(
            f"paper's claims at {c.load_torque:g} N·m: settles in {c.settle_s:.3f} s "
            f"({'confirmed' if c.settles_under_1_s else 'REFUTED'}: well under 1 s); "
            f"|i_s| {c.i_s:.4f} A vs {c.i_s_zero_d_measured:.4f} A under i_d = 0: "
            f"{100 * c.saving_vs_zero_d:+.3f} % saved of {100 * c.saving_possible:.3f} % "
            f"possible, resolution {100 * c.resolution:.3f} % ({c.less_current_than_zero_d}:"
            f" less current than i_d = 0)"
        )
    print(f"How computed: {d.how}")


def print_realism(d: RealismResult) -> None:
    print(f"{d.scenario}: {d.paper}  ({d.engine})")
    _settings(d)
    for scenario, strategies in d.strategies.items():
        print()
        print(f"{scenario}: " + ", ".join(f"{k} = {v}" for k, v in d.hardware[scenario].items()))
        if d.scenario_settings[scenario]:
            print(
                "  and every run with "
                + ", ".join(f"{k} = {v}" for k, v in d.scenario_settings[scenario].items())
            )
        width = max(14, *(len(s) for s in strategies)) + 1
        for key in SHOWN:
            metric = METRICS[key]
            ranked = key in RANKED
            head = metric.heading + (" (rank)" if ranked else "")
            print(f"{head:<{width}}" + "".join(f" {c:>15}" for c in d.conditions))
            for s in strategies:
                line = f"  {s:<{width - 2}}"
                for c in d.conditions:
                    cell = d.cell(scenario, s, c)
                    text = metric.format(cell.figures[key])
                    place = cell.rank.get(key)
                    if ranked and place is not None:
                        text += f" ({place})"
                    line += f" {text:>15}"
                print(line)
        for condition, text in d.unequal_fsw().get(scenario, {}).items():
            print(f"  {condition}: {text}")
    print(f"How computed: {d.how}")


def print_fronts(d: FrontsResult) -> None:
    print(f"{d.scenario}: {d.paper}  ({d.engine}, {d.runs} runs, {d.wall_s:.0f} s)")
    _settings(d)
    tol = d.tolerance
    print(
        f"holding the operating point: mean torque within {100 * tol['torque']:g} % of T*, mean "
        f"|psi_s| within {100 * tol['flux']:g} % of psi*, the current's fundamental within "
        f"{100 * tol['current']:g} % of the point's current"
    )
    f_sw = METRICS["f_sw_hz"]
    heads = "".join(f" {f'{f / 1e3:g} kHz':>17}" for f in d.frequencies)
    for t in d.points:
        print()
        print(f"{t.point}: {t.caption}")
        print(
            f"  T* {t.torque_ref:g} N·m, psi* {t.flux_ref:g} Wb; the point's current "
            f"{t.base_current_a:.4g} A ({t.base_current}): TDD's base"
        )
        if t.device:
            print(f"  every run's inverter devices: {t.device} (plant.losses.device)")
        width = max(14, *(len(c.name) for c in t.curves)) + 1
        for c in t.curves:
            said = f"  (prediction: {c.prediction})" if c.prediction else ""
            own = f"  (your node: {c.external})" if c.external else ""
            print(f"  {c.name:<{width}} over {c.knob}{said}{own}")
            for p in c.points:
                marks = "".join("*" if p.on_front[k] else " " for k in FRONT_RANKED)
                cells = " ".join(
                    f"{METRICS[k].heading} {METRICS[k].format(p.figures[k])}"
                    for k in ("f_sw_hz", "t_ripple_cont", "t_rmse_cont", "i_thd_cont")
                )
                tdd = METRICS["i_tdd_cont"].format(p.figures["i_tdd_cont"])
                value = "" if c.knob == "ts" else f" {c.knob.rsplit('.', 1)[-1]} = {p.value:<8g}"
                loss = METRICS[LOSS].format(p.figures[LOSS])
                print(
                    f"    {marks} ts {1e6 * p.ts:>5g} µs{value} {cells} TDD {tdd} % "
                    f"P_inv {loss} W dT {100 * p.misses['torque']:+.2f} %"
                    + ("" if p.holds else "  (off)")
                )
        _front_tables(t.ranking, t.at, t.torque_miss_at, heads, width)
        if t.loss_columns:
            print(f"  at equal inverter loss ({METRICS[LOSS].title}):")
            heads_w = "".join(f" {f'{w:g} W':>17}" for w in t.loss_columns)
            _front_tables(t.ranking_loss, t.at_loss, t.torque_miss_at_loss, heads_w, width)
        if t.papers_ranking:
            print(f"  papers' ranking ({t.papers_source}): " + " < ".join(t.papers_ranking))
        if t.excluded:
            print(f"  left the operating point ({len(t.excluded)} runs, not on the fronts):")
            for e in t.excluded:
                print(
                    f"    {e.curve} ts {1e6 * e.ts:g} µs value {e.value:g} f_sw "
                    f"{f_sw.format(e.f_sw_hz)} kHz: {e.reason}"
                )
    print(f"(* on the front against f_sw of {', '.join(METRICS[k].title for k in FRONT_RANKED)})")
    print(f"How computed: {d.how}")


def print_efficiency(d: EfficiencyResult) -> None:
    print(f"{d.scenario}: {d.paper}  ({d.engine}, {d.runs} runs, {d.wall_s:.0f} s)")
    _settings(d)
    print(d.caption)
    print("every run with " + ", ".join(f"{k} = {v}" for k, v in d.every_run.items()))
    heads = "".join(f" {n:>6g}" for n in d.speeds_rpm)
    for m in d.maps:
        for key, scale in (("efficiency", 100.0), (LOSS, 1.0)):
            metric = METRICS[key]
            print()
            print(f"{m.name}: {metric.title} ({metric.unit}) by torque (N·m) and speed (r/min)")
            print(f"  {'':>6}{heads}")
            for t, row in zip(d.torques, m.grid(key, d.speeds_rpm, d.torques)):
                cells = "".join(f" {'-' if v is None else f'{scale * v:.1f}':>6}" for v in row)
                print(f"  {t:>6g}{cells}")
    excluded = d.excluded()
    if excluded:
        print()
        print(f"left the operating point ({len(excluded)} points, blank on their maps):")
        for name, p in excluded:
            print(f"  {name} {p.speed_rpm:g} r/min {p.torque:g} N·m: {p.reason}")
    print(f"How computed: {d.how}")


def print_robustness(d: RobustnessResult) -> None:
    print(
        f"{d.scenario}: {d.paper}  ({d.engine}, {d.draws} drives per point, seed {d.seed}, "
        f"{d.runs} runs, {d.wall_s:.0f} s)"
    )
    _settings(d)
    for p in d.points:
        print()
        print(f"{p.point}: {p.caption}")
        print(f"  drawn: {', '.join(p.spreads)}")
        if p.settings:
            print("  every run with " + ", ".join(f"{k} = {v}" for k, v in p.settings.items()))
        print_drawn(p.figures, d.shown, d.ranked)
        for key in d.ranked:
            print(f"  by mean {METRICS[key].title}: " + (" < ".join(p.ranking(key)) or "-"))
        if p.papers_ranking:
            print(f"  papers' ranking ({p.papers_source}): " + " < ".join(p.papers_ranking))
        if p.conditions:
            names = list(p.conditions)
            t = METRICS["t_rmse"]
            print(f"  {t.heading + ' (x nominal)':<22}" + "".join(f" {c:>20}" for c in names))
            for s in dict.fromkeys(s for c in p.conditions.values() for s in c):
                nominal = p.conditions.get("nominal", {}).get(s, {}).get("t_rmse")
                cells = []
                for c in names:
                    v = p.conditions[c].get(s, {}).get("t_rmse")
                    ratio = f" (x{v / nominal:.2f})" if v and nominal and c != "nominal" else ""
                    cells.append(f" {t.format(v) + ratio:>20}")
                print(f"    {s:<20}" + "".join(cells))
    print(f"How computed: {d.how}")


def _front_tables(
    ranking: dict[str, list[list[str]]],
    at: dict[str, dict[str, list[float | None]]],
    misses_at: dict[str, dict[str, list[float | None]]],
    heads: str,
    width: int,
) -> None:
    """Each ranked figure's fronts read at the columns ``heads`` and the lowest there."""
    for key, ranked in ranking.items():
        metric = METRICS[key]
        print(f"  {metric.heading + ' (mean torque miss)':<{width + 2}}{heads}")
        for name, values in at[key].items():
            misses = misses_at[key][name]
            cells = "".join(f" {_cell(metric, v, m):>17}" for v, m in zip(values, misses))
            print(f"    {name:<{width}}{cells}")
        best = "".join(f" {(r[0] if r else '-'):>17}" for r in ranked)
        print(f"    {'lowest':<{width}}{best}")


def _cell(metric: Metric, value: float | None, miss: float | None) -> str:
    if value is None:
        return "-"
    return f"{metric.format(value)} ({100 * (miss or 0.0):+.1f} %)"
