"""``predictive-drive analyze``: vector utilization of a recording (paper 001 Tables 1, 3-8) and
the candidate sets it derives (SPEC §6.4)."""

from __future__ import annotations

import json
import math
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

__all__ = ["analyze"]


def analyze(
    bag: str | Path,
    *,
    threshold: float | None = None,
    write_tables: str | Path | None = None,
) -> dict[str, Any]:
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
        {
            "band": None if math.isinf(b) else b,
            "n": n,
            "n_v0": n0,
            "eta_v0": n0 / n if n else math.nan,
            "paper": PAPER_001_TABLE1.get(None if math.isinf(b) else b),
        }
        for b, n, n0 in u.bands
    ]
    out: dict[str, Any] = {
        "bag": str(Path(bag)),
        "scenario": info.info["scenario"],
        "strategy": info.info["strategy"],
        "threshold": threshold,
        "window": [start, end],
        "steps": u.steps,
        "bands": bands,
        "class_steps": counts,
        "utilization": shares,
        "rule": DERIVATION_RULE,
        "derived": derived,
        "matches_tables": not differences,
        "differences": differences,
    }
    if write_tables is not None:
        doc = {
            "source": f"predictive-drive analyze {Path(bag)}",
            "rule": DERIVATION_RULE,
            **derived,
        }
        dest = Path(write_tables)
        tmp = dest.with_name(dest.name + ".tmp")
        tmp.write_text(json.dumps(doc, indent=1) + "\n")
        tmp.replace(dest)  # never a half-written table
        out["written"] = str(dest)
    return out
