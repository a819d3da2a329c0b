"""``predictive-drive compare BAG BAG...``: recordings side by side."""

from __future__ import annotations

import argparse

from ..api.compare import compare
from ..core.metrics import METRICS
from .common import say_json

HELP = "recordings side by side: metrics, overlaid figures"
#: the table's rows, by metric (how each is shown: core.metrics.METRICS)
ROWS = (
    "t_rmse", "psi_rmse", "f_ave_hz", "f_sw_hz", "cal_ave", "deadbeat_share", "speed_rmse", "thd",
    "compute_ns_median", "t_ripple_cont", "t_rmse_cont", "i_thd_cont",
)  # fmt: skip


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bags", nargs="+", metavar="BAG", help="bag directories (or .mcap files)")
    p.add_argument("--figures", metavar="DIR", help="draw the overlaid figures (PNG) here")


def main(a: argparse.Namespace) -> int:
    r = compare(a.bags, figures=a.figures)
    if a.json:
        return say_json(r)
    width = max(len(run.label) for run in r.runs) + 2
    print(f"{'':<22}" + "".join(f"{run.label:>{width}}" for run in r.runs))
    for key in ROWS:
        shown = METRICS[key]
        cells = "".join(f"{shown.format(getattr(run.metrics, key)):>{width}}" for run in r.runs)
        print(f"{shown.heading:<22}" + cells)
    if r.unequal_fsw:
        print(f"note: {r.unequal_fsw}")
    for f in r.figures:
        print(f"figure {f}")
    return 0
