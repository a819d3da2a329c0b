"""Statistics of many drawn drives (docs/reproduction.md#robustness): the mean of a figure with
its confidence interval by the t-distribution, the probability that a strategy ranks first with
its Wilson score interval, and the ranks themselves. Pure functions of numbers.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from statistics import NormalDist
from typing import NamedTuple

__all__ = [
    "Interval",
    "first_shares",
    "mean_interval",
    "student_t_cdf",
    "t_quantile",
    "wilson_interval",
]


class Interval(NamedTuple):
    """An estimate with its two-sided interval at ``level`` (NaN where there is none)."""

    value: float
    low: float
    high: float
    n: int  #: how many values (or trials) it rests on


def _betacf(a: float, b: float, x: float) -> float:
    """The continued fraction of the regularised incomplete beta function (modified Lentz)."""
    tiny = 1e-300
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * x / qap
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 400):
        m2 = 2 * m
        aa = m * (b - m) * x / ((qam + m2) * (a + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > tiny else tiny)
        c = 1.0 + aa / c
        c = c if abs(c) > tiny else tiny
        h *= d * c
        aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))
        d = 1.0 + aa * d
        d = 1.0 / (d if abs(d) > tiny else tiny)
        c = 1.0 + aa / c
        c = c if abs(c) > tiny else tiny
        step = d * c
        h *= step
        if abs(step - 1.0) < 1e-15:
            break
    return h


def _betainc(a: float, b: float, x: float) -> float:
    """I_x(a, b), the regularised incomplete beta function."""
    if x <= 0.0:
        return 0.0
    if x >= 1.0:
        return 1.0
    front = math.exp(
        math.lgamma(a + b) - math.lgamma(a) - math.lgamma(b) + a * math.log(x)
        + b * math.log1p(-x)
    )  # fmt: skip
    if x < (a + 1.0) / (a + b + 2.0):
        return front * _betacf(a, b, x) / a
    return 1.0 - front * _betacf(b, a, 1.0 - x) / b


def student_t_cdf(t: float, nu: float) -> float:
    """P(T <= t) for Student's t with ``nu`` degrees of freedom."""
    tail = 0.5 * _betainc(0.5 * nu, 0.5, nu / (nu + t * t))
    return 1.0 - tail if t >= 0.0 else tail


def t_quantile(p: float, nu: float) -> float:
    """The t with P(T <= t) = p, ``nu`` degrees of freedom (bisection of :func:`student_t_cdf`
    to 1e-12)."""
    if not 0.0 < p < 1.0 or nu <= 0.0:
        raise ValueError(f"t_quantile needs 0 < p < 1 and nu > 0, got p={p}, nu={nu}")
    if p < 0.5:
        return -t_quantile(1.0 - p, nu)
    lo, hi = 0.0, 1.0
    while student_t_cdf(hi, nu) < p:
        hi *= 2.0
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if student_t_cdf(mid, nu) < p:
            lo = mid
        else:
            hi = mid
        if hi - lo <= 1e-12 * hi:
            break
    return 0.5 * (lo + hi)


def mean_interval(values: Sequence[float], level: float = 0.95) -> Interval:
    """The mean of the finite ``values`` and its interval mean ± t_{(1+level)/2, n-1}·s/√n
    (the values independent draws; the t-distribution's, exact for normal values, close for
    others at n in the tens and more). NaN bounds below two values."""
    xs = [v for v in values if math.isfinite(v)]
    n = len(xs)
    if n == 0:
        return Interval(math.nan, math.nan, math.nan, 0)
    mean = math.fsum(xs) / n
    if n < 2:
        return Interval(mean, math.nan, math.nan, n)
    s = math.sqrt(math.fsum((x - mean) ** 2 for x in xs) / (n - 1))
    half = t_quantile(0.5 + 0.5 * level, n - 1) * s / math.sqrt(n)
    return Interval(mean, mean - half, mean + half, n)


def wilson_interval(successes: float, trials: int, level: float = 0.95) -> Interval:
    """A probability estimated as successes/trials, with the Wilson score interval: the p whose
    normal test |p̂ - p| <= z·sqrt(p(1 - p)/n) accepts (it stays inside [0, 1] and is not empty
    at p̂ = 0 or 1, unlike p̂ ± z·sqrt(p̂(1 - p̂)/n))."""
    if trials <= 0:
        return Interval(math.nan, math.nan, math.nan, 0)
    z = NormalDist().inv_cdf(0.5 + 0.5 * level)
    n, p = trials, successes / trials
    z2 = z * z
    centre = (p + z2 / (2 * n)) / (1 + z2 / n)
    half = z * math.sqrt(p * (1 - p) / n + z2 / (4 * n * n)) / (1 + z2 / n)
    low = 0.0 if successes <= 0 else max(0.0, centre - half)  # rounding aside: 0 at p̂ = 0
    high = 1.0 if successes >= trials else min(1.0, centre + half)
    return Interval(p, low, high, n)


def first_shares(draws: Sequence[Mapping[str, float]]) -> tuple[dict[str, float], int]:
    """How often each strategy ranks first (the lowest figure) over the draws, each draw a
    strategy → figure mapping (common random numbers: every strategy on the same drive). A tie
    for first shares that draw equally; a draw with no finite figure counts for none. Returns
    (strategy → firsts, draws counted)."""
    names = list(dict.fromkeys(s for d in draws for s in d))
    firsts = dict.fromkeys(names, 0.0)
    counted = 0
    for d in draws:
        finite = {s: v for s, v in d.items() if math.isfinite(v)}
        if not finite:
            continue
        best = min(finite.values())
        tied = [s for s, v in finite.items() if v == best]
        for s in tied:
            firsts[s] += 1.0 / len(tied)
        counted += 1
    return firsts, counted
