"""Analyses of a recorded run beyond its metrics.

Vector utilization (paper 001 §3-5, docs/physics.md#utilization-analysis): how often each voltage
vector was chosen by torque-error band, by flux sector × torque-error sign and by 12 sectors ×
torque- and flux-error sign, and the candidate sets a stated rule derives from that. This is how the
simplified strategies were designed; here it is a function of a recording.

Errors are the controller's own: ΔT = T* - T̂ and Δψ = ψ* - |ψ̂| at each step, the sector that of ψ̂
(all recorded in the command and reference records), so the tables describe what the strategy saw.

Load steps (the MTPA study, docs/physics.md#field-oriented-control-and-mtpa): the measured current
angle and amplitude each load settles to, and how long the angle took.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from .metrics import step_window
from .trace import Trace

__all__ = [
    "BANDS",
    "DERIVATION_RULE",
    "MIN_RELATIVE",
    "LoadStep",
    "Utilization",
    "derive_candidates",
    "load_steps",
    "measured_current_angle",
    "utilization",
]

#: torque-error bands of paper 001 Table 1, N·m: |ΔT| ≤ b
BANDS = tuple(round(0.1 * i, 1) for i in range(1, 16))
#: a non-zero vector is a candidate of a class when it was chosen at least this many times as often
#: as the class's most chosen vector (on the spmsm_analysis strategy-1 run the kept vectors lie at
#: >= 0.20 and the dropped ones at <= 0.12 of it)
MIN_RELATIVE = 0.15
DERIVATION_RULE = (
    f"keep V0 and every non-zero vector chosen in at least {MIN_RELATIVE:.0%} as many of the class's steps "
    "as the class's most chosen non-zero vector (class = flux sector x sign of dT [x sign of "
    "dpsi]; steps with |dT| > threshold)"
)


@dataclass(frozen=True)
class Utilization:
    """Counts of chosen vectors. ``bands``: (b, N, N_V0) for |ΔT| ≤ b and (inf, N, N_V0) for all.
    ``six[t, s, v]``: steps with ΔT > th (t = 0) or ΔT < -th (t = 1), 6-sector s, vector v.
    ``twelve[t, f, s, v]``: as ``six`` with the flux-error sign f (0: Δψ ≥ 0, 1: Δψ < 0) and 12
    sectors."""

    threshold: float
    steps: int
    bands: tuple[tuple[float, int, int], ...]
    six: np.ndarray
    twelve: np.ndarray

    def shares(self, counts: np.ndarray) -> np.ndarray:
        """Utilization η = N_i / N per class (last axis: vectors), 0 where a class is empty."""
        n = counts.sum(axis=-1, keepdims=True)
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(n > 0, counts / np.maximum(n, 1), 0.0)


def utilization(
    trace: Trace, *, threshold: float, t_start: float = 0.0, t_end: float = math.inf
) -> Utilization:
    """Tabulate the vectors a run chose (paper 001 Tables 1 and 3-8)."""
    k0, k1 = step_window(trace, t_start, t_end)
    d_t = trace.col("reference", "torque_ref")[k0:k1] - trace.col("command", "torque_est")[k0:k1]
    d_psi = trace.col("reference", "flux_ref")[k0:k1] - trace.col("command", "flux_est")[k0:k1]
    angle = np.mod(trace.col("command", "flux_angle")[k0:k1], 2.0 * math.pi)
    vec = trace.col("command", "vector")[k0:k1].astype(np.int64)
    bands = []
    for b in BANDS:
        inside = np.abs(d_t) <= b + 1e-12
        bands.append((b, int(inside.sum()), int(np.count_nonzero(inside & (vec == 0)))))
    bands.append((math.inf, int(vec.size), int(np.count_nonzero(vec == 0))))
    sign_t = np.where(d_t > threshold, 0, np.where(d_t < -threshold, 1, -1))
    sign_f = (d_psi < 0).astype(np.int64)
    above = sign_t >= 0
    # the controller's sector(): an angle that rounds to 360° is 0°
    s6 = (angle / (2.0 * math.pi / 6)).astype(np.int64) % 6
    s12 = (angle / (2.0 * math.pi / 12)).astype(np.int64) % 12
    six = np.zeros((2, 6, 7), dtype=np.int64)
    np.add.at(six, (sign_t[above], s6[above], vec[above]), 1)
    twelve = np.zeros((2, 2, 12, 7), dtype=np.int64)
    np.add.at(twelve, (sign_t[above], sign_f[above], s12[above], vec[above]), 1)
    return Utilization(threshold, int(vec.size), tuple(bands), six, twelve)


def derive_candidates(counts: np.ndarray, *, min_relative: float = MIN_RELATIVE) -> list[Any]:
    """Candidate sets from per-class vector counts (any leading shape, last axis V0..V6) by
    :data:`DERIVATION_RULE`; nested lists of ascending vector numbers, V0 always first (the zero
    vector is always a candidate: strategies 2 and 3 keep it, paper 001 §4-5)."""
    out = np.empty(counts.shape[:-1], dtype=object)
    for idx in np.ndindex(*counts.shape[:-1]):
        c = counts[idx]
        top = c[1:].max()
        keep = [0] + [v for v in range(1, 7) if top and c[v] >= min_relative * top]
        out[idx] = keep
    result: list[Any] = out.tolist()
    return result


@dataclass(frozen=True)
class LoadStep:
    """How a run settled after one load step (the MTPA study,
    docs/physics.md#field-oriented-control-and-mtpa).

    ``theta`` (rad) and ``i_s`` (A) are means over the step's second half of the *measured*
    current angle from the q axis, atan2(-i_d, |i_q|), and amplitude |i_αβ|; ``settle_s`` is the
    time from the step until the measured angle, averaged over ``average_s``, stays within
    ``band`` rad of ``theta`` for the rest of the step."""

    load_torque: float
    t_start: float
    t_end: float
    theta: float
    i_s: float
    settle_s: float


def measured_current_angle(trace: Trace) -> np.ndarray:
    """atan2(-i_d, |i_q|) of the current at every state, rad (rotor frame by θ_e; the true
    current and angle where sensors measure them)."""
    i = trace.truth("i_alpha") + 1j * trace.truth("i_beta")
    i_dq = i * np.exp(-1j * trace.truth("theta_e"))
    return np.arctan2(-i_dq.real, np.abs(i_dq.imag))


def load_steps(
    trace: Trace,
    *,
    load_times: tuple[float, ...],
    load_values: tuple[float, ...],
    band: float = math.radians(0.5),
    average_s: float = 2e-3,
) -> list[LoadStep]:
    """One :class:`LoadStep` per load of the scenario's profile that the run covers."""
    ts = trace.ts
    n = trace.steps
    t = np.arange(n) * ts
    theta = measured_current_angle(trace)[:n]
    amp = np.hypot(trace.truth("i_alpha"), trace.truth("i_beta"))[:n]
    w = max(1, round(average_s / ts))
    smooth = np.convolve(theta, np.ones(w) / w, mode="full")[:n]
    out = []
    ends = (*load_times[1:], math.inf)
    for start, end, value in zip(load_times, ends, load_values):
        if start >= n * ts:
            break  # the run (or its recording) ends before this load
        end = min(end, n * ts)
        k0, k1 = step_window(trace, start, end)
        half = step_window(trace, 0.5 * (start + end), end)
        final = float(theta[half[0] : half[1]].mean())
        seg = smooth[k0 + w : k1]  # a full averaging window after the step
        outside = np.flatnonzero(np.abs(seg - final) > band)
        settle = float((outside[-1] + 1 + w) * ts) if outside.size else w * ts
        out.append(
            LoadStep(
                load_torque=float(value),
                t_start=float(t[k0]),
                t_end=float(k1 * ts),
                theta=final,
                i_s=float(amp[half[0] : half[1]].mean()),
                settle_s=settle,
            )
        )
    return out
