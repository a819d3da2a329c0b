"""The sphere decoder compiled (docs/physics.md#long-horizons): :func:`~.search.sphere_decode`
as a numba kernel, for ``direct_mpc``'s long horizons, where the decoder visits thousands of
nodes a period and CPython spends 2-3 µs on each.

The one part of the core that is not numpy and the standard library: numba is optional
(``pip install 'predictive_drive[fast]'``) and imported here only, the first time a kernel is
asked for. :func:`~.search.sphere_decode` stays the reference: the kernel does the same
arithmetic in the same order — each row's fixed columns added from the last down, the partial
distance row by row, values tried nearest first, ties to the lexicographically smallest — so its
answer is the same, bit for bit (``test_the_compiled_decoder_is_the_reference_bit_for_bit``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from functools import cache
from typing import Any

import numpy as np

from .search import SearchResult

__all__ = ["compiled_sphere_decoder", "kernel_unavailable"]

#: a sphere decoder: (V, ū, guess, levels) → SearchResult
Decoder = Callable[[Any, Any, Sequence[int], Sequence[int]], SearchResult]


@cache
def kernel_unavailable() -> str | None:
    """Why there is no compiled kernel here (None: there is one)."""
    try:
        import numba  # noqa: F401
    except ImportError:
        return "numba is not installed (pip install 'predictive_drive[fast]')"
    return None


@cache
def _kernel() -> Any:
    from numba import njit

    @njit(cache=True)
    def decode(
        v: np.ndarray, ub: np.ndarray, radius: float, best: np.ndarray, levels: np.ndarray
    ) -> tuple[np.ndarray, float, int]:
        n = ub.shape[0]
        k = levels.shape[0]
        u = np.zeros(n, np.int64)
        offs = np.zeros((n, n))
        partial = np.zeros(n)
        centre = np.zeros(n)
        order = np.zeros((n, k), np.int64)
        pos = np.zeros(n, np.int64)
        have_best = best.shape[0] == n
        nodes = 0

        def enter(r: int) -> None:
            c = ub[r] - offs[r, r]
            centre[r] = c
            diag = v[r, r]
            # insertion sort of the values by (|c - diag x|, x)
            for i in range(k):
                order[r, i] = levels[i]
            for i in range(1, k):
                x = order[r, i]
                key = abs(c - diag * x)
                j = i - 1
                while j >= 0:
                    y = order[r, j]
                    ky = abs(c - diag * y)
                    if ky > key or (ky == key and y > x):
                        order[r, j + 1] = y
                        j -= 1
                    else:
                        break
                order[r, j + 1] = x
            pos[r] = 0

        r = n - 1
        enter(r)
        while True:
            if pos[r] < k:
                x = order[r, pos[r]]
                pos[r] += 1
                nodes += 1
                e = centre[r] - v[r, r] * x
                d = partial[r] + e * e
                if d > radius:
                    pos[r] = k  # the next values lie farther still
                    continue
                u[r] = x
                if r == 0:
                    smaller = False
                    if have_best:
                        for i in range(n):
                            if u[i] != best[i]:
                                smaller = u[i] < best[i]
                                break
                    if d < radius or smaller:
                        radius = d
                        best = u.copy()
                        have_best = True
                    continue
                for q in range(r):
                    offs[r - 1, q] = offs[r, q] + v[q, r] * x
                partial[r - 1] = d
                r -= 1
                enter(r)
            else:
                r += 1
                if r == n:
                    break
        if not have_best:
            best = np.zeros(0, np.int64)
        return best, radius, nodes

    @njit(cache=True)
    def distance(v: np.ndarray, ub: np.ndarray, u: np.ndarray) -> float:
        """search._distance, compiled: the same terms in the same order."""
        n = ub.shape[0]
        d = 0.0
        for r in range(n - 1, -1, -1):
            off = 0.0
            for c in range(n - 1, r, -1):
                off += v[r, c] * u[c]
            e = (ub[r] - off) - v[r, r] * u[r]
            d += e * e
        return d

    return decode, distance


def compiled_sphere_decoder() -> Decoder:
    """:func:`~.search.sphere_decode` compiled; ImportError (with the reason) without numba."""
    reason = kernel_unavailable()
    if reason is not None:
        raise ImportError(reason)
    decode, distance = _kernel()

    def sphere_decode(
        v: Any, ubar: Any, guess: Sequence[int] = (), levels: Sequence[int] = (0, 1)
    ) -> SearchResult:
        vv = np.ascontiguousarray(v, dtype=np.float64)
        ub = np.ascontiguousarray(ubar, dtype=np.float64)
        n = ub.shape[0]
        if len(guess) == n:
            best = np.asarray(guess, dtype=np.int64)
            radius = distance(vv, ub, best)
        else:
            radius, best = math.inf, np.zeros(0, np.int64)
        u, d, nodes = decode(vv, ub, radius, best, np.asarray(levels, dtype=np.int64))
        return SearchResult(tuple(int(x) for x in u), float(d), int(nodes))

    return sphere_decode
