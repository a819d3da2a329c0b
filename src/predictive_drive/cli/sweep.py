"""``predictive-drive sweep SCENARIO``: a grid of in-process runs, as one table."""

from __future__ import annotations

import argparse

from ..api.sweep import SweepResult, sweep
from ..core.metrics import METRICS
from .common import refuse, runs_progress, say_json, scenario_argument, seconds

HELP = (
    "a grid of in-process runs (strategies x settings) on the local cores or a Dask cluster, "
    "as one table"
)
#: the table's metric columns (how each is shown: core.metrics.METRICS)
COLUMNS = ("t_rmse", "psi_rmse", "f_ave_hz", "f_sw_hz", "thd")


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


def main(a: argparse.Namespace) -> int:
    if a.scheduler:
        refuse(a, "sets the local processes; with --scheduler the cluster's workers run", "jobs")
    update, close = runs_progress(f"sweep {a.scenario}", quiet=a.json)
    try:
        r = sweep(
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
        say_json(r)
    else:
        print_sweep(r)
    return 130 if r.interrupted else 0


def print_sweep(r: SweepResult) -> None:
    keys = list(dict.fromkeys(k for row in r.rows for k in row.settings))
    widths = [
        max(6, len(k.rsplit(".", 1)[-1]), *(len(str(row.settings.get(k))) for row in r.rows))
        for k in keys
    ]
    head = " ".join(f"{k.rsplit('.', 1)[-1]:>{w}}" for k, w in zip(keys, widths))
    shown = [METRICS[c] for c in COLUMNS]
    print(f"{'strategy':<14} {head} " + " ".join(f"{m.title:>9}" for m in shown))
    print(f"{'':<14} {' ' * len(head)} " + " ".join(f"{m.unit:>9}" for m in shown))
    for row in r.rows:
        values = " ".join(f"{str(row.settings.get(k)):>{w}}" for k, w in zip(keys, widths))
        if row.error or row.metrics is None:
            print(f"{row.strategy:<14} {values} error: {row.error}")
            continue
        cells = " ".join(f"{m.format(getattr(row.metrics, c)):>9}" for m, c in zip(shown, COLUMNS))
        print(f"{row.strategy:<14} {values} {cells}")
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
