"""Sweeps: the grid, its rows against direct runs, the table files, failures and Ctrl-C, and the
same grid on a Dask cluster of a scheduler and two workers started here."""

from __future__ import annotations

import csv
import json
import math
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from predictive_drive.api.report import metrics_of, report
from predictive_drive.api.sweep import MEASURED, Case, Row, grid, parse_set, run_cases, sweep
from predictive_drive.config import apply_settings, load_scenario_text, resolve_scenario_path
from predictive_drive.core.runner import run_inprocess
from predictive_drive.errors import ConfigError
from procs import dask_cluster, descendants, kill_if_running, parents, wait_until

GRID = dict(
    strategies=["mptc", "db_mptc"],
    sets=["torque_controller.lambda_psi=20,50,100", "torque_controller.motor.r_s=*0.9,*1,*1.1"],
    duration=0.02,
)


def same_rows(a, b) -> None:
    """Rows equal bit for bit but the timings measured where they ran."""
    assert len(a) == len(b)
    for x, y in zip(a, b):
        assert (x.strategy, x.settings, x.error) == (y.strategy, y.settings, y.error)
        mx = {
            k: v for k, v in (x.metrics.as_dict() if x.metrics else {}).items() if k not in MEASURED
        }
        my = {
            k: v for k, v in (y.metrics.as_dict() if y.metrics else {}).items() if k not in MEASURED
        }
        assert mx.keys() == my.keys()
        for k in mx:
            assert mx[k] == my[k] or (mx[k] != mx[k] and my[k] != my[k]), k  # NaN == NaN here


@pytest.mark.core
def test_the_grid_is_the_cartesian_product_of_strategies_and_settings():
    sets = [parse_set("a.b=1,2e-3"), parse_set("c.d=*0.7,*1.3,x")]
    assert sets == [("a.b", [1, 0.002]), ("c.d", ["*0.7", "*1.3", "x"])]
    # a list is one value: its commas are inside brackets
    assert parse_set("w=[1.0, 1.45],[0.2,0.5]") == ("w", [[1.0, 1.45], [0.2, 0.5]])
    cases = grid(["s1", "s2"], sets)
    assert len(cases) == 2 * 2 * 3
    assert cases[0] == Case("s1", {"a.b": 1, "c.d": "*0.7"})
    assert cases[-1] == Case("s2", {"a.b": 0.002, "c.d": "x"})
    assert len({(c.strategy, tuple(c.settings.items())) for c in cases}) == 12
    for bad, msg in (("a.b", "expected KEY=V1"), ("a.b=1,,2", "an empty value"),
                     ("a.b=*x", "not \\*<number>")):  # fmt: skip
        with pytest.raises(ConfigError, match=msg):
            parse_set(bad)
    with pytest.raises(ConfigError, match="a key given twice"):
        grid(["s"], [("k", [1]), ("k", [2])])


@pytest.mark.core
def test_a_sweep_row_is_the_run_with_its_settings(tmp_path):
    """Every row equals a direct in-process run of the scenario with the row's settings applied
    (factors of the present value); the CSV and Parquet tables hold the rows; the figures
    are drawn; a value the scenario refuses is that row's error, the others run."""
    r = sweep(
        "im_short",
        strategies=["mptc", "db_mptc"],
        sets=["torque_controller.lambda_psi=20,50", "torque_controller.motor.l_m=*0.95,*-1"],
        duration=0.02,
        out=tmp_path / "t",
        figures=tmp_path / "f",
        jobs=2,
    )
    assert len(r.rows) == r.cases == 8 and not r.interrupted
    bad = [row for row in r.rows if row.error]
    assert len(bad) == 4 and all(
        row.settings["torque_controller.motor.l_m"] == "*-1" for row in bad
    )
    assert "/drive/torque_controller.motor: l_m must be a finite number > 0" in bad[0].error
    assert "with torque_controller.lambda_psi=" in bad[0].error  # names the case
    path = resolve_scenario_path("im_short")
    for row in r.rows:
        if row.error:
            continue
        text = apply_settings(path.read_text(), row.settings, path)
        sc = load_scenario_text(text, path).with_strategy(row.strategy).with_duration(0.02)
        assert sc.controller.motor.l_m == pytest.approx(0.2751 * 0.95)
        m = metrics_of(run_inprocess(sc), sc)
        same_rows([row], [type(row)(row.strategy, row.settings, m)])
    with open(tmp_path / "t" / "sweep.csv") as f:
        lines = list(csv.DictReader(f))
    assert [ln["strategy"] for ln in lines] == [row.strategy for row in r.rows]
    for ln, row in zip(lines, r.rows):
        if row.error:
            assert ln["error"] == row.error and ln["t_rmse"] == "nan"
        else:
            assert float(ln["t_rmse"]) == row.metrics.t_rmse  # written exactly (repr)
    import pyarrow.parquet as pq

    t = pq.read_table(tmp_path / "t" / "sweep.parquet").to_pydict()
    assert t["torque_controller.lambda_psi"] == [20.0, 20.0, 50.0, 50.0] * 2
    assert t["torque_controller.motor.l_m"] == ["*0.95", "*-1"] * 4
    assert [x for x in t["f_ave_hz"] if not math.isnan(x)] == [
        row.metrics.f_ave_hz for row in r.rows if not row.error
    ]
    assert sorted(p.name for p in (tmp_path / "f").iterdir()) == [
        "sweep_torque_controller_lambda_psi.png",
        "sweep_torque_controller_motor_l_m.png",
    ]


@pytest.mark.core
def test_a_key_the_scenario_lacks_fails_before_anything_runs(tmp_path):
    with pytest.raises(ConfigError, match="has no group 'motr'"):
        sweep("im_short", sets=["torque_controller.motr.l_m=*1"], out=tmp_path / "t")
    with pytest.raises(ConfigError, match="not a strategy of mptc_im; valid: mptc, mptc_db"):
        sweep("im_short", strategies=["dtc"])
    assert not (tmp_path / "t").exists()


@pytest.mark.core
@pytest.mark.parametrize("jobs", [0, -2])
def test_jobs_below_one_is_refused(jobs):
    """(was: -2 ran silently on one process)"""
    with pytest.raises(ConfigError, match=rf"--jobs {jobs}: the number of local processes must "
                       r"be at least 1"):  # fmt: skip
        sweep("im_short", jobs=jobs, duration=0.01)


@pytest.mark.core
def test_ctrl_c_during_a_recorded_sweep_closes_the_cut_bags_and_says_so(tmp_path):
    """Interrupted while recorded runs are in flight (here right after the first, short, row):
    the runs in flight stop and close their bags, each readable with the steps it holds, and
    the result says which bags were cut (was: their workers killed, the files left without an
    index, unmentioned)."""
    from predictive_drive.bag import check_new_bag
    from predictive_drive.readback import bag_status

    def progress(done, total):  # once a long run is in flight (its bag begun)
        wait_until(lambda: any(b.exists() for b in bags[1:]), "no long run began", timeout=60)
        raise KeyboardInterrupt

    bags = [tmp_path / "bags" / f"{i}" for i in range(4)]
    cases = [Case("db_mptc", bag=str(check_new_bag(bags[0])), duration=0.01)] + [
        Case("db_mptc", {"torque_controller.lambda_psi": v}, bag=str(check_new_bag(b)),
             duration=60.0)
        for v, b in zip((10, 20, 30), bags[1:])
    ]  # fmt: skip
    before = set(descendants(os.getpid()))
    r = run_cases("im_short", cases, jobs=2, progress=progress)
    assert r.interrupted and [row.bag for row in r.rows] == [str(bags[0])]
    assert workers_left(before) == []
    assert r.cut, "a long run began: its bag is said to be cut"
    for b in bags[1:]:  # each closed with what it holds and said to be, or never begun
        if b.exists():
            status = bag_status(b)
            assert status.closed and 0 < status.steps < 1_200_000, status
            assert f"{b}: cut at {status.steps} of 1200000 steps, closed (readable)" in r.cut
        else:  # not begun, or begun and stopped before its first whole step
            assert f"{b}: removed (no whole step)" in r.cut or not any(str(b) in c for c in r.cut)


@pytest.mark.core
def test_a_stop_waits_for_a_worker_still_starting(tmp_path):
    """Ctrl-C while a local worker is still starting (its SIGTERM handler not yet in): it is told
    to stop once the handler is in, so its case closes its bag or never begins (was: SIGTERM at
    once killed it, the pool broke, and a CI run under load ended a sibling worker outright
    while it closed its bag)."""
    from predictive_drive.api.sweep import INTERRUPTED, NOT_RUN, _LocalPool, _stop_local, run_case
    from predictive_drive.readback import bag_status

    path = resolve_scenario_path("im_short")
    bag = tmp_path / "bag"
    case = Case("db_mptc", bag=str(bag), duration=60.0)
    pool = _LocalPool(1)
    before = set(descendants(os.getpid()))
    fut = pool.submit(run_case, path.read_text(), str(path), case)
    done: dict[int, Row] = {}
    _stop_local(pool, {fut: 0}, done, [case], [0])  # at once: the worker is still importing
    assert workers_left(before) == []
    assert done[0].error in (INTERRUPTED, NOT_RUN), done[0].error
    if bag.exists():  # closed with what it holds, or stopped in its opening: no whole step,
        status = bag_status(bag)  # which the sweep removes (_settle: 'no whole step')
        assert status.closed or not status.readable, status


@pytest.mark.core
def test_after_ctrl_c_a_complete_bag_is_a_row_and_an_unclosed_one_is_removed(tmp_path):
    """What the sweep makes of the bags of the runs whose rows it did not get: a bag holding the
    whole run is its row (the run ended as Ctrl-C came); one its writer could not close is
    removed, and said to be."""
    from predictive_drive.api.run import run_inprocess_to_bag
    from predictive_drive.api.sweep import INTERRUPTED, _settle
    from predictive_drive.config import load_scenario

    whole, killed = tmp_path / "whole", tmp_path / "killed"
    sc = load_scenario("im_short", strategy="db_mptc", duration=0.02)
    for b in (whole, killed):
        run_inprocess_to_bag(sc, b)
    (f,) = killed.glob("*.mcap")
    f.write_bytes(f.read_bytes()[:-2000])  # no summary, no footer: as a killed writer leaves it
    cases = [Case("db_mptc", bag=str(whole)), Case("db_mptc", bag=str(killed))]
    rows, cut = _settle({1: Row("db_mptc", {}, error=INTERRUPTED, bag=str(killed))}, cases)
    assert [row.bag for row in rows] == [str(whole)] and rows[0].metrics.steps > 0
    assert cut == [f"{killed}: removed (its writer was ended outright)"]
    assert not killed.exists() and whole.exists()


@pytest.mark.core
def test_ctrl_c_keeps_the_finished_rows_and_leaves_no_worker(tmp_path):
    """Ctrl-C (a KeyboardInterrupt in the sweep's loop, here right after the third row) stops
    the workers; the rows finished so far are kept, each a complete run."""
    seen = []

    def progress(done, total):
        seen.append(done)
        if done == 3:
            raise KeyboardInterrupt

    cases = grid(["mptc", "db_mptc"], [parse_set("torque_controller.lambda_psi=10,20,30,40,50,60")])
    before = set(descendants(os.getpid()))
    r = run_cases("im_short", cases, duration=0.05, jobs=2, progress=progress)
    assert r.interrupted and 3 <= len(r.rows) < 12 and seen[-1] == 3
    assert all(row.metrics and row.metrics.steps > 0 and not row.error for row in r.rows)
    assert workers_left(before) == []


def workers_left(before: set[int]) -> list[int]:
    """Processes this one started since ``before`` that are not multiprocessing's helpers: the
    forkserver the pool forks its workers from and the resource tracker stay for the life of
    the process that started them, as our children; a pool worker is the forkserver's child
    (and carries its command line), so it shows here. Waits up to 10 s for them to go."""
    helpers = (b"multiprocessing.forkserver", b"multiprocessing.resource_tracker")

    def left() -> list[int]:
        parent = parents()
        out = []
        for pid in set(descendants(os.getpid())) - before:
            try:
                cmdline = Path(f"/proc/{pid}/cmdline").read_bytes()
            except OSError:
                continue  # gone meanwhile
            if parent.get(pid) != os.getpid() or not any(h in cmdline for h in helpers):
                out.append(pid)
        return out

    deadline = time.monotonic() + 10
    while (found := left()) and time.monotonic() < deadline:
        time.sleep(0.05)
    return found


@pytest.mark.process
def test_the_same_grid_on_a_dask_cluster_gives_the_same_table(tmp_path):
    """A scheduler and two workers (one process, one thread each) on localhost, as a user starts
    them with the `dask` command; the grid run there equals the local one row for row."""
    pytest.importorskip("distributed")
    with dask_cluster(tmp_path) as address:
        remote = sweep("im_short", scheduler=address, **GRID)
    local = sweep("im_short", **GRID)
    assert remote.engine == f"dask ({address}, 2 workers)" and local.engine.startswith("local")
    assert len(remote.rows) == 18 and not any(row.error for row in remote.rows)
    same_rows(remote.rows, local.rows)
    assert np.isfinite([row.metrics.t_rmse for row in remote.rows]).all()


@pytest.mark.core
def test_ctrl_c_does_not_wait_for_the_runs_in_flight():
    """Stopped while long runs are in flight, the sweep ends them rather than waiting for them:
    each would take minutes on any machine (300 s of simulated time, 6 million steps); the sweep
    returns within seconds, and their workers are gone."""
    stopped = []

    def progress(done, total):
        stopped.append(time.perf_counter())
        raise KeyboardInterrupt

    # the first case is short: its row comes while the others run
    cases = [Case("db_mptc", duration=0.01)] + [
        Case("db_mptc", {"torque_controller.lambda_psi": v}, duration=300.0) for v in (10, 20, 30)
    ]
    before = set(descendants(os.getpid()))
    r = run_cases("im_short", cases, jobs=2, progress=progress)
    took = time.perf_counter() - stopped[0]
    assert r.interrupted and len(r.rows) == 1
    assert took < 30.0, f"the sweep waited {took:.1f} s for the runs in flight"
    assert workers_left(before) == []


CLI = [sys.executable, "-m", "predictive_drive.cli"]


@pytest.mark.core
def test_sweep_record_json_on_the_command_line(tmp_path):
    """`sweep ... --out DIR --record --json`: one JSON object with every row; each row's bag in
    DIR/bags/ reports the row's own metrics; the CSV holds the rows."""
    out = tmp_path / "t"
    r = subprocess.run(
        [*CLI, "sweep", "im_short", "--strategy", "mptc,db_mptc", "--set",
         "torque_controller.lambda_psi=10,30", "--duration", "0.02", "--jobs", "2",
         "--out", str(out), "--record", "--json"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert len(d["rows"]) == 4 and not any(row["error"] for row in d["rows"])
    bags = sorted((out / "bags").iterdir())
    assert len(bags) == 4
    for row in d["rows"]:
        bag = Path(row["bag"])
        assert bag in bags
        assert report(bag).metrics.t_rmse == row["metrics"]["t_rmse"]
    with (out / "sweep.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 4


@pytest.mark.core
@pytest.mark.parametrize("presses", [1, 2], ids=["ctrl-c", "ctrl-c twice"])
def test_ctrl_c_on_the_command_line_exits_130_with_the_rows_written(tmp_path, presses):
    """Ctrl-C once a row is done (with one process the runs go one after the other: the second
    run's bag appearing means the first is complete): exit 130, the table written with the
    finished rows, the table printed saying they are kept. Twice in a row: the same, the run in
    flight ended outright and its bag said to be cut or removed (was: 'error: interrupted'
    alone, no table, no sweep.csv)."""
    out = tmp_path / "t"
    p = subprocess.Popen(
        [*CLI, "sweep", "im_short", "--set", "torque_controller.lambda_psi=10,20,30,40,50,60",
         "--duration", "0.5", "--jobs", "1", "--out", str(out), "--record"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        wait_until(
            lambda: (out / "bags").exists() and len(list((out / "bags").iterdir())) >= 2,
            "no run finished",
            proc=p,
        )
        for _ in range(presses):
            p.send_signal(signal.SIGINT)
            time.sleep(0.02)
        stdout, stderr = p.communicate(timeout=60)
    finally:
        kill_if_running(p)
    assert p.returncode == 130, stderr
    assert "Traceback" not in stderr
    assert "of 6 runs" in stdout and "interrupted: the rows above are kept" in stdout
    assert "not complete: " in stdout  # the run in flight: its bag cut (closed) or removed
    with (out / "sweep.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert 1 <= len(rows) < 6 and all(row["error"] == "" for row in rows)
    # each a whole run: its metrics window, 0.05-0.4 s of the 0.5 s (7,000 steps)
    assert all(float(row["steps"]) == 7000 for row in rows), rows


def test_a_horizon_is_checked_against_the_strategy_that_runs(tmp_path):
    """--strategy applies before the controller's keys are checked: im_short's file runs
    db_mptc, and `run --strategy mptc --set torque_controller.horizon=2` runs mptc at N = 2
    (was: refused, 'db_mptc looks one period ahead'); its recording reads back. In a sweep each
    row is checked with its own strategy: mptc at N = 3 runs, db_mptc at N = 3 is an error row
    that says why."""
    from predictive_drive.api.run import run
    from predictive_drive.readback import read_bag

    r = run("im_short", strategy="mptc", settings={"torque_controller.horizon": 2},
            engine="inprocess", duration=0.005, out=tmp_path / "b")  # fmt: skip
    assert r.strategy == "mptc" and r.steps == 100
    assert read_bag(tmp_path / "b")[0].col("command", "horizon")[-1] == 2
    rows = sweep("im_short", strategies=["mptc", "db_mptc"],
                 sets=["torque_controller.horizon=1,3"], duration=0.005, jobs=1).rows  # fmt: skip
    errors = {(row.strategy, row.settings["torque_controller.horizon"]): row.error for row in rows}
    assert errors[("mptc", 3)] is None and errors[("db_mptc", 1)] is None
    assert "db_mptc looks one period ahead" in errors[("db_mptc", 3)]


def _numbers_of(path: Path, text_columns: set[str]) -> list[dict[str, float]]:
    """The CSV's rows, every column but ``text_columns`` read as a plain number (refused if a
    cell is anything else, a numpy repr such as np.float64(0.03) included)."""
    with open(path) as f:
        lines = list(csv.DictReader(f))
    return [{k: float(v) for k, v in ln.items() if k not in text_columns} for ln in lines]


@pytest.mark.core
def test_every_number_column_of_the_csv_holds_plain_numbers(tmp_path):
    """A deadbeat law's deadbeat share (a numpy scalar once: the CSV read np.float64(0.031))
    and every other metric are written as numbers a CSV reader parses."""
    r = sweep("im_short", strategies=["mptc", "db_mptc"], duration=0.05, out=tmp_path / "t.csv",
              jobs=1)  # fmt: skip
    rows = _numbers_of(tmp_path / "t.csv", {"strategy", "error"})
    assert len(rows) == 2 and rows[1]["deadbeat_share"] > 0.0
    for ln, row in zip(rows, r.rows):
        assert ln["deadbeat_share"] == row.metrics.deadbeat_share
    for k, v in r.rows[1].metrics.as_dict().items():  # the cause: metrics are plain numbers
        assert type(v) in (int, float, str, list, dict), (k, type(v))


@pytest.mark.core
def test_a_sweep_whose_runs_book_losses_shows_and_writes_the_loss_columns(tmp_path, capsys):
    """With a device file the printed table adds P_inverter, eta and T_j max and the CSV every
    loss metric, each the run's own metric; without losses the table is as it was."""
    from predictive_drive.cli.sweep import print_sweep
    from predictive_drive.core.metrics import LOSS_METRICS

    device = "plant.losses.device=semikron_skm150gb124d"
    r = sweep("im_short", strategies=["db_mptc"], sets=[device], duration=0.02,
              out=tmp_path / "t.csv", jobs=1)  # fmt: skip
    (ln,) = _numbers_of(tmp_path / "t.csv", {"strategy", "error", "tj_max_device",
                                             "plant.losses.device"})  # fmt: skip
    m = r.rows[0].metrics
    assert m.p_inverter > 0.0 and m.tj_max > 25.0 and m.tj_max_device
    for k in LOSS_METRICS:
        if k != "tj_max_device":
            assert ln[k] == getattr(m, k) or (math.isnan(ln[k]) and math.isnan(getattr(m, k))), k
    with open(tmp_path / "t.csv") as f:
        assert next(csv.DictReader(f))["tj_max_device"] == m.tj_max_device
    print_sweep(r)
    head, units, line = capsys.readouterr().out.splitlines()[:3]
    assert head.split()[-4:] == ["P_inverter", "eta", "T_j", "max"]
    assert units.split()[-3:] == ["W", "%", "°C"]
    assert line.split()[-3] == f"{m.p_inverter:.3g}" and line.split()[-1] == f"{m.tj_max:.1f}"

    plain = sweep("im_short", strategies=["db_mptc"], duration=0.02, out=tmp_path / "p.csv",
                  jobs=1)  # fmt: skip
    with open(tmp_path / "p.csv") as f:
        assert not set(LOSS_METRICS) & set(next(csv.reader(f)))
    print_sweep(plain)
    assert "P_inverter" not in capsys.readouterr().out
