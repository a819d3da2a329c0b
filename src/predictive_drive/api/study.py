"""What every study of ``reproduce`` shares, whatever its table: how its runs are made (the
engine, a shortened duration, the local cores or a Dask cluster), where their bags go, the
progress told case by case, and the metrics window the runs actually used.

A study builds its cases (:class:`~.sweep.Case`), names each one's bag with
:meth:`StudyRuns.bag` and runs them with :meth:`StudyRuns.runs`; :func:`studying` makes the
:class:`StudyRuns` and, when the study ends, removes the bags nobody asked to keep. So a new
study gets the progress, the bag handling and the window for nothing.
"""

from __future__ import annotations

import dataclasses
import os
import shutil
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..bag import check_new_bag
from ..config import scenario_with
from ..errors import Interrupted, PredictiveDriveError
from ..outputs import check_output_dir
from .report import evaluate
from .run import run
from .sweep import WORKER_ENDED, Analysis, Case, Row, run_cases

__all__ = ["BagsKept", "Reproduction", "StudyRuns", "studying"]


@dataclass(frozen=True)
class BagsKept:
    """The bags a study kept (``reproduce --bags DIR``): where, how many, how many bytes."""

    folder: str
    count: int
    bytes: int


@dataclass(frozen=True)
class Reproduction:
    """What every reproduction says of itself: the scenario, the engine, the run length if
    shortened (then not comparable with the paper), the settings applied to every run, the
    paper's caption and how our figures are computed; and, filled in for every study alike
    (:mod:`.study`), the metrics window each scenario's runs used (``windows``: scenario →
    (from, to) s, the scenario's window cut by a shortened run) and the bags kept (``bags``:
    None unless asked for)."""

    scenario: str
    engine: str
    duration: float | None
    settings: dict[str, Any]
    paper: str
    how: str
    windows: dict[str, list[tuple[float, float]]] = field(default_factory=dict, kw_only=True)
    bags: BagsKept | None = field(default=None, kw_only=True)

    def head(self) -> dict[str, Any]:
        return {
            "scenario": self.scenario,
            "engine": self.engine,
            "duration": self.duration,
            "settings": self.settings,
            "paper": self.paper,
            "how": self.how,
            "windows": {k: [list(w) for w in v] for k, v in self.windows.items()},
            "bags": None if self.bags is None else dataclasses.asdict(self.bags),
        }


@dataclass
class StudyRuns:
    """How a study's runs are made and what they tell. ``folder``: where the bags go — the
    user's (``keep``), or a temporary one removed when the study ends; ``progress(done,
    planned[, name])``: told as each case ends, counted across all the study's sweeps
    (``planned`` grows as each sweep starts), with what the case was where the study names
    it; ``windows``: each scenario's metrics windows the runs used (the scenario's, cut by
    ``duration``)."""

    folder: Path
    keep: bool
    engine: str = "inprocess"
    duration: float | None = None
    jobs: int | None = None
    scheduler: str | None = None
    progress: Callable[..., None] | None = None
    #: ``local (N processes)``, ``dask (ADDRESS, N workers)`` or the ROS engine's name
    where: str = ""
    planned: int = 0
    done: int = 0
    windows: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    bags: list[str] = field(default_factory=list)
    stamp: str = field(default_factory=lambda: f"{time.strftime('%Y%m%d-%H%M%S')}_{os.getpid()}")

    def bag(self, name: str, *, needed: bool = False) -> str | None:
        """The bag of a case called ``name`` (the study's stamp is added): recorded when the
        user keeps the bags, when the study needs it (``needed``: its figures, its timing
        replays) or when the engine records anyway (a ROS graph); else None, not recorded."""
        if not (self.keep or needed or self.engine != "inprocess"):
            return None
        path = str(check_new_bag(self.folder / f"{name}_{self.stamp}").resolve())
        self.bags.append(path)
        return path

    def runs(
        self,
        scenario: str,
        cases: Sequence[Case],
        *,
        analysis: Analysis | None = None,
        failures: bool = False,
        names: Sequence[str] | None = None,
        external: Mapping[str, str] | None = None,
        label: str | None = None,
    ) -> list[Row]:
        """The cases, each recorded to its bag if it names one: a sweep across the cores or the
        cluster (in-process), or one graph at a time (a ROS engine, which uses the cores
        already; and nodes of the user's own, ``external`` as ``run --external`` takes them,
        ``label`` naming their torque controller). ``names``: what each case is, told to the
        progress as it ends. A failed case fails the study, naming it (``failures``: a case's
        own failure is a row with its error, for a study that counts them, as over drawn
        drives; a worker that died still fails the study)."""
        before = self.done
        self.planned += len(cases)
        last = [""]

        def ended(i: int) -> None:
            last[0] = names[i] if names is not None else ""

        def finished(k: int, n: int) -> None:
            self.done = before + k
            if self.progress is not None:
                if last[0]:
                    self.progress(self.done, self.planned, last[0])
                else:
                    self.progress(self.done, self.planned)

        if self.engine == "inprocess" and not external:
            result = run_cases(
                scenario,
                cases,
                duration=self.duration,
                scheduler=self.scheduler,
                jobs=self.jobs,
                analysis=analysis,
                progress=finished,
                finished=ended,
            )
            if result.interrupted:
                raise self.interrupted(before + len(result.rows), result.cut)
            rows, self.where = result.rows, result.engine
        else:
            rows = []
            if not external:
                self.where = self.engine
            for i, c in enumerate(cases):
                try:
                    rows.append(self._graph_run(scenario, c, analysis, external, label))
                except Interrupted as e:  # the run's own report: where its bag is, what it holds
                    cut = [str(e).removeprefix("interrupted: ")]
                    raise self.interrupted(before + i, cut) from None
                ended(i)
                finished(i + 1, len(cases))
        for row in rows:
            if failures and row.error and not row.error.startswith(WORKER_ENDED):
                continue  # the case's own failure (a drive that leaves its map), counted
            if row.error or row.metrics is None:
                raise PredictiveDriveError(
                    f"reproduce {scenario}: the run {row.strategy} {row.settings or ''} failed: "
                    f"{row.error}"
                )
            window = (row.metrics.t_start, row.metrics.t_end)
            if window not in self.windows.setdefault(scenario, []):
                self.windows[scenario].append(window)
        return rows

    def _graph_run(
        self,
        scenario: str,
        c: Case,
        analysis: Analysis | None,
        external: Mapping[str, str] | None = None,
        label: str | None = None,
    ) -> Row:
        with tempfile.TemporaryDirectory() as tmp:
            own = list(external or ())
            path = scenario_with(scenario, c.settings, Path(tmp), own=own)
            if external:
                r = run(
                    path, engine="ros", out=c.bag, duration=self.duration, external=external,
                    label=label,
                )  # fmt: skip
            else:
                r = run(
                    path, strategy=c.strategy, engine=self.engine, out=c.bag,
                    duration=self.duration,
                )  # fmt: skip
        ev = evaluate(r.bag)
        extra = analysis(ev.trace, ev.scenario) if analysis is not None else {}
        return Row(c.strategy, c.settings, ev.metrics, None, r.wall_s, c.bag, extra)

    def interrupted(self, finished: int, cut: Sequence[str]) -> Interrupted:
        """What a Ctrl-C leaves of the study: how many runs had finished, where their bags
        are (kept only with ``--bags``), and each run it cut, as a sweep lists them."""
        text = f"interrupted: {finished} of {self.planned} runs of the study had finished"
        if self.keep:
            text += f"; their bags are in {self.folder}"
        else:
            text += " (no table: it needs every run; --bags DIR keeps each run's bag)"
        return Interrupted("\n".join([text, *(f"not complete: {c}" for c in cut)]))

    def kept(self) -> BagsKept | None:
        """The bags kept for the user (None when they were not asked for)."""
        if not self.keep:
            return None
        made = [Path(b) for b in self.bags if Path(b).exists()]
        size = sum(f.stat().st_size for b in made for f in b.rglob("*") if f.is_file())
        return BagsKept(str(self.folder), len(made), size)


@contextmanager
def studying(
    bags: str | Path | None,
    *,
    engine: str = "inprocess",
    duration: float | None = None,
    jobs: int | None = None,
    scheduler: str | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> Iterator[StudyRuns]:
    """A study's :class:`StudyRuns`; ``bags``: the folder to keep its bags in, or None: the
    bags the study needs go to a temporary folder, removed when it ends (however it ends). A
    Ctrl-C between its sweeps says, as one inside a sweep does, how many runs had finished."""
    if bags is not None:
        check_output_dir(bags, option="--bags")
    folder = (
        Path(bags) if bags is not None else Path(tempfile.mkdtemp(prefix="predictive_drive_study_"))
    )
    runner = StudyRuns(folder, bags is not None, engine, duration, jobs, scheduler, progress)
    try:
        yield runner
    except KeyboardInterrupt:
        raise runner.interrupted(runner.done, []) from None
    finally:
        if bags is None:
            shutil.rmtree(folder, ignore_errors=True)
