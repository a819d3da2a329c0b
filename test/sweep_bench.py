"""Where a sweep runs, measured: `python test/sweep_bench.py [SCENARIO] [DURATION]` runs the grid
strategy (mptc, db_mptc) × lambda_psi (20, 50, 100) × controller-side R_s (×0.8, ×1, ×1.2)
one after another (one process), on the local pool (one process per core), on a Dask
LocalCluster, and on a Dask cluster of a scheduler and two workers started here with the `dask`
command; prints wall time and runs/s of each and whether the tables equal the sequential one
(the measured timings aside). The README's sweep figures come from it."""

from __future__ import annotations

import json
import os
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from predictive_drive.api.sweep import MEASURED, sweep  # noqa: E402
from procs import dask_cluster  # noqa: E402

SETS = ["torque_controller.lambda_psi=20,50,100", "torque_controller.motor.r_s=*0.8,*1,*1.2"]


def same(a, b) -> bool:
    def key(rows):
        return [
            (r.strategy, r.settings, r.error,
             {k: v for k, v in (r.metrics or {}).items() if k not in MEASURED})
            for r in rows
        ]  # fmt: skip

    return json.dumps(key(a), sort_keys=True) == json.dumps(key(b), sort_keys=True)


def main() -> None:
    scenario = sys.argv[1] if len(sys.argv) > 1 else "im_paper"
    duration = float(sys.argv[2]) if len(sys.argv) > 2 else None
    grid = {"strategies": ["mptc", "db_mptc"], "sets": SETS, "duration": duration}
    with tempfile.TemporaryDirectory() as tmp, dask_cluster(Path(tmp)) as address:
        runs = {"one after another": sweep(scenario, jobs=1, **grid)}
        runs["local pool"] = sweep(scenario, **grid)
        from distributed import Client, LocalCluster

        with LocalCluster(n_workers=os.cpu_count(), threads_per_worker=1,
                          dashboard_address=None) as lc, Client(lc):  # fmt: skip
            runs["dask LocalCluster"] = sweep(scenario, scheduler=lc.scheduler_address, **grid)
        runs["dask cluster"] = sweep(scenario, scheduler=address, **grid)
    base = runs["one after another"]
    print(f"{scenario}: {base.cases} runs ({'duration ' + str(duration) if duration else 'full'})")
    for name, r in runs.items():
        print(
            f"  {name:<20} {r.engine:<40} {r.wall_s:7.1f} s  {len(r.rows) / r.wall_s:6.2f} runs/s  "
            f"x{base.wall_s / r.wall_s:.2f}  same table: {same(r.rows, base.rows)}"
        )


if __name__ == "__main__":
    main()
