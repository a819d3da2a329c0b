"""The long horizons' searches compiled (docs/physics.md#long-horizons): the sphere decoder of
:func:`~.search.sphere_decode`, ``direct_mpc``'s whole decision (its problem,
:func:`~.mpc_pmsm.problem`, and the decoder), and branch and bound over the MPTC families'
stages (:func:`~.search.branch_and_bound` of :func:`~.mptc_im.horizon_stages` and
:func:`~.mptc_pmsm.horizon_stages`), as numba kernels, where CPython spends 2-3 µs on a
node.

The one part of the core that is not numpy and the standard library: numba is optional
(``pip install 'predictive_drive[fast]'``) and imported here only, the first time a kernel is
asked for. The Python functions stay the reference: each kernel does the same arithmetic in
the same order — the problem's sums and factor entry by entry, each row's fixed columns added
from the last down, the partial distance row by row, values and children tried in the same
order, ties to the lexicographically smallest, the budget counted alike — so its answer is
the same, bit for bit, node count included (``test_the_compiled_decoder_is_the_reference_bit_for_bit``,
``test_compiled_direct_mpc_is_the_reference_bit_for_bit``,
``test_compiled_branch_and_bound_is_the_reference_bit_for_bit``).

The decoder computes the fixed columns' sums of a row only when it enters that row, from
the highest column changed since it last did (Ghasemmehdi and Agrell's lazy projection,
"Faster recursions in sphere decoding", IEEE TIT 57(6), 2011): the same sums, added in the same
order, without the work for rows a pruned branch never reaches.
"""

from __future__ import annotations

import importlib.util
import math
from collections.abc import Callable, Sequence
from functools import cache
from typing import Any

import numpy as np

from .search import SearchResult

__all__ = [
    "compiled_branch_and_bound",
    "compiled_direct_mpc",
    "compiled_sphere_decoder",
    "kernel_unavailable",
    "load_kernels",
    "IM_STAGE",
    "PMSM_STAGE",
]

#: a sphere decoder: (V, ū, guess, levels, budget) → SearchResult
Decoder = Callable[..., SearchResult]
#: which stage :func:`compiled_branch_and_bound` computes
IM_STAGE, PMSM_STAGE = 0, 1


@cache
def kernel_unavailable() -> str | None:
    """Why there is no compiled kernel here (None: there is one). numba is looked for, not
    imported: that waits for the first kernel."""
    if importlib.util.find_spec("numba") is None:
        return "numba is not installed (pip install 'predictive_drive[fast]')"
    return None


def load_kernels() -> bool:
    """Load (or compile, the first time) every kernel now, not in the first step that needs
    one (about 1.4 s in a process: numba loads a kernel's machine code at its first call);
    False without numba."""
    if kernel_unavailable() is not None:
        return False
    compiled_sphere_decoder()(np.eye(2), np.ones(2), (0, 1))
    model, state = (1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 1e-2, 0.0, 0.0, 1e-2, 0.5), (0.0,) * 7
    compiled_direct_mpc()(model, 2, state, 1.0, 0.01, (0, 0, 0), (0,) * 6, 0)
    table, moves = np.zeros((8, 7)), np.zeros((7, 2))
    compiled_branch_and_bound()(
        IM_STAGE, np.ones(11), np.zeros(4), 0, moves, table, np.zeros((8, 7), np.int64), moves,
        2, (), 0,
    )  # fmt: skip
    return True


def smaller(a: np.ndarray, b: np.ndarray) -> bool:
    """a < b, lexicographically (as ``tuple`` compares)."""
    for i in range(a.shape[0]):
        if a[i] != b[i]:
            return bool(a[i] < b[i])
    return False


def decode(
    v: np.ndarray,
    ub: np.ndarray,
    radius: float,
    best: np.ndarray,
    levels: np.ndarray,
    budget: int,
) -> tuple[np.ndarray, float, int, bool]:
    n = ub.shape[0]
    k = levels.shape[0]
    u = np.zeros(n, np.int64)
    # sums[q, c] = Σ_{j ≥ c} V[q, j]·U[j] (sums[q, n] = 0), valid for c > stale[q]
    sums = np.zeros((n, n + 1))
    stale = np.full(n, n - 1, np.int64)
    partial = np.zeros(n)
    centre = np.zeros(n)
    order = np.zeros((n, k), np.int64)
    pos = np.zeros(n, np.int64)
    have_best = best.shape[0] == n
    nodes = 0
    complete = True

    def enter(r: int) -> None:
        for c in range(stale[r], r, -1):
            sums[r, c] = sums[r, c + 1] + v[r, c] * u[c]
        if r > 0 and stale[r] > stale[r - 1]:
            stale[r - 1] = stale[r]
        stale[r] = r
        c = ub[r] - sums[r, r + 1]
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
            if budget > 0 and nodes >= budget and have_best:
                complete = False
                break
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
                if d < radius or (have_best and smaller(u, best)):
                    radius = d
                    best = u.copy()
                    have_best = True
                continue
            if stale[r - 1] < r:  # U[r] changed: row r-1's sums from column r on
                stale[r - 1] = r
            partial[r - 1] = d
            r -= 1
            enter(r)
        else:
            r += 1
            if r == n:
                break
    if not have_best:
        best = np.zeros(0, np.int64)
    return best, radius, nodes, complete


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


def problem(
    model: Sequence[float],
    n: int,
    state: Sequence[float],
    i_base: float,
    lam: float,
    prev: Sequence[int],
) -> tuple[np.ndarray, np.ndarray]:
    """mpc_pmsm.problem, compiled: (V, ū), the same operations in the same order."""
    a11, a12, a21, a22 = model[0], model[1], model[2], model[3]
    cd, cq, g11, g12, g21, g22, share = (
        model[4], model[5], model[6], model[7], model[8], model[9], model[10]
    )  # fmt: skip
    i_d, i_q, theta, turn, u_dc, r_d, r_q = (
        state[0], state[1], state[2], state[3], state[4], state[5], state[6]
    )  # fmt: skip
    size = 3 * n
    l0 = (2.0 / 3.0, -1.0 / 3.0, -1.0 / 3.0)
    l1 = (0.0, 1.0 / math.sqrt(3.0), -1.0 / math.sqrt(3.0))
    pw = np.zeros((n, 4))
    pw[0, 0] = 1.0
    pw[0, 3] = 1.0
    for k in range(1, n):
        p11, p12, p21, p22 = pw[k - 1, 0], pw[k - 1, 1], pw[k - 1, 2], pw[k - 1, 3]
        pw[k, 0] = a11 * p11 + a12 * p21
        pw[k, 1] = a11 * p12 + a12 * p22
        pw[k, 2] = a21 * p11 + a22 * p21
        pw[k, 3] = a21 * p12 + a22 * p22
    e0 = np.zeros(2 * n)
    x, y = i_d, i_q
    for ell in range(n):
        x, y = a11 * x + a12 * y + cd, a21 * x + a22 * y + cq
        e0[2 * ell] = (r_d - x) / i_base
        e0[2 * ell + 1] = (r_q - y) / i_base
    ups = np.zeros((2 * n, size))
    for m in range(n):
        angle = theta + (m + share) * turn
        co, si = math.cos(angle), math.sin(angle)
        for j in range(3):
            ud = u_dc * (co * l0[j] + si * l1[j])
            uq = u_dc * (co * l1[j] - si * l0[j])
            bd = (g11 * ud + g12 * uq) / i_base
            bq = (g21 * ud + g22 * uq) / i_base
            col = size - 1 - (3 * m + j)
            for ell in range(m, n):
                ups[2 * ell, col] = pw[ell - m, 0] * bd + pw[ell - m, 1] * bq
                ups[2 * ell + 1, col] = pw[ell - m, 2] * bd + pw[ell - m, 3] * bq
    h = np.zeros((size, size))
    f = np.zeros(size)
    for i in range(size):
        ti = size - 1 - i
        mi = ti // 3
        acc = 0.0
        for r in range(2 * mi, 2 * n):
            acc += ups[r, i] * e0[r]
        f[i] = acc + lam * prev[ti] if mi == 0 else acc
        for k in range(i, size):
            tk = size - 1 - k
            mk = tk // 3
            acc = 0.0
            for r in range(2 * (mi if mi > mk else mk), 2 * n):
                acc += ups[r, i] * ups[r, k]
            if ti == tk:
                acc += lam * (1.0 if mi == n - 1 else 2.0)
            elif ti - tk == 3 or tk - ti == 3:
                acc -= lam
            h[i, k] = acc
            h[k, i] = acc
    v = np.zeros((size, size))
    ubar = np.zeros(size)
    for j in range(size):
        acc = h[j, j]
        for k in range(j):
            acc -= v[k, j] * v[k, j]
        d = math.sqrt(acc)
        v[j, j] = d
        for i in range(j + 1, size):
            acc = h[j, i]
            for k in range(j):
                acc -= v[k, j] * v[k, i]
            v[j, i] = acc / d
        acc = f[j]
        for k in range(j):
            acc -= v[k, j] * ubar[k]
        ubar[j] = acc / d
    return v, ubar


def smallest_of_equal_cost(u: np.ndarray, prev: Sequence[int]) -> np.ndarray:
    """mpc_pmsm.smallest_of_equal_cost of a solution in U's order: the plan in order of
    time, 000 and 111 chosen alike."""
    n = u.shape[0] // 3
    size = 3 * n
    codes = np.zeros(n, np.int64)
    for ell in range(n):
        k = size - 1 - 3 * ell  # u(ℓ)_a
        codes[ell] = u[k] * 4 + u[k - 1] * 2 + u[k - 2]
    ch = np.zeros((n, 2), np.int64)
    for ell in range(n):
        c = codes[ell]
        if c == 0 or c == 7:
            ch[ell, 0], ch[ell, 1] = 0, 7
        else:
            ch[ell, 0], ch[ell, 1] = c, c
    ham = np.zeros((8, 8), np.int64)
    for a in range(8):
        for b in range(8):
            x = a ^ b
            ham[a, b] = (x & 1) + ((x >> 1) & 1) + ((x >> 2) & 1)
    tg = np.zeros((n, 2), np.int64)
    for ell in range(n - 2, -1, -1):
        na, nb, ta, tb = ch[ell + 1, 0], ch[ell + 1, 1], tg[ell + 1, 0], tg[ell + 1, 1]
        for i in range(2):
            x = ch[ell, i]
            tg[ell, i] = min(ham[x, na] + ta, ham[x, nb] + tb)
    out = np.zeros(size, np.int64)
    last = prev[0] * 4 + prev[1] * 2 + prev[2]
    for ell in range(n):
        a, b = ch[ell, 0], ch[ell, 1]
        last = a if ham[last, a] + tg[ell, 0] <= ham[last, b] + tg[ell, 1] else b
        out[3 * ell] = (last >> 2) & 1
        out[3 * ell + 1] = (last >> 1) & 1
        out[3 * ell + 2] = last & 1
    return out


def direct_mpc(
    model: Sequence[float],
    n: int,
    state: Sequence[float],
    i_base: float,
    lam: float,
    prev: Sequence[int],
    guess: np.ndarray,
    budget: int,
) -> tuple[np.ndarray, float, int, bool]:
    v, ub = problem(model, n, state, i_base, lam, prev)
    radius = math.inf
    if guess.shape[0] == 3 * n:
        radius = distance(v, ub, guess)
    u, d, nodes, complete = decode(v, ub, radius, guess, np.arange(2), budget)
    return smallest_of_equal_cost(u, prev), d, nodes, complete


def expand(
    kind: int, prm: np.ndarray, x: np.ndarray, code: int, level: int, volts: np.ndarray,
    full: np.ndarray, after: np.ndarray, turn: np.ndarray, cost: np.ndarray,
    nxt: np.ndarray, ncode: np.ndarray,
) -> None:  # fmt: skip
    """A node's seven children, as mptc_im.horizon_stages (kind IM_STAGE) and
    mptc_pmsm.horizon_stages (PMSM_STAGE) compute them. Python multiplies a float and a
    complex as two complex numbers, (a + 0j)(b + cj): the zero products are kept."""
    if kind == 0:
        ar, ai, br, bi, ts, rs, gain_i, tk, lam, t_ref, psi_ref = (
            prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7], prm[8],
            prm[9], prm[10],
        )  # fmt: skip
        ir, ii, pr, pi = x[0], x[1], x[2], x[3]
        # i_free = i + ts * (a * i + b * psi)
        sr = (ar * ir - ai * ii) + (br * pr - bi * pi)
        si = (ar * ii + ai * ir) + (br * pi + bi * pr)
        fr = ir + (ts * sr - 0.0 * si)
        fi = ii + (ts * si + 0.0 * sr)
        # psi_free = psi - ts * rs * i
        k = ts * rs
        qr = pr - (k * ir - 0.0 * ii)
        qi = pi - (k * ii + 0.0 * ir)
        for n in range(7):
            ur, ui = volts[n, 0], volts[n, 1]
            i1r = fr + (gain_i * ur - 0.0 * ui)
            i1i = fi + (gain_i * ui + 0.0 * ur)
            p1r = qr + (ts * ur - 0.0 * ui)
            p1i = qi + (ts * ui + 0.0 * ur)
            t1 = tk * (p1r * i1i - p1i * i1r)
            cost[n] = abs(t_ref - t1) + lam * abs(psi_ref - math.hypot(p1r, p1i)) + full[code, n]
            nxt[n, 0], nxt[n, 1], nxt[n, 2], nxt[n, 3] = i1r, i1i, p1r, p1i
            ncode[n] = after[code, n]
    else:
        pf, ild, ilq, tk, dl, inv_t, inv_p, t_ref, psi_ref = (
            prm[0], prm[1], prm[2], prm[3], prm[4], prm[5], prm[6], prm[7], prm[8]
        )  # fmt: skip
        rr, ri = turn[level, 0], turn[level, 1]
        for n in range(7):
            p1r = x[0] + volts[n, 0]
            p1i = x[1] + volts[n, 1]
            dr = p1r * rr - p1i * ri
            di = p1r * ri + p1i * rr
            i_d = (dr - pf) * ild
            i_q = di * ilq
            e_t = (tk * i_q * (pf + dl * i_d) - t_ref) * inv_t
            e_p = (math.hypot(p1r, p1i) - psi_ref) * inv_p
            cost[n] = math.sqrt(e_t * e_t + e_p * e_p) + full[code, n]
            nxt[n, 0], nxt[n, 1] = p1r, p1i
            ncode[n] = after[code, n]


def branch_and_bound(
    kind: int, prm: np.ndarray, root: np.ndarray, code: int, volts: np.ndarray,
    full: np.ndarray, after: np.ndarray, turn: np.ndarray, horizon: int,
    guess: np.ndarray, budget: int,
) -> tuple[np.ndarray, float, int, bool]:  # fmt: skip
    """search.branch_and_bound of a family's stages, compiled: the guess's cost first, then
    depth first, children by (stage cost, input), the same budget rule."""
    n_max = horizon
    x = np.zeros((n_max + 1, 4))
    x[0, :] = root
    codes = np.zeros(n_max + 1, np.int64)
    codes[0] = code
    acc = np.zeros(n_max + 1)
    cost = np.zeros((n_max, 7))
    nxt = np.zeros((n_max, 7, 4))
    ncode = np.zeros((n_max, 7), np.int64)
    order = np.zeros((n_max, 7), np.int64)
    pos = np.zeros(n_max, np.int64)
    seq = np.zeros(n_max, np.int64)
    best = np.zeros(0, np.int64)
    best_cost = math.inf
    have_best = False
    nodes = 0
    if guess.shape[0] == n_max:
        total = 0.0
        for level in range(n_max):
            expand(kind, prm, x[level], codes[level], level, volts, full, after, turn,
                   cost[level], nxt[level], ncode[level])  # fmt: skip
            nodes += 7
            u = guess[level]
            total = total + cost[level, u]
            x[level + 1, :] = nxt[level, u]
            codes[level + 1] = ncode[level, u]
        best_cost, best, have_best = total, guess.copy(), True
    complete = True
    level = 0
    while True:
        if pos[level] == 0:  # entering the level: the budget, then its children in order
            if budget > 0 and nodes >= budget and have_best:
                complete = False
                break
            expand(kind, prm, x[level], codes[level], level, volts, full, after, turn,
                   cost[level], nxt[level], ncode[level])  # fmt: skip
            nodes += 7
            for i in range(7):
                order[level, i] = i
            for i in range(1, 7):
                m = order[level, i]
                j = i - 1
                while j >= 0 and cost[level, order[level, j]] > cost[level, m]:
                    order[level, j + 1] = order[level, j]
                    j -= 1
                order[level, j + 1] = m
        if pos[level] < 7:
            n = order[level, pos[level]]
            pos[level] += 1
            total = acc[level] + cost[level, n]
            if total > best_cost:
                pos[level] = 8  # the rest cost as much or more at this level already
                continue
            seq[level] = n
            if level == n_max - 1:
                if total < best_cost or (have_best and smaller(seq, best)):
                    best_cost, best, have_best = total, seq.copy(), True
                continue
            acc[level + 1] = total
            x[level + 1, :] = nxt[level, n]
            codes[level + 1] = ncode[level, n]
            level += 1
            pos[level] = 0
        else:
            if level == 0:
                break
            level -= 1
    return best, best_cost, nodes, complete


#: the kernels, compiled where they are first loaded: the functions below (plain Python that
#: numba compiles), each replaced in this module by its compiled form, so one kernel calls
#: another as a module global and numba's cache keeps them between processes (a kernel that
#: called another through a closure was compiled anew in every process)
_COMPILED = ("smaller", "decode", "distance", "problem", "smallest_of_equal_cost", "direct_mpc", "expand",
             "branch_and_bound")  # fmt: skip


@cache
def _kernels() -> Any:
    from numba import njit

    g = globals()
    for name in _COMPILED:
        g[name] = njit(cache=True)(g[name])
    return decode, distance, direct_mpc, problem, branch_and_bound


def compiled_sphere_decoder() -> Decoder:
    """:func:`~.search.sphere_decode` compiled; ImportError (with the reason) without numba."""
    reason = kernel_unavailable()
    if reason is not None:
        raise ImportError(reason)
    decode, distance, *_ = _kernels()

    def sphere_decode(
        v: Any, ubar: Any, guess: Sequence[int] = (), levels: Sequence[int] = (0, 1),
        budget: int = 0,
    ) -> SearchResult:  # fmt: skip
        vv = np.ascontiguousarray(v, dtype=np.float64)
        ub = np.ascontiguousarray(ubar, dtype=np.float64)
        n = ub.shape[0]
        if len(guess) == n:
            best = np.asarray(guess, dtype=np.int64)
            radius = distance(vv, ub, best)
        else:
            radius, best = math.inf, np.zeros(0, np.int64)
        lv = np.asarray(levels, dtype=np.int64)
        u, d, nodes, complete = decode(vv, ub, radius, best, lv, budget)
        return SearchResult(tuple(int(x) for x in u), float(d), int(nodes), bool(complete))

    return sphere_decode


#: direct_mpc's decision: (model, N, state, I_b, λ_u, u_prev, guess, budget) → SearchResult
DirectMPC = Callable[..., SearchResult]


def compiled_direct_mpc() -> DirectMPC:
    """:func:`~.mpc_pmsm.solve` compiled; ImportError (with the reason) without numba."""
    reason = kernel_unavailable()
    if reason is not None:
        raise ImportError(reason)
    kernel = _kernels()[2]
    empty = np.zeros(0, np.int64)

    def solve(
        model: Sequence[float],
        n: int,
        state: Sequence[float],
        i_base: float,
        lam: float,
        prev: Sequence[int],
        guess: Sequence[int],
        budget: int,
    ) -> SearchResult:
        # the model, the state and u_prev as tuples (of floats, ints): numba takes a tuple
        # faster than it takes a new array
        u, d, nodes, complete = kernel(
            model, n, state, i_base, lam, prev, np.array(guess, np.int64) if guess else empty,
            budget,
        )  # fmt: skip
        return SearchResult(tuple(u.tolist()), float(d), int(nodes), bool(complete))

    return solve


def compiled_problem() -> Callable[..., tuple[np.ndarray, np.ndarray]]:
    """:func:`~.mpc_pmsm.problem`'s (V, ū) compiled (for the tests that hold the two
    together)."""
    reason = kernel_unavailable()
    if reason is not None:
        raise ImportError(reason)
    kernel = _kernels()[3]

    def problem(model: Any, n: int, state: Any, i_base: float, lam: float, prev: Any) -> Any:
        return kernel(model, n, state, i_base, lam, prev)

    return problem


#: branch and bound over a family's stages: (kind, constants, root, code, V·(Ts), λ_sw costs,
#: codes after, rotor turns, N, guess, budget) → SearchResult
BranchAndBound = Callable[..., SearchResult]


def compiled_branch_and_bound() -> BranchAndBound:
    """:func:`~.search.branch_and_bound` of :func:`~.mptc_im.horizon_stages`
    (:data:`IM_STAGE`) or :func:`~.mptc_pmsm.horizon_stages` (:data:`PMSM_STAGE`) compiled;
    ImportError (with the reason) without numba. The families give their stage's constants
    (``stage_constants``)."""
    reason = kernel_unavailable()
    if reason is not None:
        raise ImportError(reason)
    kernel = _kernels()[4]
    empty = np.zeros(0, np.int64)

    def search(
        kind: int,
        prm: Any,
        root: Any,
        code: int,
        volts: Any,
        full: Any,
        after: Any,
        turn: Any,
        horizon: int,
        guess: Sequence[int],
        budget: int,
    ) -> SearchResult:
        g = np.array(guess, np.int64) if guess else empty
        u, cost, nodes, complete = kernel(
            kind, prm, root, code, volts, full, after, turn, horizon, g, budget
        )
        return SearchResult(tuple(u.tolist()), float(cost), int(nodes), bool(complete))

    return search
