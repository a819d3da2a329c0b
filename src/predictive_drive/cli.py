"""predictive-drive: simulate electric drives under model predictive torque control on a
lock-step ROS 2 graph, record every run to MCAP, and evaluate, compare, replay and sweep the
recordings."""

from __future__ import annotations

import argparse
import json
import math
import os
import signal
import sys
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from . import __version__
from .api import analyze, bench, compare, repair, replay, report, reproduce, run, sweep
from .errors import ConfigError, Interrupted, PredictiveDriveError
from .live import DEFAULT_PORT
from .reports.papers import MTPA_STUDIES, PAPER_TABLES
from .ros.placement import AFFINITIES, SCHED_POLICIES

__all__ = ["main"]


def _finite(obj: Any) -> Any:
    """NaN/inf → None, so ``--json`` prints strict JSON (null where a figure does not exist)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    if isinstance(obj, np.floating):
        return _finite(float(obj))
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def dumps(obj: Any) -> str:
    """One line of strict JSON."""
    return json.dumps(_finite(obj), indent=None, allow_nan=False)


def _progress(
    enabled: bool, unit: str = "step"
) -> tuple[Callable[[int, int], None] | None, Callable[[], None]]:
    if not enabled:
        return None, lambda: None
    from tqdm import tqdm

    bar: dict[str, Any] = {}

    def update(k: int, n: int) -> None:
        if "bar" not in bar:
            bar["bar"] = tqdm(
                total=n, unit=unit, unit_scale=unit == "step", file=sys.stderr, leave=False
            )
        b = bar["bar"]
        b.update(k - b.n)

    def close() -> None:
        if "bar" in bar:
            bar["bar"].close()

    return update, close


def _switch(text: str) -> tuple[float, str]:
    t, sep, name = text.partition(":")
    try:
        if not sep:
            raise ValueError
        return float(t), name
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected T:STRATEGY (e.g. 2.5:mptc), got {text!r}"
        ) from None


def _print_metrics(d: dict[str, Any]) -> None:
    m = d["metrics"]
    print(
        f"scenario {d['scenario']}  strategy {d['strategy']}  engine {d['engine']}  "
        f"steps {d['steps']}" + (f"  wall {d['wall_s']:.2f} s" if "wall_s" in d else "")
    )
    print(f"bag      {d['bag']}")
    print(f"window   {m['t_start']:.4g}-{m['t_end']:.4g} s ({m['steps']} steps)")
    rows = [
        (
            "T_RMSE",
            f"{m['t_rmse']:.4f} N·m",
            "sqrt(mean((T_e - T*)^2)), true torque at k vs T* used at k",
        ),
        ("psi_RMSE", f"{m['psi_rmse']:.5f} Wb", "sqrt(mean((|psi_s| - psi*)^2)), true flux"),
        ("f_ave", f"{m['f_ave_hz'] / 1e3:.3f} kHz", "device transitions / (6 t), 2 per leg change"),
        ("Cal_ave", f"{m['cal_ave']:.3f}", "vector predictions per step"),
        ("deadbeat", f"{100 * m['deadbeat_share']:.2f} %", "steps with 0 < t_u < Ts"),
        ("speed_RMSE", f"{m['speed_rmse']:.3f} rad/s", "omega_m vs omega_m*"),
        ("compute", f"{m['compute_ns_median'] / 1e3:.2f} µs/step", "median, control law only"),
    ]
    if m.get("thd") is not None and m["thd"] == m["thd"]:  # NaN: no THD window
        rows.append(
            (
                "THD_a",
                f"{100 * m['thd']:.2f} %",
                f"phase-a distortion, {m['thd_cycles']} cycles of "
                f"{m['thd_fundamental_hz']:.1f} Hz (harmonics alone {100 * m['thd_harmonics']:.2f} %)",
            )
        )
    for name, value, how in rows:
        print(f"  {name:<11}{value:>16}   {how}")
    if any(m["utilization"]):
        util = " ".join(f"V{i} {100 * u:.1f}%" for i, u in enumerate(m["utilization"]))
        print(f"  {'vectors':<11}{util}")
    spans = d.get("strategies", [])
    if len(spans) > 1:
        for sp in spans:
            print(
                f"  {'strategy':<11}{sp['strategy']:>16}   steps {sp['first']}-{sp['last']} "
                f"({sp['t_start']:g}-{sp['t_end']:g} s)"
            )
    if d.get("outcome"):
        print(f"  {'outcome':<11}{d['outcome']}")
    for e in d.get("parameter_events", []):
        changes = ", ".join(f"{k} = {v}" for k, v in e["changed"].items())
        print(f"  {'parameter':<11}{e['t']:>14.6g} s   {e['node']}: {changes}")
    for st in d.get("load_steps", []):
        print(
            f"  load {st['load_torque']:g} N·m from {st['t_start']:g} s: current angle "
            f"{st['theta_deg']:.2f} deg, |i_s| {st['i_s']:.4f} A (means over the step's second "
            f"half, measured), angle settled {st['settle_s']:.3f} s after the step"
        )


def cmd_run(a: argparse.Namespace) -> int:
    if a.live:
        print(
            f"predictive-drive: live view on ws://127.0.0.1:{a.live} (Foxglove / Lichtblick: "
            "open connection, Foxglove WebSocket)",
            file=sys.stderr,
        )
    update, close = _progress(sys.stderr.isatty() and not a.json)
    try:
        r = run.run(
            a.scenario,
            strategy=a.strategy,
            duration=a.duration,
            engine=a.engine,
            out=a.out,
            switches=a.switch or (),
            progress=update,
            affinity=a.affinity,
            sched=a.sched,
            peer_timeout=a.peer_timeout,
            live=a.live or 0,
        )
    finally:
        close()
    if a.json:
        print(dumps(r.as_dict()))
    else:
        _print_metrics(r.as_dict())
    return 0


def cmd_report(a: argparse.Namespace) -> int:
    d = report.report(a.bag, figures=a.figures)
    if a.json:
        print(dumps(d))
    else:
        _print_metrics(d)
        if not d["complete"]:
            print(
                "  note: the recording is truncated (no index: its writer was killed); read up "
                f"to its last complete step; `predictive-drive repair {d['bag']}` rebuilds it"
            )
        if d["steps"] < d["planned_steps"]:
            print(
                f"  note: the run stopped early: {d['steps']} of {d['planned_steps']} planned "
                "steps recorded"
            )
        for f in d.get("figures", []):
            print(f"figure   {f}")
    return 0


def _print_mtpa(d: dict[str, Any]) -> None:
    print(f"{d['scenario']}: {d['paper']}  (engine {d['engine']})")
    if d["duration"] is not None:
        print(f"NOTE: runs shortened to {d['duration']:g} s")
    if d.get("settings"):
        print("every run with " + ", ".join(f"{k} = {v}" for k, v in d["settings"].items()))
    print(
        f"{'strategy':<14} {'form':<10} {'L_d':>4} {'L_q':>4} {'T_L':>5} {'theta':>7} "
        f"{'MTPA':>7} {'error':>6} {'|i_s|':>8} {'MTPA':>8} {'excess':>7} {'i_d=0':>8} "
        f"{'settle':>7}"
    )
    print(
        f"{'':<14} {'':<10} {'x':>4} {'x':>4} {'N·m':>5} {'deg':>7} {'deg':>7} {'deg':>6} "
        f"{'A':>8} {'A':>8} {'%':>7} {'A':>8} {'s':>7}"
    )
    for r in d["rows"]:
        m = r["mismatch"]
        err = r["theta_deg"] - r["theta_mtpa_deg"]
        excess = 100.0 * (r["i_s"] / r["i_s_mtpa"] - 1.0)
        print(
            f"{r['strategy']:<14} {r['form'] or '':<10} {m['l_d']:>4g} {m['l_q']:>4g} "
            f"{r['load_torque']:>5g} {r['theta_deg']:>7.2f} {r['theta_mtpa_deg']:>7.2f} "
            f"{err:>+6.2f} {r['i_s']:>8.4f} {r['i_s_mtpa']:>8.4f} {excess:>+7.3f} "
            f"{r['i_s_zero_d']:>8.4f} {r['settle_s']:>7.3f}"
        )
    for c in d["claims"]:
        print(
            f"paper's claims at {c['load_torque']:g} N·m: settles in {c['settle_s']:.3f} s "
            f"({'confirmed' if c['settles_under_1_s'] else 'REFUTED'}: well under 1 s); "
            f"|i_s| {c['i_s']:.4f} A vs {c['i_s_zero_d_measured']:.4f} A under i_d = 0: "
            f"{100 * c['saving_vs_zero_d']:+.3f} % saved of {100 * c['saving_possible']:.3f} % "
            f"possible, resolution {100 * c['resolution']:.3f} % ({c['less_current_than_zero_d']}:"
            f" less current than i_d = 0)"
        )
    print(f"How computed: {d['how']}")


def _row_label(r: dict[str, Any]) -> str:
    return str(r.get("label") or r["strategy"])


def cmd_sweep(a: argparse.Namespace) -> int:
    update, close = _progress(sys.stderr.isatty() and not a.json, unit="run")
    try:
        r = sweep.sweep(
            a.scenario,
            strategies=[s for s in (a.strategy or "").split(",") if s],
            sets=a.set or [],
            duration=a.duration,
            out=a.out,
            record=a.record,
            figures=a.figures,
            scheduler=a.scheduler,
            jobs=a.jobs,
            progress=update,
        )
    finally:
        close()
    if a.json:
        print(dumps(r.as_dict()))
    else:
        _print_sweep(r)
    return 130 if r.interrupted else 0


def _print_sweep(r: sweep.SweepResult) -> None:
    keys = list(dict.fromkeys(k for row in r.rows for k in row.settings))
    widths = [max(len(k.rsplit(".", 1)[-1]), 6) for k in keys]
    head = " ".join(f"{k.rsplit('.', 1)[-1]:>{w}}" for k, w in zip(keys, widths))
    print(f"{'strategy':<14} {head} {'T_RMSE':>8} {'psi_RMSE':>9} {'f_ave':>8} {'THD_a':>7}")
    print(f"{'':<14} {' ' * len(head)} {'N·m':>8} {'Wb':>9} {'kHz':>8} {'%':>7}")
    for row in r.rows:
        values = " ".join(f"{str(row.settings.get(k)):>{w}}" for k, w in zip(keys, widths))
        if row.error:
            print(f"{row.strategy:<14} {values} error: {row.error}")
            continue
        m = row.metrics or {}
        print(
            f"{row.strategy:<14} {values} {m['t_rmse']:>8.4f} {m['psi_rmse']:>9.5f} "
            f"{m['f_ave_hz'] / 1e3:>8.3f} {100 * m['thd']:>7.2f}"
        )
    runs = len(r.rows)
    print(
        f"{runs} of {r.cases} runs in {r.wall_s:.1f} s on {r.engine} "
        f"({runs / r.wall_s:.2f} runs/s)"
        + ("; interrupted: the rows above are kept" if r.interrupted else "")
    )
    for f in [*r.files, *r.figures]:
        print(f"wrote    {f}")


def cmd_reproduce(a: argparse.Namespace) -> int:
    settings = {}
    for text in a.set or []:
        key, values = sweep.parse_set(text)
        if len(values) != 1:
            raise ConfigError(f"--set {text}: one value per key here (a grid is `sweep`)")
        settings[key] = values[0]
    d = reproduce.reproduce(
        a.scenario,
        engine=a.engine,
        repeats=a.repeats,
        duration=a.duration,
        figures=a.figures,
        settings=settings,
    )
    if a.json:
        print(dumps(d))
        return 0
    if d["scenario"] in MTPA_STUDIES:
        _print_mtpa(d)
        return 0
    cols = PAPER_TABLES[d["scenario"]].columns
    print(f"{d['scenario']} vs {d['paper']}  (engine {d['engine']})")
    if d["duration"] is not None:
        print(f"NOTE: runs shortened to {d['duration']:g} s; not comparable with the paper")
    if d.get("settings"):
        print("every run with " + ", ".join(f"{k} = {v}" for k, v in d["settings"].items()))
    width = max(len(_row_label(r)) for r in d["rows"]) + 1
    head = f"{'':<{width}}" + "".join(f" {c.title:>17}" for c in cols)
    sub = f"{'':<{width}}" + "".join(f" {'ours':>8} {'paper':>8}" for _ in cols)
    print(head)
    print(sub)
    for r in d["rows"]:
        line = f"{_row_label(r):<{width}}"
        for c in cols:
            ours = r.get(c.key)
            paper = r["paper"].get(c.key)
            line += f" {format(ours * c.scale, c.fmt) if ours is not None else '-':>8}"
            line += f" {format(paper * c.scale, c.fmt) if paper is not None else '-':>8}"
        print(line)
    print(f"How computed: {d['how']}")
    return 0


def cmd_analyze(a: argparse.Namespace) -> int:
    d = analyze.analyze(a.bag, threshold=a.threshold, write_tables=a.write_tables)
    if a.json:
        print(dumps(d))
        return 0
    print(
        f"{d['bag']}: {d['scenario']} / {d['strategy']}, {d['steps']} steps over "
        f"{d['window'][0]:g}-{d['window'][1]:g} s, threshold {d['threshold']:g} N·m"
    )
    print("\nZero-vector use by torque-error band (paper 001 Table 1; the paper's from a mptc run)")
    print(f"  {'|dT| <= N·m':>12} {'N':>7} {'N_V0':>7} {'eta_V0':>7}   {'paper N':>8} {'N_V0':>7}")
    for b in d["bands"]:
        p = b["paper"] or ("", "")
        band = "all" if b["band"] is None else f"{b['band']:.1f}"
        print(
            f"  {band:>12} {b['n']:>7} {b['n_v0']:>7} {100 * b['eta_v0']:>6.2f}%   "
            f"{p[0]:>8} {p[1]:>7}"
        )
    for table, nsec in (("six_sector", 6), ("twelve_sector", 12)):
        for cls, shares in d["utilization"][table].items():
            n = d["class_steps"][table][cls]
            what = "Tables 3-4" if nsec == 6 else "Tables 5-8"
            print(f"\nUtilization %, {nsec} sectors, {cls} (paper 001 {what}); steps per sector:")
            print("       " + "".join(f"{'th' + str(s + 1):>7}" for s in range(nsec)))
            print("  N    " + "".join(f"{x:>7}" for x in n))
            for v in range(7):
                print(f"  V{v}   " + "".join(f"{100 * shares[s][v]:>7.1f}" for s in range(nsec)))
            sets = d["derived"][table][cls]
            print("  sets " + " ".join("{" + ",".join(f"V{v}" for v in c) + "}" for c in sets))
    print(f"\nRule: {d['rule']}")
    if d["matches_tables"]:
        print("Derived sets = the tables simplified2/simplified3 use (all 60 classes).")
    else:
        print(f"Derived sets differ from the tables in use in {len(d['differences'])} classes:")
        for line in d["differences"]:
            print(f"  {line}")
    if "written" in d:
        print(f"Wrote {d['written']}")
    return 0


def cmd_bench(a: argparse.Namespace) -> int:
    d = bench.bench(repeats=a.repeats, steps=a.steps, ros=not a.no_ros, quick=a.quick)
    if a.json:
        print(dumps(d))
        return 0
    rt = d["real_time_steps_per_s"]
    print(
        f"core in-process loop (im_paper, db_mptc, {d['steps']} steps, median of "
        f"{len(d['core_steps_per_s_runs'])}): {d['core_steps_per_s']:,.0f} steps/s "
        f"({d['core_steps_per_s'] / rt:.2f}x real time)"
    )
    print(f"in-process with MCAP recording: {d['inprocess_recorded_steps_per_s']:,.0f} steps/s")
    print(f"reading the recording back and evaluating it: {d['report_steps_per_s']:,.0f} steps/s")
    whats = {
        "ros_steps_per_s": "four processes, paired CPUs, SCHED_BATCH, recording on",
        "ros_immediate_steps_per_s": "the same, speed_loop immediate: the controller waits "
        "for the speed PI",
        "ros_sched_other_steps_per_s": "four processes, paired CPUs, --sched other, recording on",
        "ros_unpinned_steps_per_s": "four processes, --affinity none --sched other, recording on",
        "composed_steps_per_s": "one process",
    }
    for k, what in whats.items():
        if k not in d:
            continue
        startup = d[k.replace("steps_per_s", "startup_s")]
        if d[k] is None:
            print(f"{k} ({what}): no figure (too few progress samples for a slope)")
        else:
            print(
                f"{k} ({what}): {d[k]:,.0f} steps/s ({d[k] / rt:.2f}x real time; slope over "
                f"20-90 % of one run, start-up {startup:.1f} s excluded)"
            )
    for name, us in d["compute_us_per_step"].items():
        print(f"controller compute {name:<8} {us:6.2f} µs/step (median)")
    return 0


def _remap(text: str) -> tuple[str, str]:
    old, sep, new = text.partition(":=")
    if not (sep and old and new):
        raise argparse.ArgumentTypeError(
            f"expected OLD:=NEW (e.g. /clock:=/sim_clock), got {text!r}"
        )
    return old, new


def cmd_compare(a: argparse.Namespace) -> int:
    d = compare.compare(a.bags, figures=a.figures)
    if a.json:
        print(dumps(d))
        return 0
    rows = [
        ("T_RMSE N·m", "t_rmse", 1.0, ".4f"),
        ("psi_RMSE Wb", "psi_rmse", 1.0, ".5f"),
        ("f_ave kHz", "f_ave_hz", 1e-3, ".3f"),
        ("Cal_ave", "cal_ave", 1.0, ".2f"),
        ("deadbeat %", "deadbeat_share", 100.0, ".2f"),
        ("speed_RMSE rad/s", "speed_rmse", 1.0, ".3f"),
        ("THD %", "thd", 100.0, ".2f"),
        ("compute µs/step", "compute_ns_median", 1e-3, ".2f"),
    ]
    width = max(len(r["label"]) for r in d["runs"]) + 2
    print(f"{'':<18}" + "".join(f"{r['label']:>{width}}" for r in d["runs"]))
    for title, key, scale, fmt in rows:
        cells = []
        for r in d["runs"]:
            v = r["metrics"].get(key)
            cells.append("-" if v is None or v != v else format(v * scale, fmt))
        print(f"{title:<18}" + "".join(f"{c:>{width}}" for c in cells))
    for f in d.get("figures", []):
        print(f"figure {f}")
    return 0


def cmd_replay(a: argparse.Namespace) -> int:
    if a.into:
        d = replay.replay_into(a.bag, node=a.into, strategy=a.strategy, out=a.out)
        if a.json:
            print(dumps(d))
            return 0
        ag = d["agreement"]
        print(
            f"replayed {a.bag} into the torque controller ({d['strategy']}): {d['steps']} "
            f"steps at {d['steps_per_s']:,.0f} steps/s; new bag {d['bag']}"
        )
        print(
            f"  agreement with the recorded commands: vector {100 * ag['vector']:.2f} %, "
            f"pulses {100 * ag['pulses']:.2f} %; compute {d['compute_us_per_step']:.2f} µs/step"
        )
        return 0
    d = replay.replay(
        a.bag,
        rate=a.rate,
        start_offset=a.start_offset,
        playback_duration=a.playback_duration,
        loop=a.loop,
        topics=tuple(a.topics or ()),
        exclude_topics=tuple(a.exclude_topics or ()),
        remap=dict(a.remap or ()),
        clock_hz=a.clock,
        start_paused=a.start_paused,
    )
    if a.json:
        print(
            dumps({k: d[k] for k in ("published", "achieved_rate", "lag_s", "max_lag_s", "wall_s")})
        )
        return 0
    total = sum(d["published"].values())
    print(
        f"replayed {d['bag']}: {total} messages in {d['wall_s']:.2f} s "
        f"({d['passes']} pass{'es' if d['passes'] > 1 else ''}), achieved rate "
        f"{d['achieved_rate']:.3g} (recorded s per wall s)"
    )
    for topic, n in d["published"].items():
        print(f"  {topic:<28}{n:>9}")
    if d["max_lag_s"] > 0.1:
        print(
            f"  fell behind the recording's pace by up to {d['max_lag_s']:.2f} s (at the end "
            f"{d['lag_s']:.2f} s): every message was published, in order, but late"
        )
    return 0


def cmd_layout(a: argparse.Namespace) -> int:
    from .reports.layout import write_layout

    path = write_layout(a.out)
    print(f"wrote {path}: import it in Foxglove or Lichtblick (Layouts → Import from file)")
    return 0


def cmd_repair(a: argparse.Namespace) -> int:
    d = repair.repair(a.bag)
    if a.json:
        print(dumps(d))
    elif d["repaired"]:
        print(
            f"repaired {d['bag']}: {d['messages']} messages, {d['steps']} whole steps; the "
            f"original file is kept as {d['original']}"
        )
    else:
        print(f"{d['bag']} is intact ({d['messages']} messages, {d['steps']} steps): left as it is")
    return 0


def cmd_param(a: argparse.Namespace) -> int:
    from .ros.params import param

    if a.action == "get":
        if a.value is not None:
            raise PredictiveDriveError("param get takes NODE NAME only")
        print(param(node=a.node, name=a.name))
    else:
        if a.value is None:
            raise PredictiveDriveError("param set needs NODE NAME VALUE")
        param(node=a.node, name=a.name, value=a.value)
        print(f"set {a.name} = {a.value} on {a.node}")
    return 0


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(prog="predictive-drive", description=__doc__)
    p.add_argument("--version", action="version", version=f"%(prog)s {__version__}")
    sub = p.add_subparsers(dest="verb", required=True)

    r = sub.add_parser("run", help="run a scenario, record it to bags/<run>/ and print its metrics")
    r.add_argument("scenario", help="scenario name in config/ or a path to a scenario .yaml")
    r.add_argument("--strategy", help="override the scenario's torque_controller.strategy")
    r.add_argument("--duration", type=float, help="simulated seconds (default: the scenario's)")
    r.add_argument(
        "--engine",
        default="ros",
        choices=run.ENGINES,
        help="ros: four node processes (default); composed: one process; inprocess: no ROS",
    )
    r.add_argument(
        "--composed",
        dest="engine",
        action="store_const",
        const="composed",
        help="same as --engine composed",
    )
    r.add_argument(
        "--affinity",
        default="paired",
        choices=AFFINITIES,
        help="CPU placement of the node processes: paired (default) keeps plant + "
        "torque_controller on one CPU and speed_pi + metrics_logger on another; none: the "
        "kernel's choice",
    )
    r.add_argument(
        "--sched",
        default="batch",
        choices=tuple(SCHED_POLICIES),
        help="scheduling policy of the node processes' threads: batch (default, SCHED_BATCH: a "
        "woken node does not preempt the one publishing to it) or other (the kernel's default)",
    )
    r.add_argument("--out", help="bag directory to write (must not exist)")
    r.add_argument(
        "--live",
        type=int,
        nargs="?",
        const=DEFAULT_PORT,
        metavar="PORT",
        help="serve the running drive to Foxglove / Lichtblick on ws://127.0.0.1:PORT (default "
        f"{DEFAULT_PORT}): the topics decimated to 1 kHz of simulated time, /clock as the "
        "app's time, the strategy as a parameter the app can set",
    )
    r.add_argument(
        "--peer-timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="ROS engines: s of wall time a node waits for a silent peer (or the recorder) "
        "before the run fails (default 10)",
    )
    r.add_argument(
        "--switch",
        action="append",
        type=_switch,
        metavar="T:STRATEGY",
        help="switch the strategy at simulated time T (repeatable)",
    )
    r.add_argument("--json", action="store_true", help="print one JSON object")
    r.set_defaults(func=cmd_run)

    rep = sub.add_parser("report", help="metrics of a recording, from the recording alone")
    rep.add_argument("bag", help="bag directory (or its .mcap file)")
    rep.add_argument("--figures", metavar="DIR", help="also draw the run's figures (PNG) here")
    rep.add_argument("--json", action="store_true")
    rep.set_defaults(func=cmd_report)

    cmp_ = sub.add_parser("compare", help="recordings side by side: metrics, overlaid figures")
    cmp_.add_argument("bags", nargs="+", metavar="BAG")
    cmp_.add_argument("--figures", metavar="DIR", help="draw the overlaid figures (PNG) here")
    cmp_.add_argument("--json", action="store_true")
    cmp_.set_defaults(func=cmd_compare)

    sw = sub.add_parser(
        "sweep",
        help="a grid of in-process runs (strategies x settings) on the local cores or a Dask "
        "cluster, as one table",
    )
    sw.add_argument("scenario", help="scenario name (config/NAME.yaml) or a scenario file")
    sw.add_argument("--strategy", metavar="A,B,...", help="strategies (default: the scenario's)")
    sw.add_argument(
        "--set",
        action="append",
        metavar="KEY=V1,V2,...",
        help="a scenario key and its values (dotted: torque_controller.lambda_psi, "
        "torque_controller.motor.l_q; *0.7 = 70 %% of the present value); repeat for more keys: "
        "the grid is their cartesian product",
    )
    sw.add_argument("--duration", type=float, help="simulated seconds of every run")
    sw.add_argument("--out", metavar="DIR", help="write DIR/sweep.csv and DIR/sweep.parquet")
    sw.add_argument("--record", action="store_true", help="keep every run's bag in DIR/bags/")
    sw.add_argument("--figures", metavar="DIR", help="each metric against each swept key (PNG)")
    sw.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run on a Dask cluster (tcp://host:8786; `dask scheduler`, `dask worker ADDRESS`) "
        "instead of the local cores",
    )
    sw.add_argument("--jobs", type=int, help="local processes (default: one per core)")
    sw.add_argument("--json", action="store_true")
    sw.set_defaults(func=cmd_sweep)

    rp = sub.add_parser("reproduce", help="a paper's table side by side with our figures")
    rp.add_argument("scenario", choices=sorted([*PAPER_TABLES, *MTPA_STUDIES]))
    rp.add_argument("--engine", default="inprocess", choices=run.ENGINES)
    rp.add_argument(
        "--repeats", type=int, default=5, help="timing repeats for compute ratios (median)"
    )
    rp.add_argument(
        "--duration", type=float, help="shorten every run to this many simulated seconds"
    )
    rp.add_argument("--figures", metavar="DIR", help="draw the table's runs, overlaid (PNG)")
    rp.add_argument(
        "--set",
        action="append",
        metavar="KEY=VALUE",
        help="a scenario setting for every run, e.g. speed_pi.speed_loop=immediate (repeatable)",
    )
    rp.add_argument("--json", action="store_true")
    rp.set_defaults(func=cmd_reproduce)

    an = sub.add_parser(
        "analyze",
        help="vector utilization of a recording (paper 001 Tables 1, 3-8) and the candidate sets "
        "it derives",
    )
    an.add_argument("bag", help="bag directory (or its .mcap file)")
    an.add_argument(
        "--threshold", type=float, help="torque threshold, N·m (default: the recorded scenario's)"
    )
    an.add_argument(
        "--write-tables",
        metavar="PATH",
        help="write the derived candidate tables as JSON (the format of "
        "core/candidate_tables.json, which simplified2/simplified3 use)",
    )
    an.add_argument("--json", action="store_true")
    an.set_defaults(func=cmd_analyze)

    rpl = sub.add_parser(
        "replay",
        help="publish a recording onto ROS topics with its QoS, paced by its log time (as ros2 "
        "bag play does), on the environment's ROS_DOMAIN_ID",
    )
    rpl.add_argument("bag", help="bag directory (or its .mcap file)")
    rpl.add_argument("--rate", type=float, default=1.0, help="recorded s per wall s (> 0)")
    rpl.add_argument("--start-offset", type=float, default=0.0, metavar="S",
                     help="start S s of recorded time after the bag's start")  # fmt: skip
    rpl.add_argument("--playback-duration", type=float, metavar="S",
                     help="play S s of recorded time")  # fmt: skip
    rpl.add_argument("--loop", action="store_true", help="play again from the start at the end")
    rpl.add_argument("--topics", nargs="+", metavar="TOPIC", help="play only these topics")
    rpl.add_argument("--exclude-topics", nargs="+", metavar="TOPIC", help="leave these out")
    rpl.add_argument("--remap", action="append", type=_remap, metavar="OLD:=NEW",
                     help="publish topic OLD as NEW (repeatable)")  # fmt: skip
    rpl.add_argument("--clock", type=float, nargs="?", const=40.0, metavar="HZ",
                     help="publish /clock from the replayed time at HZ (default 40) instead of "
                     "the recorded /clock")  # fmt: skip
    rpl.add_argument("--start-paused", action="store_true",
                     help="start paused (`predictive-drive param set player paused false`)")  # fmt: skip
    rpl.add_argument(
        "--into",
        choices=["torque_controller"],
        help="instead: feed the recorded states and references step by step into a node of "
        "this kind and record its new commands (deterministic replay)",
    )
    rpl.add_argument(
        "--strategy",
        help="with --into: the strategy to replay into (default: the recording's, switched "
        "where it switched)",
    )
    rpl.add_argument("--out", help="with --into: the new bag (default: beside the recording)")
    rpl.add_argument("--json", action="store_true")
    rpl.set_defaults(func=cmd_replay)

    lay = sub.add_parser(
        "layout", help="write a Foxglove / Lichtblick layout for the drive's topics (JSON)"
    )
    lay.add_argument("--out", default="layouts/drive.foxglove.json", help="default: %(default)s")
    lay.set_defaults(func=cmd_layout)

    rr = sub.add_parser(
        "repair",
        help="rebuild a recording whose writer was killed (index, footer, metadata.yaml); "
        "the original file is kept as <name>.mcap.orig",
    )
    rr.add_argument("bag", help="bag directory (or its .mcap file)")
    rr.add_argument("--json", action="store_true")
    rr.set_defaults(func=cmd_repair)

    b = sub.add_parser("bench", help="throughput figures of this machine")
    b.add_argument("--repeats", type=int, default=5)
    b.add_argument("--steps", type=int, default=20000)
    b.add_argument("--no-ros", action="store_true", help="skip the graph engines")
    b.add_argument(
        "--quick", action="store_true", help="short runs: a smoke test, not a measurement"
    )
    b.add_argument("--json", action="store_true")
    b.set_defaults(func=cmd_bench)
    pp = sub.add_parser(
        "param",
        help="get or set a parameter of a running node "
        "(uses ROS_DOMAIN_ID; `run` prints the domain of its graph)",
    )
    pp.add_argument("action", choices=["get", "set"])
    pp.add_argument("node", help="node name, e.g. torque_controller or /drive/torque_controller")
    pp.add_argument("name")
    pp.add_argument("value", nargs="?")
    pp.set_defaults(func=cmd_param)
    return p


def _interrupt(signum: int, frame: object) -> None:
    raise KeyboardInterrupt


def main(argv: Sequence[str] | None = None) -> int:
    # Ctrl-C and SIGTERM both end the run the same way: children stopped, bag closed. (A shell's
    # background job inherits SIGINT ignored; the graph's owner must still honour it.)
    signal.signal(signal.SIGINT, _interrupt)
    signal.signal(signal.SIGTERM, _interrupt)
    args = build_parser().parse_args(argv)
    as_json = bool(getattr(args, "json", False))
    try:
        return int(args.func(args))
    except Interrupted as e:
        _say_error(e, as_json)
        return 130
    except PredictiveDriveError as e:
        _say_error(e, as_json)
        return 2
    except KeyboardInterrupt:
        _say_error(Interrupted("interrupted"), as_json)
        return 130
    except BrokenPipeError:
        # the reader went away (`report BAG | head -1`): nothing more to say to it
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 2


def _say_error(e: PredictiveDriveError, as_json: bool) -> None:
    """An error on stderr; with --json also as one JSON object on stdout."""
    print(f"predictive-drive: error: {e}", file=sys.stderr)
    if as_json:
        print(dumps({"error": str(e), "kind": type(e).__name__}))


if __name__ == "__main__":
    sys.exit(main())
