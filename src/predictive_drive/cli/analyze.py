"""``predictive-drive analyze BAG``: vector utilization and the candidate sets it derives."""

from __future__ import annotations

import argparse

from ..api.analyze import analyze
from .common import say_json

HELP = (
    "vector utilization of a recording (paper 001 Tables 1, 3-8) and the candidate sets it derives"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("bag", help="bag directory (or its .mcap file)")
    p.add_argument(
        "--threshold", type=float, help="torque threshold, N·m (default: the recorded scenario's)"
    )
    p.add_argument(
        "--write-tables",
        metavar="PATH",
        help="write the derived candidate tables as JSON (the format of "
        "core/control/candidate_tables.json, which simplified2/simplified3 use)",
    )


def main(a: argparse.Namespace) -> int:
    d = analyze(a.bag, threshold=a.threshold, write_tables=a.write_tables)
    if a.json:
        return say_json(d)
    print(
        f"{d.bag}: {d.scenario} / {d.strategy}, {d.steps} steps over "
        f"{d.window[0]:g}-{d.window[1]:g} s, threshold {d.threshold:g} N·m"
    )
    print("\nZero-vector use by torque-error band (paper 001 Table 1; the paper's from a mptc run)")
    print(f"  {'|dT| <= N·m':>12} {'N':>7} {'N_V0':>7} {'eta_V0':>7}   {'paper N':>8} {'N_V0':>7}")
    for b in d.bands:
        p = b.paper or ("", "")
        band = "all" if b.band is None else f"{b.band:.1f}"
        print(f"  {band:>12} {b.n:>7} {b.n_v0:>7} {100 * b.eta_v0:>6.2f}%   {p[0]:>8} {p[1]:>7}")
    for table, nsec in (("six_sector", 6), ("twelve_sector", 12)):
        for cls, shares in d.utilization[table].items():
            n = d.class_steps[table][cls]
            what = "Tables 3-4" if nsec == 6 else "Tables 5-8"
            print(f"\nUtilization %, {nsec} sectors, {cls} (paper 001 {what}); steps per sector:")
            print("       " + "".join(f"{'th' + str(s + 1):>7}" for s in range(nsec)))
            print("  N    " + "".join(f"{x:>7}" for x in n))
            for v in range(7):
                print(f"  V{v}   " + "".join(f"{100 * shares[s][v]:>7.1f}" for s in range(nsec)))
            sets = d.derived[table][cls]
            print("  sets " + " ".join("{" + ",".join(f"V{v}" for v in c) + "}" for c in sets))
    print(f"\nRule: {d.rule}")
    if d.matches_tables:
        print("Derived sets = the tables simplified2/simplified3 use (all 60 classes).")
    else:
        print(f"Derived sets differ from the tables in use in {len(d.differences)} classes:")
        for line in d.differences:
            print(f"  {line}")
    if d.written is not None:
        print(f"Wrote {d.written}")
    return 0
