"""The controller replay harness: a recording's inputs fed again through a fresh controller, to
time its strategies on the run's own cases (paper 001 Table 11) and check it decides as recorded."""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..core.runner import build_controller
from ..core.signals import Reference, State
from ..readback import read_bag
from ..recording import scenario_of

__all__ = ["controller_replay"]


def controller_replay(
    bags: Sequence[str | Path], *, repeats: int = 5, chunk: int = 500
) -> list[dict[str, Any]]:
    """Time runs' strategies on the runs' own inputs, as paper 001 Table 11 does (recorded cases,
    counts × per-case time).

    Each run's recorded states and references are fed again through a fresh controller. Two
    figures per run, both per step and the median over ``repeats``: ``hot_ns`` times the strategy's
    decisions alone in a tight loop over the recorded estimates (where the estimate is a function
    of the state: PMSM) — the paper's method — less the harness's own cost per case (the same loop
    without the decision, timed after each chunk; the median over chunks, so a preempted one
    cannot eat into the decision time); ``loop_ns`` sums the per-step ``compute_ns`` of the controller
    stepping through the run (every engine's figure, caches cooled by the rest of each step).
    The runs are replayed side by side, ``chunk`` steps of each in turn, so a slow spell of this
    noisy machine hits all of them alike; ratios are per repeat against the first bag,
    then the median. Also checks that every replay decides as recorded."""
    runs = []
    for bag in bags:
        trace, info = read_bag(bag)
        sc = scenario_of(info.info, info.path)
        n = trace.steps
        states = [State(*row) for row in trace.state[:n].tolist()]
        refs = [Reference(*row) for row in trace.reference[:n].tolist()]
        ctrl = build_controller(sc)
        inputs = ctrl.decision_inputs(states)
        cases = None
        if inputs is not None:
            cases = [(m, r.torque_ref, r.flux_ref) for m, r in zip(inputs, refs)]
        runs.append((sc, states, refs, trace.col("command", "vector"), cases))
    loop: list[list[float]] = [[] for _ in runs]
    hot: list[list[float]] = [[] for _ in runs]
    identical = [True] * len(runs)
    longest = max(len(r[1]) for r in runs)
    harness: list[float] = []  # ns per case of the bare timing loop, per chunk
    for _ in range(repeats):
        ctrls = [build_controller(sc) for sc, *_ in runs]
        loop_t = [0.0] * len(runs)
        hot_t = [0.0] * len(runs)
        vectors: list[list[float]] = [[] for _ in runs]
        for lo in range(0, longest, chunk):
            for j, (_, states, refs, _, inputs) in enumerate(runs):
                step = ctrls[j].step
                total = 0.0
                out = vectors[j]
                for s, ref in zip(states[lo : lo + chunk], refs[lo : lo + chunk]):
                    c = step(s, ref)
                    total += c.compute_ns
                    out.append(c.vector)
                loop_t[j] += total
                if inputs is not None:
                    decide = ctrls[j].strategy.decide
                    part = inputs[lo : lo + chunk]
                    t0 = time.perf_counter_ns()
                    for m, t_ref, psi_ref in part:
                        decide(m, t_ref, psi_ref)
                    t1 = time.perf_counter_ns()
                    for _m, _t, _p in part:  # the harness alone: same unpacking, no decision
                        pass
                    harness.append((time.perf_counter_ns() - t1) / len(part))
                    hot_t[j] += t1 - t0
        for j, (_, states, _, recorded, inputs) in enumerate(runs):
            loop[j].append(loop_t[j] / len(states))
            hot[j].append(hot_t[j] / len(states) if inputs is not None else math.nan)
            identical[j] = identical[j] and bool(np.array_equal(np.asarray(vectors[j]), recorded))

    per_case = float(np.median(harness)) if harness else 0.0
    hot = [[t - per_case for t in h] for h in hot]  # NaN stays NaN

    def ratio(times: list[float], base: list[float]) -> float:
        return float(np.median(np.asarray(times) / np.asarray(base)))

    return [
        {
            "hot_ns": float(np.median(hot[j])),
            "loop_ns": float(np.median(loop[j])),
            "hot_ratio": ratio(hot[j], hot[0]),
            "loop_ratio": ratio(loop[j], loop[0]),
            "loop_runs_ns": loop[j],
            "hot_runs_ns": hot[j],
            "identical": identical[j],
            "steps": len(runs[j][1]),
        }
        for j in range(len(runs))
    ]
