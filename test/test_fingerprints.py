"""Today's recordings, held: every short scenario with every strategy of its family, on the ideal
drive and on a real one, fingerprinted field by field against test/fingerprints.json (see
fingerprints.py for what is run and how to regenerate the file after a change meant to alter
a recording)."""

from __future__ import annotations

import json

import pytest

from fingerprints import STORED, cases, fingerprint, trace_of

CASES = cases()


@pytest.fixture(scope="module")
def stored() -> dict:
    return json.loads(STORED.read_text())


@pytest.mark.core
def test_the_stored_file_holds_exactly_the_cases_run(stored):
    assert sorted(stored) == sorted(c[0] for c in CASES)


@pytest.mark.core
@pytest.mark.parametrize(("scenario", "strategy", "settings", "steps"), [c[1:] for c in CASES],
                         ids=[c[0] for c in CASES])  # fmt: skip
def test_a_run_records_what_it_recorded_before(
    stored, scenario, strategy, settings, steps, request
):
    case = request.node.callspec.id
    now = fingerprint(trace_of(scenario, strategy, settings, steps))
    before = stored[case]
    changed = [
        f"{record}.{name}"
        for record in before
        for name in before[record]
        if now[record].get(name) != before[record][name]
    ]
    added = [f"{r}.{n}" for r in now for n in now[r] if n not in before.get(r, {})]
    assert not changed and not added, (
        f"{case}: fields that differ from the stored fingerprint: {changed}; fields new to it: "
        f"{added}. If the change is meant, run `python test/fingerprints.py` and say why in "
        f"the commit"
    )


@pytest.mark.core
@pytest.mark.parametrize("drive", ["ideal", "real"])
def test_period_means_change_nothing_else(drive):
    """The plant's period means on or off: every other field the same, bit for bit (the
    integrator takes the same sub-steps); off, the means are NaN."""
    import math

    import numpy as np

    from predictive_drive.core.plant import PERIOD_MEANS
    from predictive_drive.core.signals import State

    case = next(c for c in CASES if c[0] == f"ipmsm_mtpa_short-foc_zero_d-{drive}")
    on = trace_of(*case[1:])
    off = trace_of(case[1], case[2], {**case[3], "plant.period_means": False}, case[4])
    means = [State._fields.index(name) for name in PERIOD_MEANS]
    rest = [i for i in range(len(State._fields)) if i not in means]
    assert np.array_equal(on.state[:, rest], off.state[:, rest], equal_nan=True)
    assert np.array_equal(on.command[:, :-1], off.command[:, :-1], equal_nan=True)  # not compute_ns
    assert np.isnan(off.state[:, means]).all() and not np.isnan(on.state[:, means]).any()
    assert not math.isnan(on.state[-1, means[-1]])
