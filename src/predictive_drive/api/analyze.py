"""``predictive-drive analyze``: vector utilization of a recording (paper 001 Tables 1, 3-8) and
the candidate sets it derives (docs/physics.md#utilization-analysis)."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.analysis import DERIVATION_RULE, derive_candidates, utilization
from ..core.control.candidates import TABLES, class_document
from ..errors import ConfigError
from ..readback import read_bag
from ..recording import scenario_of
from ..reports.papers import PAPER_001_TABLE1
from .report import metrics_window

__all__ = ["Analysis", "Band", "analyze"]


@dataclass(frozen=True)
class Band:
    """Zero-vector use among the steps with |ΔT| ≤ ``band`` N·m (None: all steps), and the
    paper's (N, N_V0) for that band where paper 001 Table 1 gives one."""

    band: float | None
    n: int
    n_v0: int
    eta_v0: float
    paper: tuple[int, int] | None


@dataclass(frozen=True)
class Analysis:
    """``analyze``: a recording's vector utilization and the candidate sets it derives.

    ``class_steps``, ``utilization`` and ``derived`` are keyed by table (``six_sector``,
    ``twelve_sector``) and sign class, a value per sector, in the layout of
    ``core/control/candidate_tables.json``; ``differences`` names the classes whose derived set
    differs from the tables in use."""

    bag: Path
    scenario: str
    strategy: str
    threshold: float
    window: tuple[float, float]
    steps: int
    bands: list[Band]
    class_steps: dict[str, Any]
    utilization: dict[str, Any]
    rule: str
    derived: dict[str, Any]
    differences: list[str]
    written: Path | None = None

    @property
    def matches_tables(self) -> bool:
        return not self.differences

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "bag": str(self.bag),
            "scenario": self.scenario,
            "strategy": self.strategy,
            "threshold": self.threshold,
            "window": list(self.window),
            "steps": self.steps,
            "bands": [
                {"band": b.band, "n": b.n, "n_v0": b.n_v0, "eta_v0": b.eta_v0, "paper": b.paper}
                for b in self.bands
            ],
            "class_steps": self.class_steps,
            "utilization": self.utilization,
            "rule": self.rule,
            "derived": self.derived,
            "matches_tables": self.matches_tables,
            "differences": self.differences,
        }
        if self.written is not None:
            out["written"] = str(self.written)
        return out


def analyze(
    bag: str | Path,
    *,
    threshold: float | None = None,
    write_tables: str | Path | None = None,
) -> Analysis:
    """Vector utilization of a recording (paper 001 Tables 1, 3-8) and the candidate sets it
    derives, compared with the tables strategies 2 and 3 use."""
    trace, info = read_bag(bag)
    sc = scenario_of(info.info, info.path)
    if threshold is None:
        threshold = getattr(sc.controller, "torque_threshold", None)
        if threshold is None:
            raise ConfigError(
                f"analyze: {bag} is a {sc.family} run without a torque threshold; give "
                f"--threshold N·m"
            )
    if not (math.isfinite(threshold) and threshold >= 0):
        raise ConfigError(f"--threshold must be a torque >= 0 N·m, got {threshold}")
    start, end = metrics_window(sc, trace.steps * trace.ts)
    u = utilization(trace, threshold=threshold, t_start=start, t_end=end)
    derived = class_document(derive_candidates(u.six), derive_candidates(u.twelve))
    used = class_document(TABLES.six, TABLES.twelve)
    differences = [
        f"{table.split('_')[0]} sectors, {cls}, θ{s + 1}: derived {d}, used {u_}"
        for table, classes in derived.items()
        for cls, cells in classes.items()
        for s, (d, u_) in enumerate(zip(cells, used[table][cls]))
        if d != u_
    ]
    shares = class_document(u.shares(u.six), u.shares(u.twelve), cell=np.ndarray.tolist)
    counts = class_document(u.six.sum(axis=-1), u.twelve.sum(axis=-1), cell=int)
    bands = [
        Band(
            None if math.isinf(b) else b,
            n,
            n0,
            n0 / n if n else math.nan,
            PAPER_001_TABLE1.get(None if math.isinf(b) else b),
        )
        for b, n, n0 in u.bands
    ]
    written = None
    if write_tables is not None:
        doc = {
            "source": f"predictive-drive analyze {Path(bag)}",
            "rule": DERIVATION_RULE,
            **derived,
        }
        written = Path(write_tables)
        tmp = written.with_name(written.name + ".tmp")
        tmp.write_text(json.dumps(doc, indent=1) + "\n")
        tmp.replace(written)  # never a half-written table
    return Analysis(
        bag=Path(bag),
        scenario=info.info["scenario"],
        strategy=info.info["strategy"],
        threshold=threshold,
        window=(start, end),
        steps=u.steps,
        bands=bands,
        class_steps=counts,
        utilization=shares,
        rule=DERIVATION_RULE,
        derived=derived,
        differences=differences,
        written=written,
    )
