"""``predictive-drive sweep``: a grid of in-process runs (strategies × scenario settings), on the
local cores or a Dask cluster, as one table.

A case is a strategy and a set of settings (``apply_settings`` keys: dotted, ``*f`` for a factor
of the present value). Every case runs the in-process engine on the scenario text with its
settings applied, in a worker: a process of the local pool, or a Dask worker (``--scheduler``);
the worker gets the scenario *text*, so a remote machine needs the package but not the scenario
files. Its row (strategy, settings, every metric, or the error) does not depend on where it ran
(bit for bit, the measured timings aside: see :data:`MEASURED`). A failed case is a row with its
error; Ctrl-C (or SIGTERM) keeps the rows finished so far: the runs in flight on the local cores
are told to stop (a recorded one closes its bag, readable), and :attr:`SweepResult.cut` says what
became of the bags of the runs that did not finish.
"""

from __future__ import annotations

import concurrent.futures as cf
import csv
import dataclasses
import itertools
import json
import math
import multiprocessing
import os
import shutil
import signal
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager, suppress
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from .. import interrupts
from ..config import apply_settings, load_scenario_text, resolve_scenario_path
from ..core.control import strategy_names
from ..core.metrics import LOSS_METRICS, Metrics, books_losses
from ..core.runner import run_inprocess
from ..core.scenario import Scenario
from ..core.trace import Trace
from ..dependencies import missing
from ..errors import ConfigError, PredictiveDriveError
from ..outputs import check_output_dir
from .report import metrics_of

__all__ = [
    "MEASURED",
    "Case",
    "Row",
    "SweepResult",
    "grid",
    "parse_set",
    "run_cases",
    "sweep",
    "write_table",
]

#: row fields measured on the machine that ran the case (they differ from run to run)
MEASURED = ("compute_ns_mean", "compute_ns_median", "compute_ns_median_by_strategy", "wall_s")
#: a function of a finished run, run in the worker: more for its row (``extra``)
Analysis = Callable[[Trace, Scenario], dict[str, Any]]


@dataclass(frozen=True)
class Case:
    strategy: str
    settings: dict[str, Any] = field(default_factory=dict)
    bag: str | None = None  #: record the run to this bag directory (None: no recording)
    duration: float | None = None  #: s of simulated time (None: the sweep's, or the scenario's)
    #: the drawn drive it runs on (:class:`~.draws.Draw` as a dict; its values are in
    #: ``settings``), recorded in its bag's metadata
    draw: dict[str, Any] | None = None


@dataclass
class Row:
    """One case's outcome: its strategy and settings, and its metrics or its error."""

    strategy: str
    settings: dict[str, Any]
    metrics: Metrics | None = None
    error: str | None = None
    wall_s: float = math.nan
    bag: str | None = None
    extra: dict[str, Any] = field(default_factory=dict)
    draw: dict[str, Any] | None = None  #: the drawn drive (see :attr:`Case.draw`)

    def as_dict(self) -> dict[str, Any]:
        out = {
            "strategy": self.strategy,
            "settings": self.settings,
            "metrics": None if self.metrics is None else self.metrics.as_dict(),
            "error": self.error,
            "wall_s": self.wall_s,
        }
        if self.bag is not None:
            out["bag"] = self.bag
        if self.draw is not None:
            out["draw"] = self.draw
        out.update(self.extra)
        return out


@dataclass
class SweepResult:
    scenario: str
    rows: list[Row]  #: in case order; those not run (interrupted) are missing
    cases: int
    engine: str  #: "local (N processes)" or "dask (ADDRESS, N workers)"
    wall_s: float
    interrupted: bool = False
    files: list[str] = field(default_factory=list)
    figures: list[str] = field(default_factory=list)
    #: interrupted with ``--record``: what became of each bag of a run that did not finish (closed
    #: readable with the steps it holds, or removed); a run whose bag is complete is a row
    cut: list[str] = field(default_factory=list)
    #: with drawn drives (``--draw N``): each strategy's figures over them
    #: (:class:`~.draws.StrategyFigures`), the spreads and the seed
    drawn: list[Any] = field(default_factory=list)
    spreads: list[str] = field(default_factory=list)
    seed: int | None = None

    def as_dict(self) -> dict[str, Any]:
        return {
            "scenario": self.scenario,
            "cases": self.cases,
            "engine": self.engine,
            "wall_s": self.wall_s,
            "interrupted": self.interrupted,
            "rows": [r.as_dict() for r in self.rows],
            "cut": self.cut,
            "files": self.files,
            "figures": self.figures,
            **(
                {"spreads": self.spreads, "seed": self.seed,
                 "drawn": [d.as_dict() for d in self.drawn]}
                if self.spreads else {}
            ),
        }  # fmt: skip


def _split_values(values: str) -> list[str]:
    """``V1,V2,…`` split at the commas outside brackets: a list value (``[0.8,1.4]``) is one."""
    out, depth, start = [], 0, 0
    for i, ch in enumerate(values):
        depth += (ch == "[") - (ch == "]")
        if ch == "," and depth == 0:
            out.append(values[start:i])
            start = i + 1
    return [*out, values[start:]]


def parse_set(text: str) -> tuple[str, list[Any]]:
    """``KEY=V1,V2,…`` → (key, values); values read as a parameter file reads them (``5e-5``
    is a number, ``[0.8,1.4]`` a list), ``*f`` kept as a factor. ConfigError names what is
    wrong."""
    key, sep, values = text.partition("=")
    if not sep or not key.strip() or not values.strip():
        raise ConfigError(
            f"--set {text!r}: expected KEY=V1,V2,... (e.g. torque_controller.lambda_psi=0,50)"
        )
    out: list[Any] = []
    for v in _split_values(values):
        v = v.strip()
        if not v:
            raise ConfigError(f"--set {text!r}: an empty value")
        if v.startswith("*"):
            try:
                float(v[1:])
            except ValueError:
                raise ConfigError(f"--set {text!r}: {v!r} is not *<number>") from None
            out.append(v)
        else:
            from ..config import parse_yaml

            out.append(parse_yaml(v, f"--set {key}"))
    return key.strip(), out


def grid(strategies: Sequence[str], sets: Sequence[tuple[str, Sequence[Any]]]) -> list[Case]:
    """The cartesian product: every strategy with every combination of the settings' values."""
    keys = [k for k, _ in sets]
    if len(set(keys)) != len(keys):
        raise ConfigError(f"--set: a key given twice ({', '.join(keys)})")
    combos = itertools.product(*(values for _, values in sets))
    settings = [dict(zip(keys, combo)) for combo in combos]
    return [Case(s, dict(st)) for s in strategies for st in settings]


def _case_text(text: str, source: Path, case: Case) -> str:
    """The scenario text with the case's settings applied (checked by the caller)."""
    return apply_settings(text, case.settings, source) if case.settings else text


def run_case(
    text: str,
    where: str,
    case: Case,
    duration: float | None = None,
    analysis: Analysis | None = None,
) -> Row:
    """One case, start to end, in whichever process runs it: the scenario text with its
    settings, run in-process (recorded when the case names a bag), its metrics and ``analysis``.
    Never raises for the case's own failure: that is the row's error."""
    global _in_case
    t0 = time.perf_counter()
    row = Row(case.strategy, dict(case.settings), bag=case.bag, draw=case.draw)
    # in a case before the look at _stopping: a stop that comes between the two interrupts the
    # case (was: it came after the look and before this flag, and the case ran on, 60 s, until
    # the sweep ended its worker outright and removed its bag)
    _in_case = True
    try:
        if _stopping:  # the sweep was interrupted before this case began: it never runs
            row.error = NOT_RUN
            return row
        sc = load_scenario_text(text, where, strategy=case.strategy)
        if case.draw is not None:
            sc = dataclasses.replace(sc, draw=json.dumps(case.draw))
        if case.duration is not None or duration is not None:
            sc = sc.with_duration(case.duration if case.duration is not None else duration)
        if case.bag is not None:
            from .report import evaluate
            from .run import run_inprocess_to_bag

            run_inprocess_to_bag(sc, Path(case.bag))
            ev = evaluate(case.bag)
            trace, metrics = ev.trace, ev.metrics
        else:
            trace = run_inprocess(sc)
            metrics = metrics_of(trace, sc)
        row.metrics = metrics
        if analysis is not None:
            row.extra = analysis(trace, sc)
    except (PredictiveDriveError, ArithmeticError, ValueError) as e:
        row.error = f"{type(e).__name__}: {e}"
    except KeyboardInterrupt:  # told to stop (see _stop_case): a recorded run closed its bag
        row.error = INTERRUPTED
    finally:
        _in_case = False
    row.wall_s = time.perf_counter() - t0
    return row


#: a row's error when the sweep stopped its run midway, when it stopped before the run began,
#: and (its start) when the worker running it ended before it did
INTERRUPTED, NOT_RUN = "interrupted", "not run: the sweep was interrupted"
WORKER_ENDED = "its worker ended"
#: a local worker: it runs a case now, and the sweep has told it to stop (see _stop_case)
_in_case = _stopping = False
#: s the sweep waits, once interrupted, for the runs in flight to stop and close their bags
STOP_WAIT = 10.0


def _stop_case(signum: int, frame: object) -> None:
    """A local worker's SIGTERM: the sweep was interrupted. The case in progress stops where
    it is (its bag closes with what it holds; see :func:`interrupts.interrupt`), and no case
    starts after it."""
    global _stopping
    _stopping = True
    if _in_case:
        interrupts.interrupt(signum, frame)


def _quiet_worker(ready: Any) -> None:
    """A local worker leaves Ctrl-C to the sweep, which keeps what is done and stops it (by
    SIGTERM: :func:`_stop_case`); it says when that handler is in (its PID into ``ready``)."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _stop_case)
    ready.put(os.getpid())


class _LocalPool(cf.ProcessPoolExecutor):
    """The local cores' processes; ``ready`` holds the PIDs of those whose SIGTERM handler is in
    (see :func:`_stop_local`)."""

    def __init__(self, workers: int) -> None:
        # forkserver, not fork: the calling process may hold threads (rclpy, a live view, a
        # Dask client) whose locks a forked child would inherit held
        ctx = multiprocessing.get_context("forkserver")
        self.ready = ctx.SimpleQueue()
        super().__init__(workers, mp_context=ctx, initializer=_quiet_worker, initargs=(self.ready,))


@contextmanager
def _executor(scheduler: str | None, jobs: int | None, cases: int) -> Iterator[tuple[Any, str]]:
    """The pool the cases go to, as a concurrent.futures executor: the local cores' processes,
    or a Dask cluster's workers."""
    if scheduler is None:
        if jobs is not None and jobs < 1:
            raise ConfigError(f"--jobs {jobs}: the number of local processes must be at least 1")
        workers = max(1, min(cases, jobs or os.cpu_count() or 1))
        pool = _LocalPool(workers)
        try:
            yield pool, f"local ({workers} process{'es' if workers > 1 else ''})"
        finally:
            pool.shutdown(wait=True, cancel_futures=True)
        return
    try:
        from distributed import Client
    except ImportError:
        raise missing("distributed", "--scheduler") from None
    try:
        client = Client(scheduler, timeout=10)
    except (OSError, TimeoutError) as e:
        raise ConfigError(
            f"--scheduler {scheduler}: no Dask scheduler answers there ({e})"
        ) from None
    try:
        n = len(client.scheduler_info().get("workers", {}))
        if n == 0:
            raise ConfigError(f"--scheduler {scheduler}: the cluster has no workers")
        yield client.get_executor(pure=False), f"dask ({scheduler}, {n} workers)"
    finally:
        client.close()


def run_cases(
    scenario: str | Path,
    cases: Sequence[Case],
    *,
    duration: float | None = None,
    scheduler: str | None = None,
    jobs: int | None = None,
    analysis: Analysis | None = None,
    progress: Callable[[int, int], None] | None = None,
    finished: Callable[[int], None] | None = None,
) -> SweepResult:
    """Run ``cases`` of ``scenario`` on the local cores or the Dask cluster at ``scheduler``.
    Settings are applied and checked here first: a key the scenario lacks fails the sweep
    before anything runs; a value the scenario refuses is that case's error row.
    ``finished(i)``: told which case (its index) ended, before ``progress``."""
    path = resolve_scenario_path(scenario)
    text = path.read_text(encoding="utf-8")
    where = str(path)
    base = load_scenario_text(text, where)
    names = strategy_names(base.family)
    for c in cases:
        if c.strategy not in names:
            raise ConfigError(
                f"--strategy {c.strategy}: not a strategy of {base.family}; valid: {', '.join(names)}"
            )
    made: dict[str, str] = {}  # drawn drives: one text per drive, whatever the strategy
    texts = [
        made.get(key) or made.setdefault(key, _case_text(text, path, c))  # ConfigError: unknown key
        for c in cases
        for key in (repr(c.settings),)
    ]
    t0 = time.perf_counter()
    done: dict[int, Row] = {}
    interrupted = False
    with _executor(scheduler, jobs, len(cases)) as (pool, engine):
        futures = {
            pool.submit(run_case, t, _where(where, c), c, duration, analysis): i
            for i, (t, c) in enumerate(zip(texts, cases))
        }
        try:
            for fut in cf.as_completed(futures):
                done[futures[fut]] = _row_of(fut, cases[futures[fut]])
                if finished is not None:
                    finished(futures[fut])
                if progress is not None:
                    progress(len(done), len(cases))
        except KeyboardInterrupt:
            interrupted = True
            # from here a Ctrl-C is counted, never raised: a second one ends the runs in flight
            # outright, and the summary (rows, table, cut bags) still comes
            with interrupts.counting() as presses:
                for fut in futures:
                    fut.cancel()
                if isinstance(pool, _LocalPool):
                    running = {f: i for f, i in futures.items() if i not in done}
                    _stop_local(pool, running, done, cases, presses)
    if interrupted:
        with interrupts.counting():
            rows, cut = _settle(done, cases)
    else:
        rows, cut = [done[i] for i in sorted(done)], []
    return SweepResult(
        path.stem, rows, len(cases), engine, time.perf_counter() - t0, interrupted, cut=cut
    )


def _row_of(fut: cf.Future[Row], case: Case) -> Row:
    """A finished case's row (a worker that died is the row's error, not the case's)."""
    try:
        return fut.result()
    except Exception as e:  # noqa: BLE001 — the worker died, not the case
        error = f"{WORKER_ENDED}: {type(e).__name__}: {e}"
        return Row(case.strategy, dict(case.settings), error=error, bag=case.bag, draw=case.draw)


def _where(path: str, case: Case) -> str:
    """How errors name a case's scenario: the file and the settings applied to it."""
    if not case.settings:
        return path
    return f"{path} with " + ", ".join(f"{k}={v}" for k, v in case.settings.items())


def _stop_local(
    pool: _LocalPool,
    running: dict[cf.Future[Row], int],
    done: dict[int, Row],
    cases: Sequence[Case],
    presses: list[int],
) -> None:
    """Stop the local workers: each is told to (SIGTERM, see :func:`_stop_case`) once its
    handler is in, so the runs in flight end where they are and close their bags, and ``done``
    takes their rows; those still running after :data:`STOP_WAIT` s (or once ``presses``
    counts another Ctrl-C) are ended outright. (A worker still starting died of a SIGTERM sent
    at once, and the broken pool ended the wait for the others: one was killed while it closed
    its bag.)"""
    deadline = time.monotonic() + STOP_WAIT
    ready: set[int] = set()
    told: set[int] = set()
    left = dict(running)
    while left and time.monotonic() < deadline and not presses[0]:
        while not pool.ready.empty():
            ready.add(pool.ready.get())
        for p in _workers(pool):
            if p.pid in ready and p.pid not in told:
                told.add(p.pid)
                with suppress(ProcessLookupError):
                    os.kill(p.pid, signal.SIGTERM)
        finished, _ = cf.wait(left, timeout=0.05)
        for fut in finished:
            i = left.pop(fut)
            if not fut.cancelled():
                done[i] = _row_of(fut, cases[i])
    # the rest are ended outright: their bags are seen to in _settle
    for p in _workers(pool):
        p.kill()
    pool.shutdown(wait=True, cancel_futures=True)


def _workers(pool: _LocalPool) -> list[Any]:
    """The pool's worker processes still alive."""
    return [p for p in getattr(pool, "_processes", {}).values() if p.is_alive()]


def _settle(done: dict[int, Row], cases: Sequence[Case]) -> tuple[list[Row], list[str]]:
    """After an interrupt: the rows of the runs that finished, and what became of the bag of
    each recorded run that did not. A bag that holds the whole run is that run's row (its run
    ended as the interrupt came); one cut short and closed is kept, readable; one its writer
    could not close (its worker was ended outright) is removed, as is one without a step."""
    from ..readback import bag_status

    rows: list[Row] = []
    cut: list[str] = []
    for i, case in enumerate(cases):
        row = done.get(i)
        if row is not None and not _unfinished(row):
            rows.append(row)
            continue
        if case.bag is None or not Path(case.bag).exists():
            continue
        status = bag_status(case.bag)
        planned = _planned_steps(case.bag) if status.closed else None
        if status.closed and status.steps == planned:
            from .report import evaluate

            ev = evaluate(case.bag)
            rows.append(
                Row(case.strategy, dict(case.settings), ev.metrics, bag=case.bag, draw=case.draw)
            )
        elif status.closed:
            cut.append(f"{case.bag}: cut at {status.steps} of {planned} steps, closed (readable)")
        else:
            shutil.rmtree(case.bag, ignore_errors=True)
            why = "no whole step" if not status.readable else "its writer was ended outright"
            cut.append(f"{case.bag}: removed ({why})")
    return rows, cut


def _unfinished(row: Row) -> bool:
    """The row's run was stopped, never began, or its worker ended under it."""
    return row.error in (INTERRUPTED, NOT_RUN) or (row.error or "").startswith(WORKER_ENDED)


def _planned_steps(bag: str) -> int:
    """The steps a recorded run was to have, from its stored scenario."""
    from ..readback import read_bag
    from ..recording import scenario_of

    info = read_bag(bag)[1]
    return scenario_of(info.info, info.path).run.steps


# --- the table -------------------------------------------------------------------------------

#: metrics in the table, in order (utilization is spread over V0..V6)
COLUMNS = (
    "t_rmse", "psi_rmse", "f_ave_hz", "f_sw_hz", "cal_ave", "deadbeat_share", "speed_rmse", "thd",
    "thd_harmonics", "thd_cycles", "thd_fundamental_hz", "steps", "t_start", "t_end",
    "compute_ns_mean", "compute_ns_median",
)  # fmt: skip


#: a sweep of drawn drives summarises these metrics (by key), and ranks by these
DRAW_COLUMNS = ("t_rmse", "thd", "f_sw_hz")
DRAW_RANKED = ("t_rmse",)


def table(rows: Sequence[Row]) -> tuple[list[str], list[list[Any]]]:
    """Header and rows: strategy, one column per swept key (the value as given), every metric
    (:data:`COLUMNS`, and :data:`~..core.metrics.LOSS_METRICS` where a run booked losses),
    utilization V0..V6, error, wall_s."""
    keys = list(dict.fromkeys(k for r in rows for k in r.settings))
    drawn = any(r.draw is not None for r in rows)
    metrics = [*COLUMNS, *(LOSS_METRICS if any(books_losses(r.metrics) for r in rows) else ())]
    header = ["strategy", *keys, *metrics, *(f"util_v{i}" for i in range(7)), "error", "wall_s"]
    header[1:1] = ["draw"] if drawn else []
    out = []
    for r in rows:
        m = r.metrics.as_dict() if r.metrics is not None else {}
        util = list(m.get("utilization", [math.nan] * 7)) + [math.nan] * 7
        out.append(
            [
                r.strategy,
                *([r.draw["index"] if r.draw else None] if drawn else []),
                *(r.settings.get(k) for k in keys),
                *(m.get(c, "" if c == "tj_max_device" else math.nan) for c in metrics),
                *util[:7],
                r.error or "",
                r.wall_s,
            ]
        )
    return header, out


def _pyarrow() -> tuple[Any, Any]:
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise missing(
            "pyarrow", "sweep --out: the Parquet table (FILE.csv: the CSV alone)"
        ) from None
    return pa, pq


def table_files(out: str | Path) -> list[Path]:
    """What ``--out`` writes: ``FILE.csv`` (the CSV table alone), ``FILE.parquet`` (Parquet
    alone), or a folder ``DIR``: ``DIR/sweep.csv`` and ``DIR/sweep.parquet``."""
    p = Path(out)
    if p.suffix in (".csv", ".parquet"):
        return [p]
    return [p / "sweep.csv", p / "sweep.parquet"]


def check_table_files(out: str | Path) -> list[Path]:
    """:func:`table_files`, checked before anything runs: Parquet needs pyarrow, a file must
    not be a folder."""
    files = table_files(out)
    for f in files:
        if f.is_dir():
            raise ConfigError(f"sweep --out {out}: {f} is a folder, not a table file")
        check_output_dir(f.parent, option="sweep --out")
        if f.suffix == ".parquet":
            _pyarrow()
    return files


def write_table(rows: Sequence[Row], out: str | Path) -> list[Path]:
    """The table as :func:`table_files` names it; each file written whole or not at all (to a
    temporary file, then renamed)."""
    header, body = table(rows)
    files = table_files(out)
    for f in files:
        f.parent.mkdir(parents=True, exist_ok=True)
        tmp = f.with_name(f.name + ".tmp")
        if f.suffix == ".csv":
            with tmp.open("w", newline="") as fh:
                w = csv.writer(fh)
                w.writerow(header)
                for line in body:  # a float exactly (repr), a numpy scalar as a plain one
                    w.writerow(
                        ["" if v is None else repr(float(v)) if isinstance(v, float) else v
                         for v in line]
                    )  # fmt: skip
        else:
            _write_parquet(header, body, tmp)
        tmp.replace(f)
    return files


def _write_parquet(header: list[str], body: list[list[Any]], path: Path) -> None:
    pa, pq = _pyarrow()
    columns = {}
    for j, name_ in enumerate(header):
        values = [line[j] for line in body]
        numeric = all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)
        columns[name_] = (
            pa.array([float(v) for v in values], pa.float64())
            if numeric and name_ not in ("strategy", "error")
            else pa.array(["" if v is None else str(v) for v in values], pa.string())
        )
    pq.write_table(pa.table(columns), path)


def sweep(
    scenario: str | Path,
    *,
    strategies: Sequence[str] = (),
    sets: Sequence[str] = (),
    duration: float | None = None,
    out: str | Path | None = None,
    record: bool = False,
    figures: str | Path | None = None,
    scheduler: str | None = None,
    jobs: int | None = None,
    progress: Callable[[int, int], None] | None = None,
    expand: Callable[[list[Case]], list[Case]] | None = None,
) -> SweepResult:
    """The command: the grid of ``strategies`` (default: the scenario's) × every ``--set``,
    run, written (``out``: CSV + Parquet, and the bags with ``record``), drawn (``figures``).
    ``expand``: the grid's cases → the cases run (every case on each drawn drive:
    :func:`.draws.sweep_drawn`)."""
    path = resolve_scenario_path(scenario)
    base = load_scenario_text(path.read_text(encoding="utf-8"), path)
    parsed = [parse_set(s) for s in sets]
    cases = grid(list(strategies) or [base.strategy], parsed)
    if expand is not None:
        cases = expand(cases)
    if record:
        if out is None or len(table_files(out)) == 1:
            raise ConfigError(
                f"sweep --record needs --out DIR, a folder (the bags go to DIR/bags/), "
                f"not {'nothing' if out is None else out}"
            )
        from ..bag import check_new_bag

        for i, c in enumerate(cases):
            tag = "_".join(f"{k.rsplit('.', 1)[-1]}{v}" for k, v in c.settings.items())
            bag = Path(out) / "bags" / f"{i:03d}_{c.strategy}{'_' + tag if tag else ''}"
            if c.draw is not None:
                bag = bag.with_name(f"{bag.name}_draw{c.draw['index']}")
            cases[i] = dataclasses.replace(c, bag=str(check_new_bag(bag).resolve()))
    if out is not None:
        check_table_files(out)  # the table can be written: checked before the runs, not after
    check_output_dir(figures, option="sweep --figures")
    if duration is not None and not (math.isfinite(duration) and duration > 0):
        raise ConfigError(f"--duration must be a positive number of seconds, got {duration}")
    result = run_cases(
        path, cases, duration=duration, scheduler=scheduler, jobs=jobs, progress=progress
    )
    if out is not None:
        result.files = [str(p) for p in write_table(result.rows, out)]
    if figures is not None and result.rows:
        from ..reports.figures import save, sweep_figures

        keys = [k for k, _ in parsed]
        result.figures = [str(p) for p in save(sweep_figures(result.rows, keys), figures)]
    return result
