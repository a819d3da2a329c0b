"""``predictive-drive sweep SCENARIO``: a grid of in-process runs, as one table."""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from typing import Any

from ..api.sweep import DRAW_COLUMNS, DRAW_RANKED, SweepResult, sweep
from ..core.metrics import METRICS, books_losses
from .common import refuse, runs_progress, say_json, scenario_argument, seconds

HELP = (
    "a grid of in-process runs (strategies x settings) on the local cores or a Dask cluster, "
    "as one table"
)
#: the table's metric columns (how each is shown: core.metrics.METRICS), and those it adds where
#: a run booked losses (the CSV and Parquet tables have every loss metric)
COLUMNS = ("t_rmse", "psi_rmse", "f_ave_hz", "f_sw_hz", "thd")
LOSS_COLUMNS = ("p_inverter", "efficiency", "tj_max")


def add_arguments(p: argparse.ArgumentParser) -> None:
    scenario_argument(p)
    p.add_argument("--strategy", metavar="A,B,...", help="strategies (default: the scenario's)")
    p.add_argument(
        "--set",
        action="append",
        metavar="KEY=V1,V2,...",
        help="a scenario key and its values (dotted: torque_controller.lambda_psi, "
        "torque_controller.motor.l_q; *0.7 = 70 %% of the present value); repeat for more keys: "
        "the grid is their cartesian product. Each run's settings are checked with its own "
        "strategy: a value that strategy cannot take (a horizon for a one-step law) is that "
        "row's error, saying why, and the other rows run",
    )
    p.add_argument("--duration", type=seconds, help="simulated seconds of every run")
    p.add_argument(
        "--out",
        metavar="DIR|FILE",
        help="write the table: DIR/sweep.csv and DIR/sweep.parquet (Parquet needs pyarrow), or "
        "FILE.csv alone, or FILE.parquet alone",
    )
    p.add_argument(
        "--record", action="store_true", help="keep every run's bag in DIR/bags/ (--out DIR)"
    )
    p.add_argument("--figures", metavar="DIR", help="each metric against each swept key (PNG)")
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="run on a Dask cluster (tcp://host:8786; `dask scheduler`, `dask worker ADDRESS`) "
        "instead of the local cores",
    )
    p.add_argument("--jobs", type=int, help="local processes (default: one per core)")
    p.add_argument(
        "--draw",
        type=int,
        metavar="N",
        help="run every case on N drives drawn from the --spread distributions (the same N for "
        "every strategy); prints each strategy's mean with its 95%% interval and its chance of "
        "ranking first",
    )
    p.add_argument(
        "--spread",
        action="append",
        metavar="KEY=normal:S|uniform:S",
        help="a parameter drawn around its value: times 1 + S*z (z standard normal) or "
        "1 + S*u (u uniform in -1..1), e.g. plant.motor.l_q=normal:0.1; repeat for more keys",
    )
    p.add_argument("--seed", type=int, default=0, help="seed of the draws (default 0)")


def main(a: argparse.Namespace) -> int:
    if a.scheduler:
        refuse(a, "sets the local processes; with --scheduler the cluster's workers run", "jobs")
    update, close = runs_progress(f"sweep {a.scenario}", quiet=a.json)
    settings = dict(
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
    try:
        if a.draw is not None or a.spread:
            from ..api.draws import sweep_drawn

            r = sweep_drawn(
                a.scenario, draw=a.draw, spreads=a.spread or [], seed=a.seed, **settings
            )
        else:
            r = sweep(a.scenario, **settings)
    finally:
        close()
    if a.json:
        say_json(r)
    else:
        print_sweep(r)
    return 130 if r.interrupted else 0


def print_sweep(r: SweepResult) -> None:
    if r.spreads:
        print(f"{len(r.rows) // max(1, len({row.strategy for row in r.rows}))} drives drawn "
              f"(seed {r.seed}): {', '.join(r.spreads)}")  # fmt: skip
        print_drawn(r.drawn, DRAW_COLUMNS, DRAW_RANKED)
        _totals(r)
        return
    keys = list(dict.fromkeys(k for row in r.rows for k in row.settings))
    widths = [
        max(6, len(k.rsplit(".", 1)[-1]), *(len(str(row.settings.get(k))) for row in r.rows))
        for k in keys
    ]
    head = " ".join(f"{k.rsplit('.', 1)[-1]:>{w}}" for k, w in zip(keys, widths))
    columns = COLUMNS + (LOSS_COLUMNS if any(books_losses(row.metrics) for row in r.rows) else ())
    shown = [METRICS[c] for c in columns]
    cw = [max(9, len(m.title)) for m in shown]
    print(f"{'strategy':<14} {head} " + " ".join(f"{m.title:>{w}}" for m, w in zip(shown, cw)))
    print(f"{'':<14} {' ' * len(head)} " + " ".join(f"{m.unit:>{w}}" for m, w in zip(shown, cw)))
    for row in r.rows:
        values = " ".join(f"{str(row.settings.get(k)):>{w}}" for k, w in zip(keys, widths))
        if row.error or row.metrics is None:
            print(f"{row.strategy:<14} {values} error: {row.error}")
            continue
        cells = " ".join(
            f"{m.format(getattr(row.metrics, c)):>{w}}" for m, c, w in zip(shown, columns, cw)
        )
        print(f"{row.strategy:<14} {values} {cells}")
    _totals(r)


def _totals(r: SweepResult) -> None:
    runs = len(r.rows)
    print(
        f"{runs} of {r.cases} runs in {r.wall_s:.1f} s on {r.engine} "
        f"({runs / r.wall_s:.2f} runs/s)"
        + ("; interrupted: the rows above are kept, each a complete run" if r.interrupted else "")
    )
    for what in r.cut:
        print(f"not complete: {what}")
    for f in [*r.files, *r.figures]:
        print(f"wrote    {f}")


def print_drawn(figures: Sequence[Any], keys: Sequence[str], ranked: Sequence[str]) -> None:
    """Each strategy over drawn drives (:class:`~..api.draws.StrategyFigures`): per metric the
    mean [95 % interval], per ranked metric the share of draws it ranks first [interval]."""
    fixed = [  # the settings that tell the groups apart (a sweep's grid)
        k for k in dict.fromkeys(k for f in figures for k in f.settings)
        if len({repr(f.settings.get(k)) for f in figures}) > 1
    ]  # fmt: skip
    head = [f"{k.rsplit('.', 1)[-1]:>10}" for k in fixed]
    cols = [f"{METRICS[k].heading:>26}" for k in keys]
    cols += [f"{'P(first) ' + METRICS[k].title:>22}" for k in ranked]
    cols += [f"{'vs best ' + METRICS[k].title:>26}" for k in ranked[:1]]
    print(f"{'strategy':<14} " + " ".join(head + cols))
    for f in figures:
        cells = [f"{str(f.settings.get(k)):>10}" for k in fixed]
        for k in keys:
            m, iv = METRICS[k], f.mean[k]
            cells.append(
                f"{m.format(iv.value):>9} [{m.format(iv.low)}, {m.format(iv.high)}]".rjust(26)
            )
        for k in ranked:
            iv = f.first[k]
            text = f"{iv.value:6.1%} [{iv.low:.1%}, {iv.high:.1%}]" if iv.n else "-"
            cells.append(text.rjust(22))
        for k in ranked[:1]:  # paired, drive by drive, against the lowest mean
            m, iv = METRICS[k], f.versus_best.get(k)
            text = (
                "-"
                if iv is None
                else f"{m.format(iv.value)} [{m.format(iv.low)}, {m.format(iv.high)}]"
            )
            cells.append(text.rjust(26))
        failed = f"  ({f.failed} failed)" if f.failed else ""
        print(f"{f.strategy:<14} " + " ".join(cells) + failed)
