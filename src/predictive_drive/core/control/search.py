"""Exact searches over switching sequences for long prediction horizons
(docs/physics.md#long-horizons), apart from the families whose costs they minimise — as Soft4PES
keeps its solvers apart from its controllers.

- :func:`branch_and_bound` — the best sequence of N inputs for a cost that is a sum of
  non-negative stage costs (the MPTC families' torque, flux and switching terms): depth-first,
  children tried in the order of their stage cost, a branch cut as soon as its partial cost
  exceeds the best complete sequence found so far; the first incumbent is the previous optimum
  shifted by one period, its last input repeated.
- :func:`sphere_decode` — the integer least-squares problem min ‖ū - V·U‖² over U ∈ {0, 1}^n, V
  upper triangular (Geyer & Quevedo's form of a quadratic cost over a horizon): depth-first from
  the last component, each node's partial distance against the radius, the radius shrinking
  with each better leaf; the first radius from a sequence the caller guesses (the shifted
  optimum).
- :func:`exhaustive` — every sequence: the reference both are tested against.

**A budget** bounds the worst case, as real-time implementations do: with ``budget`` > 0 a
search stops once it has evaluated that many nodes and holds a complete sequence, and returns
the best one found so far, ``complete`` False (docs/physics.md#a-budget-per-step). 0: none.

**Ties** are broken by one rule everywhere: among sequences of equal cost the lexicographically
smallest wins (inputs compared level by level, as ``tuple`` compares), the first strict minimum
of an enumeration in lexicographic order. Costs are summed stage by stage in order, so every
search adds the same floats in the same order as :func:`exhaustive`.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from typing import Any, NamedTuple

__all__ = [
    "Expand",
    "SearchResult",
    "branch_and_bound",
    "exhaustive",
    "sequence_cost",
    "sphere_decode",
]

INF = math.inf

#: ``expand(node) -> [(stage cost >= 0, input, child node), ...]``: every input's stage cost and
#: the node it leads to, from a node (the predicted state, and whatever the cost needs of the
#: past, e.g. the switching state in force)
Expand = Callable[[Any], Sequence[tuple[float, int, Any]]]


class SearchResult(NamedTuple):
    """The best sequence, its cost, how many nodes the search evaluated (stage costs for
    :func:`branch_and_bound` and :func:`exhaustive`, tree nodes for :func:`sphere_decode`),
    and whether it finished (False: its budget ran out; the sequence is the best found)."""

    sequence: tuple[int, ...]
    cost: float
    nodes: int
    complete: bool = True


def sequence_cost(expand: Expand, root: Any, sequence: Sequence[int]) -> tuple[float, int]:
    """The cost of one sequence from ``root`` (INF if an input is not among a node's children)
    and the stage costs evaluated to find it."""
    total, node, nodes = 0.0, root, 0
    for u in sequence:
        children = expand(node)
        nodes += len(children)
        for cost, v, child in children:
            if v == u:
                total, node = total + cost, child
                break
        else:
            return INF, nodes
    return total, nodes


def exhaustive(expand: Expand, root: Any, horizon: int) -> SearchResult:
    """Every sequence of ``horizon`` inputs in lexicographic order; the first strict minimum."""
    best: list[Any] = [INF, ()]
    nodes = 0

    def walk(node: Any, level: int, acc: float, prefix: tuple[int, ...]) -> None:
        nonlocal nodes
        children = sorted(expand(node), key=lambda c: c[1])
        nodes += len(children)
        for cost, u, child in children:
            total = acc + cost
            if level + 1 == horizon:
                if total < best[0]:
                    best[0], best[1] = total, (*prefix, u)
            else:
                walk(child, level + 1, total, (*prefix, u))

    walk(root, 0, 0.0, ())
    return SearchResult(best[1], best[0], nodes)


def branch_and_bound(
    expand: Expand, root: Any, horizon: int, guess: Sequence[int] = (), budget: int = 0
) -> SearchResult:
    """The optimal sequence of ``horizon`` inputs from ``root``; ``guess`` (a sequence of that
    length, e.g. the last optimum shifted) gives the first upper bound. Exact for stage costs
    that are never negative: a branch is cut only when its partial cost already exceeds a
    complete sequence's, and equal costs go on to the tie rule (module text). ``budget``: see
    the module text."""
    best_cost, nodes = (INF, 0) if len(guess) != horizon else sequence_cost(expand, root, guess)
    best_seq: tuple[int, ...] = tuple(guess) if best_cost < INF else ()
    last = horizon - 1
    stopped = False

    def walk(node: Any, level: int, acc: float, prefix: tuple[int, ...]) -> None:
        nonlocal best_cost, best_seq, nodes, stopped
        if stopped or (budget and nodes >= budget and best_seq):
            stopped = True
            return
        children = sorted(expand(node), key=lambda c: (c[0], c[1]))
        nodes += len(children)
        for cost, u, child in children:
            total = acc + cost
            if total > best_cost:
                break  # the rest cost as much or more at this level already
            seq = (*prefix, u)
            if level == last:
                if total < best_cost or seq < best_seq:
                    best_cost, best_seq = total, seq
            else:
                walk(child, level + 1, total, seq)
                if stopped:
                    return

    walk(root, 0, 0.0, ())
    return SearchResult(best_seq, best_cost, nodes, not stopped)


def sphere_decode(
    v: Sequence[Sequence[float]],
    ubar: Sequence[float],
    guess: Sequence[int] = (),
    levels: Sequence[int] = (0, 1),
    budget: int = 0,
) -> SearchResult:
    """min ‖ū - V·U‖² over U with every component in ``levels``, V (n × n) upper triangular
    (row r holds columns r..n-1): the optimal U, its squared distance and the tree nodes
    visited. The first radius is the distance of ``guess`` (none: unbounded until the first
    leaf). Components are fixed from the last (row n-1 involves U[n-1] alone) to the first,
    the values at each level tried nearest first to the point that minimises that row's term
    (Schnorr-Euchner order), so the first leaf is Babai's rounding and good leaves come early.
    ``budget``: see the module text."""
    n = len(ubar)
    rows = [list(map(float, r)) for r in v]
    target = list(map(float, ubar))
    radius = INF
    best: tuple[int, ...] = ()
    if len(guess) == n:
        radius = _distance(rows, target, guess)
        best = tuple(guess)
    nodes = 0
    u = [0] * n
    stopped = False

    def walk(r: int, partial: float, offset: list[float]) -> None:
        """Fix U[r]; ``offset[q]`` = Σ_{c>r} V[q][c]·U[c] for the rows q <= r, added from the
        last column down (the order :func:`_distance` adds in)."""
        nonlocal radius, best, nodes, stopped
        row = rows[r]
        diag = row[r]
        centre = target[r] - offset[r]
        # the level's values, nearest first to centre / diag (ties: the smaller value)
        order = sorted(levels, key=lambda x: (abs(centre - diag * x), x))
        for x in order:
            if stopped or (budget and nodes >= budget and best):
                stopped = True
                return
            nodes += 1
            e = centre - diag * x
            d = partial + e * e
            if d > radius:
                break  # the next values lie farther still
            u[r] = x
            if r == 0:
                seq = tuple(u)
                if d < radius or seq < best:
                    radius, best = d, seq
                continue
            walk(r - 1, d, [offset[q] + rows[q][r] * x for q in range(r)])

    walk(n - 1, 0.0, [0.0] * n)
    return SearchResult(best, radius, nodes, not stopped)


def _distance(rows: list[list[float]], target: list[float], u: Sequence[int]) -> float:
    """‖ū - V·U‖², term by term in the decoder's order: rows from the last up, each row's
    fixed columns added from the last down."""
    n = len(target)
    d = 0.0
    for r in range(n - 1, -1, -1):
        row = rows[r]
        off = 0.0
        for c in range(n - 1, r, -1):
            off += row[c] * u[c]
        e = (target[r] - off) - row[r] * u[r]
        d += e * e
    return d
