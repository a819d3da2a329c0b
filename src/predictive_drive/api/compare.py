"""``predictive-drive compare``: recordings side by side — their metrics in one table and, on
request, their figures overlaid (e.g. the strategies of one scenario)."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..errors import ConfigError
from .report import evaluate

__all__ = ["compare"]


def compare(bags: Sequence[str | Path], *, figures: str | Path | None = None) -> dict[str, Any]:
    """Each recording's metrics; ``figures``: a folder for the overlaid figures (PNG)."""
    if len(bags) < 2:
        raise ConfigError("compare needs two recordings or more")
    evs = [evaluate(b) for b in bags]
    labels = [f"{ev.scenario.name} {ev.info.info['strategy']}" for ev in evs]
    if len(set(labels)) < len(labels):  # the same scenario and strategy twice: say which bag
        labels = [f"{lab} ({Path(b).name})" for lab, b in zip(labels, bags)]
    out: dict[str, Any] = {
        "runs": [
            {"bag": str(b), "label": lab, "steps": ev.steps, "metrics": ev.metrics.as_dict()}
            for b, lab, ev in zip(bags, labels, evs)
        ]
    }
    if figures is not None:
        from ..reports.figures import Run, compare_figures, save

        runs = [Run(ev.trace, ev.scenario, lab) for ev, lab in zip(evs, labels)]
        out["figures"] = [str(p) for p in save(compare_figures(runs), figures, "compare_")]
    return out
