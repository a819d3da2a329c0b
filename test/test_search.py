"""The exact searches of core/control/search.py against exhaustive enumeration
(docs/physics.md#long-horizons): random trees and random integer least-squares problems, ties
included, every horizon small enough to enumerate."""

from __future__ import annotations

import itertools
import random

import numpy as np
import pytest

from predictive_drive.core.control.search import (
    branch_and_bound,
    exhaustive,
    sequence_cost,
    sphere_decode,
)

pytestmark = pytest.mark.core


def random_tree(seed: int, inputs: int = 7, coarse: bool = False):
    """A tree whose node is (level, path) and whose stage costs are a hash of the path: any
    shape of cost, non-negative; ``coarse``: a few distinct values, so ties are common."""

    def expand(node):
        rng = random.Random(hash((seed, node)))
        out = []
        for u in range(inputs):
            c = rng.choice([0.0, 0.5, 1.0, 2.0]) if coarse else rng.expovariate(1.0)
            out.append((c, u, (*node, u)))
        rng.shuffle(out)  # the family's order is not the search's
        return out

    return expand


@pytest.mark.parametrize("horizon", [1, 2, 3, 4])
@pytest.mark.parametrize("coarse", [False, True], ids=["continuous", "ties"])
def test_branch_and_bound_equals_exhaustive_enumeration(horizon, coarse):
    for seed in range(150 if horizon < 4 else 40):
        expand = random_tree(seed, coarse=coarse)
        want = exhaustive(expand, (), horizon)
        rng = random.Random(seed)
        for guess in ((), tuple(rng.randrange(7) for _ in range(horizon))):
            got = branch_and_bound(expand, (), horizon, guess)
            assert (got.sequence, got.cost) == (want.sequence, want.cost), (seed, guess)
            if not coarse:
                assert got.nodes <= want.nodes + 7 * horizon


def test_the_cost_of_a_sequence_is_its_stage_costs_summed_in_order():
    expand = random_tree(3)
    want = exhaustive(expand, (), 3)
    assert sequence_cost(expand, (), want.sequence)[0] == want.cost
    assert sequence_cost(expand, (), (0, 9, 1))[0] == float("inf")  # no input 9


def brute_force_ils(v, ubar, levels):
    """min ‖ū - V·U‖² over every U, in the decoder's arithmetic order, lexicographic ties."""
    n = len(ubar)
    best, best_u = float("inf"), None
    for u in itertools.product(levels, repeat=n):
        d = 0.0
        for r in range(n - 1, -1, -1):
            off = 0.0
            for c in range(n - 1, r, -1):
                off += v[r][c] * u[c]
            e = (ubar[r] - off) - v[r][r] * u[r]
            d += e * e
        if d < best:
            best, best_u = d, u
    return best_u, best


@pytest.mark.parametrize("n", [1, 3, 6, 9])
@pytest.mark.parametrize("levels", [(0, 1), (-1, 0, 1)], ids=["two-level", "three-level"])
def test_the_sphere_decoder_equals_a_brute_force_search(n, levels):
    rng = np.random.default_rng(n)
    for trial in range(40 if len(levels) ** n < 1000 else 8):
        a = rng.standard_normal((n + 2, n))
        h = a.T @ a + 0.1 * np.eye(n)
        v = np.linalg.cholesky(h).T  # upper triangular, H = VᵀV
        ubar = v @ rng.uniform(-0.5, 1.5, n)
        want = brute_force_ils(v.tolist(), ubar.tolist(), levels)
        for guess in ((), tuple(rng.choice(levels, n).tolist())):
            got = sphere_decode(v.tolist(), ubar.tolist(), guess, levels)
            assert (got.sequence, got.cost) == want, (trial, guess)


def test_the_sphere_decoder_breaks_ties_to_the_smallest_sequence():
    """V = I, ū = ½: every binary U lies at the same distance; the rule takes the smallest."""
    got = sphere_decode(np.eye(4).tolist(), [0.5] * 4, (1, 1, 0, 1))
    assert got.sequence == (0, 0, 0, 0) and got.cost == 1.0


@pytest.mark.parametrize("n", [1, 3, 6, 9])
@pytest.mark.parametrize("levels", [(0, 1), (-1, 0, 1)], ids=["two-level", "three-level"])
def test_the_compiled_decoder_is_the_reference_bit_for_bit(n, levels):
    """The numba kernel against search.sphere_decode on the same problems, with and without a
    guess (the first radius from a shifted optimum, or from any sequence): the same sequence,
    the same distance to the last bit and the same node count."""
    kernels = pytest.importorskip("predictive_drive.core.control.kernels")
    if kernels.kernel_unavailable() is not None:
        pytest.skip(kernels.kernel_unavailable())
    compiled = kernels.compiled_sphere_decoder()
    rng = np.random.default_rng(100 + n)
    for trial in range(60):
        a = rng.standard_normal((n + 2, n))
        h = a.T @ a + rng.choice([1e-3, 0.1, 1.0]) * np.eye(n)
        v = np.linalg.cholesky(h).T
        ubar = v @ rng.uniform(min(levels) - 0.5, max(levels) + 0.5, n)
        first = sphere_decode(v.tolist(), ubar.tolist(), (), levels)
        shifted = (*first.sequence[1:], first.sequence[-1])
        for guess in ((), shifted, first.sequence, tuple(rng.choice(levels, n).tolist())):
            want = sphere_decode(v.tolist(), ubar.tolist(), guess, levels)
            got = compiled(v, ubar, guess, levels)
            assert got == want, (trial, guess)
            assert type(got.cost) is float and type(got.nodes) is int


@pytest.mark.parametrize("search", ["branch_and_bound", "sphere_decode"])
def test_a_budget_stops_the_search_with_the_best_sequence_found_so_far(search):
    """Within ``budget`` nodes, once it holds a complete sequence, the search stops and
    returns the best it has found, ``complete`` False: exactly the budget's nodes (the tree
    search counts a node's children at once, at most six more, and its guess's cost first), a
    cost that is its sequence's
    own and falls as the budget grows to the unlimited search's, which a budget at or above
    its node count gives bit for bit; a budget below the first leaf returns the guess."""
    rng = np.random.default_rng(7)
    stopped = 0
    for seed in range(60):
        if search == "branch_and_bound":
            expand, horizon = random_tree(seed), 4
            guess = tuple(rng.integers(0, 7, horizon).tolist())

            def run(budget, guess=guess, expand=expand, horizon=horizon):
                return branch_and_bound(expand, (), horizon, guess, budget)

            def cost_of(seq, expand=expand):
                return sequence_cost(expand, (), seq)[0]

            step, floor = 7, 7 * horizon  # the guess's own cost takes a node's children a level
        else:
            n = 8
            a = rng.standard_normal((n + 2, n))
            v = np.linalg.cholesky(a.T @ a + 0.05 * np.eye(n)).T
            ubar = v @ rng.uniform(-0.5, 1.5, n)
            guess = tuple(rng.integers(0, 2, n).tolist())

            def run(budget, v=v, ubar=ubar, guess=guess):
                return sphere_decode(v.tolist(), ubar.tolist(), guess, budget=budget)

            def cost_of(seq, v=v, ubar=ubar):
                return float(np.sum((ubar - v @ np.array(seq)) ** 2))

            step, floor = 1, 0
        full = run(0)
        assert full.complete
        assert run(full.nodes) == full and run(full.nodes + 5) == full
        assert run(1).sequence == guess and not run(1).complete
        last = float("inf")
        for budget in range(step, full.nodes - step + 1, max(step, full.nodes // 12)):
            got = run(budget)
            assert not got.complete and budget <= got.nodes < max(budget, floor) + step
            assert got.cost == pytest.approx(cost_of(got.sequence), rel=1e-12)
            assert full.cost <= got.cost <= last
            last = got.cost
            stopped += 1
    assert stopped > 100
