"""``predictive-drive compare``: recordings side by side — their metrics in one table and, on
request, their figures overlaid (e.g. the strategies of one scenario)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..core.metrics import Metrics, unequal_switching
from ..errors import ConfigError
from ..outputs import check_output_dir
from ..recording import run_label
from .report import evaluate

__all__ = ["Compared", "Comparison", "compare"]


@dataclass(frozen=True)
class Compared:
    """One recording of a comparison: its bag, its label in the table, steps and metrics."""

    bag: Path
    label: str
    steps: int
    metrics: Metrics


@dataclass(frozen=True)
class Comparison:
    """``compare``: the recordings in the order given, the figures drawn, and ``unequal_fsw``:
    a sentence when their switching frequencies differ too much for their distortion to
    compare (None when they do not)."""

    runs: list[Compared]
    figures: list[Path] = field(default_factory=list)

    @property
    def unequal_fsw(self) -> str | None:
        return unequal_switching({r.label: r.metrics.f_sw_hz for r in self.runs})

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            "runs": [
                {"bag": str(r.bag), "label": r.label, "steps": r.steps,
                 "metrics": r.metrics.as_dict()}
                for r in self.runs
            ],
            "unequal_fsw": self.unequal_fsw,
        }  # fmt: skip
        if self.figures:
            out["figures"] = [str(p) for p in self.figures]
        return out


def compare(bags: Sequence[str | Path], *, figures: str | Path | None = None) -> Comparison:
    """Each recording's metrics; ``figures``: a folder for the overlaid figures (PNG)."""
    if len(bags) < 2:
        raise ConfigError("compare needs two recordings or more")
    check_output_dir(figures, option="compare --figures")
    evs = [evaluate(b) for b in bags]
    labels = [run_label(ev.info.info) for ev in evs]
    if len(set(labels)) < len(labels):  # the same scenario and strategy twice: say which bag
        labels = [f"{lab} ({Path(b).name})" for lab, b in zip(labels, bags)]
    drawn: list[Path] = []
    if figures is not None:
        from ..reports.figures import Run, compare_figures, save

        runs = [Run(ev.trace, ev.scenario, lab) for ev, lab in zip(evs, labels)]
        drawn = save(compare_figures(runs), figures, "compare_")
    return Comparison(
        [Compared(Path(b), lab, ev.steps, ev.metrics) for b, lab, ev in zip(bags, labels, evs)],
        drawn,
    )
