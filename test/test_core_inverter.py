import cmath
import math

import pytest

from predictive_drive.core.inverter import (
    VECTOR_STATES,
    PhasePulses,
    active_then_zero,
    clarke,
    segments,
    vector_voltages,
    zero_state_for,
)

pytestmark = pytest.mark.core


def test_vectors_have_paper_numbering_and_two_thirds_udc_amplitude():
    v = vector_voltages(300.0)
    assert v[0] == 0
    for n in range(1, 7):
        assert abs(v[n]) == pytest.approx(200.0, rel=1e-12)
        assert math.degrees(cmath.phase(v[n])) % 360 == pytest.approx(60 * (n - 1) % 360, abs=1e-9)


def test_clarke_is_amplitude_invariant_for_balanced_three_phase():
    for th in (0.0, 0.4, 2.0):
        x = clarke(math.cos(th), math.cos(th - 2 * math.pi / 3), math.cos(th + 2 * math.pi / 3))
        assert abs(x - cmath.exp(1j * th)) < 1e-12


@pytest.mark.parametrize(
    "prev,zero",
    [
        ((0, 0, 0), (0, 0, 0)),
        ((1, 0, 0), (0, 0, 0)),
        ((1, 1, 0), (1, 1, 1)),
        ((1, 1, 1), (1, 1, 1)),
    ],
    ids=["000", "100", "110", "111"],
)
def test_zero_vector_needs_fewest_switch_changes(prev, zero):
    assert zero_state_for(prev) == zero


@pytest.mark.parametrize("vector", range(1, 7), ids=[f"V{n}" for n in range(1, 7)])
@pytest.mark.parametrize("fraction", [0.0, 0.3, 1.0])
def test_active_then_zero_applies_vector_then_nearest_zero(vector, fraction):
    pulses, end = active_then_zero(vector, fraction, (0, 0, 0))
    segs, end2, transitions = segments(pulses, (0, 0, 0))
    assert end == end2
    volt_seconds = sum(clarke(*s) * f for s, f in segs)
    assert volt_seconds == pytest.approx(fraction * clarke(*VECTOR_STATES[vector]), abs=1e-12)
    assert sum(f for _, f in segs) == pytest.approx(1.0)
    if 0 < fraction < 1:
        assert segs[0] == (VECTOR_STATES[vector], pytest.approx(fraction))
        assert segs[1][0] == zero_state_for(VECTOR_STATES[vector])
        # one leg changes vector→zero: 2 device transitions, plus those into the active vector
        into = sum(VECTOR_STATES[vector])
        assert transitions == 2 * (into + 1)


def test_transitions_count_two_per_leg_change_across_periods():
    _, _, t = segments(PhasePulses(0, 0, 0, 1, 0, 0), (0, 0, 0))  # 000 → 100
    assert t == 2
    _, _, t = segments(PhasePulses(0, 0, 0, 0, 1, 1), (1, 0, 0))  # 100 → 011
    assert t == 6
    _, _, t = segments(PhasePulses(0.25, 0.25, 0.25, 0.5, 0.5, 0.5), (0, 0, 0))  # centre-aligned
    assert t == 12
