"""Fingerprints of today's recordings: what ``test_fingerprints.py`` holds the core to.

Every short scenario, and the fronts' steady points, runs with every strategy of its family, on
the ideal drive and on the realism study's real drive (one period of computation delay with its
compensation, dead time with device drops, the sensors), in-process, :data:`STEPS` steps each,
the plant's period means on (they change nothing else:
``test_period_means_change_nothing_else``). A fingerprint is, per per-step topic (state,
reference, command; the runs book no losses) and per field, a hash of the field's column as
little-endian doubles: every field but ``compute_ns`` (wall time, never the same twice).

The long horizons (multi-step ``mptc`` of both MPTC families, ``direct_mpc``) run besides, a few
hundred steps each at one horizon (:data:`HORIZON_RUNS`): their searches are exact, so a faster
search holds these to the same decisions, node counts aside where it visits fewer. Each runs
with its family's default node budget, and ``-unlimited`` without one (the exact search: the
budget's 0 decides as the searches did before there was one).

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
    # the fronts' steady points (docs/reproduction.md#fronts-distortion-against-switching-frequency)
    # and their field-oriented twins; their direct_mpc twins (*_steady_mpc) are the horizons'
    "im_steady": ("im_paper", {}),
    "im_steady_foc": ("im_paper", {}),
    "ipmsm_steady": ("ipmsm_validation", {}),
    "ipmsm_steady_foc": ("ipmsm_validation", {}),
    "hs_ipmsm_steady": ("ipmsm_validation", {}),
    "hs_ipmsm_steady_foc": ("ipmsm_validation", {"plant.speed_window": 1e-3}),
}
#: fields whose values are measured, not computed
UNSTABLE = {"compute_ns"}


def real_drive(scenario: str) -> dict[str, Any]:
    """The realism study's last column ("+ sensors": delay, compensation, dead time, sensors)
    for the machine of ``scenario``."""
    study, own = SCENARIOS.get(scenario, (STUDY_OF.get(scenario, ""), {}))
    return {**condition_settings(REALISM[study].hardware)[-1][1], **own}


#: every run's own settings
COMMON = {"plant.period_means": True}
#: the long horizons: id → (scenario, strategy, horizon, real drive or ideal, steps); the steady
#: points' first 400 steps hold their torque ramp (direct_mpc's largest trees) and its end
HORIZON_RUNS: dict[str, tuple[str, str, int, bool, int]] = {
    # the exact search (node_budget 0), as before the budget; the default budget stops it at
    # some of these steps
    "ipmsm_steady_mpc-direct_mpc-N10-ideal-unlimited": (
        "ipmsm_steady_mpc",
        "direct_mpc",
        10,
        False,
        400,
    ),  # fmt: skip
    "im_short-mptc-N3-ideal": ("im_short", "mptc", 3, False, 1400),  # soft start: 963 steps
    "ipmsm_short-mptc-N3-ideal": ("ipmsm_short", "mptc", 3, False, 400),
    "ipmsm_short-mptc-N2-real": ("ipmsm_short", "mptc", 2, True, 400),
    "ipmsm_steady_mpc-direct_mpc-N1-ideal": ("ipmsm_steady_mpc", "direct_mpc", 1, False, 400),
    "ipmsm_steady_mpc-direct_mpc-N3-real": ("ipmsm_steady_mpc", "direct_mpc", 3, True, 400),
    "ipmsm_steady_mpc-direct_mpc-N10-ideal": ("ipmsm_steady_mpc", "direct_mpc", 10, False, 400),
    "hs_ipmsm_steady_mpc-direct_mpc-N5-ideal": ("hs_ipmsm_steady_mpc", "direct_mpc", 5, False, 400),
}
#: the real drive of each steady point: its machine's (the realism study's)
STUDY_OF = {"ipmsm_steady_mpc": "ipmsm_validation", "hs_ipmsm_steady_mpc": "ipmsm_validation"}


def cases() -> list[tuple[str, str, str, dict[str, Any], int]]:
    """(id, scenario, strategy, settings, steps) of every run fingerprinted."""
    out = []
    for scenario in SCENARIOS:
        family = load_scenario_text(*_text(scenario, {})).family
        for strategy in strategy_names(family):
            for drive, settings in (("ideal", {}), ("real", real_drive(scenario))):
                case = (scenario, strategy, {**COMMON, **settings}, STEPS)
                out.append((f"{scenario}-{strategy}-{drive}", *case))
    for cid, (scenario, strategy, horizon, real, steps) in HORIZON_RUNS.items():
        drive = real_drive(scenario) if real else {}
        law = {"torque_controller.strategy": strategy, "torque_controller.horizon": horizon}
        if cid.endswith("-unlimited"):
            law["torque_controller.node_budget"] = 0
        settings = {**COMMON, **drive, **law}
        out.append((cid, scenario, strategy, settings, steps))
    return out


def _text(scenario: str, settings: dict[str, Any]) -> tuple[str, str]:
    path = resolve_scenario_path(scenario)
    text = path.read_text(encoding="utf-8")
    return (apply_settings(text, settings, path) if settings else text), str(path)


def trace_of(scenario: str, strategy: str, settings: dict[str, Any], steps: int = STEPS) -> Trace:
    sc = load_scenario_text(*_text(scenario, settings)).with_strategy(strategy)
    return run_inprocess(sc, steps=steps)


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
    return {cid: fingerprint(trace_of(sc, st, s, n)) for cid, sc, st, s, n in cases()}


def main() -> None:
    STORED.write_text(json.dumps(compute(), indent=1, sort_keys=True) + "\n")
    print(f"wrote {STORED} ({len(cases())} runs)", file=sys.stderr)


if __name__ == "__main__":
    main()
