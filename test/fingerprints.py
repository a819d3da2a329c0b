"""Fingerprints of today's recordings: what ``test_fingerprints.py`` holds the core to.

Every short scenario runs with every strategy of its family, on the ideal drive and on the
realism study's real drive (one period of computation delay with its compensation, dead time
with device drops, the sensors), in-process, :data:`STEPS` steps each, the plant's period means
on (they change nothing else: ``test_period_means_change_nothing_else``). A fingerprint is, per
per-step topic (state, reference, command; the runs book no losses) and per field, a hash of the
field's column as little-endian doubles: every field but ``compute_ns`` (wall time, never the same twice).

A change meant to alter a recording regenerates the stored file in the same commit and says why
in its message::

    .venv/bin/python test/fingerprints.py          # rewrites test/fingerprints.json

A field added to a record adds its hashes; the others stay as they were, which is how a
commit shows that it added a field without changing one.
"""

from __future__ import annotations

import hashlib
import json
import sys
from pathlib import Path
from typing import Any

from predictive_drive.config import apply_settings, load_scenario_text, resolve_scenario_path
from predictive_drive.core.control import strategy_names
from predictive_drive.core.runner import run_inprocess
from predictive_drive.core.trace import RECORDS, Trace
from predictive_drive.reports.realism import REALISM, condition_settings

STORED = Path(__file__).with_name("fingerprints.json")
#: steps of each run: past the IM's soft start (about 40 steps), the load and flux transients
STEPS = 800
#: the short scenarios, whose real drive each takes (the realism study's, by machine) and what
#: differs from it (paper 002's 200 us period needs a speed window of at least one period)
SCENARIOS: dict[str, tuple[str, dict[str, Any]]] = {
    "im_short": ("im_paper", {}),
    "spmsm_short": ("ipmsm_validation", {}),
    "ipmsm_short": ("ipmsm_validation", {}),
    "ipmsm_mtpa_short": ("ipmsm_validation", {}),
    "hs_ipmsm_mtpa_short": ("ipmsm_validation", {"plant.speed_window": 1e-3}),
}
#: fields whose values are measured, not computed
UNSTABLE = {"compute_ns"}


def real_drive(scenario: str) -> dict[str, Any]:
    """The realism study's last column ("+ sensors": delay, compensation, dead time, sensors)
    for the machine of ``scenario``."""
    study, own = SCENARIOS[scenario]
    return {**condition_settings(REALISM[study].hardware)[-1][1], **own}


#: every run's own settings
COMMON = {"plant.period_means": True}


def cases() -> list[tuple[str, str, str, dict[str, Any]]]:
    """(id, scenario, strategy, settings) of every run fingerprinted."""
    out = []
    for scenario in SCENARIOS:
        family = load_scenario_text(*_text(scenario, {})).family
        for strategy in strategy_names(family):
            for drive, settings in (("ideal", {}), ("real", real_drive(scenario))):
                case = (scenario, strategy, {**COMMON, **settings})
                out.append((f"{scenario}-{strategy}-{drive}", *case))
    return out


def _text(scenario: str, settings: dict[str, Any]) -> tuple[str, str]:
    path = resolve_scenario_path(scenario)
    text = path.read_text(encoding="utf-8")
    return (apply_settings(text, settings, path) if settings else text), str(path)


def trace_of(scenario: str, strategy: str, settings: dict[str, Any]) -> Trace:
    sc = load_scenario_text(*_text(scenario, settings)).with_strategy(strategy)
    return run_inprocess(sc, steps=STEPS)


def fingerprint(trace: Trace) -> dict[str, dict[str, str]]:
    """Per record and field, the first 16 hex digits of the SHA-256 of its column (a record the
    run has not — the losses of a plant without them — has none)."""
    out: dict[str, dict[str, str]] = {}
    for record, fields in RECORDS.items():
        if record == "losses" and not trace.has_losses:
            continue
        out[record] = {
            name: hashlib.sha256(trace.col(record, name).astype("<f8").tobytes()).hexdigest()[:16]
            for name in fields
            if name not in UNSTABLE
        }
    return out


def compute() -> dict[str, dict[str, dict[str, str]]]:
    return {cid: fingerprint(trace_of(sc, st, s)) for cid, sc, st, s in cases()}


def main() -> None:
    STORED.write_text(json.dumps(compute(), indent=1, sort_keys=True) + "\n")
    print(f"wrote {STORED} ({len(cases())} runs of {STEPS} steps)", file=sys.stderr)


if __name__ == "__main__":
    main()
