"""What every predictive torque controller shares, whatever the machine (SPEC §2.5, §3).

A controller owns the machine-side estimate and the command format; each step it asks its strategy
for a :class:`Decision` (vector, share of Ts, deadbeat time, predictions evaluated). The base class
here turns decisions into the per-phase pulse command, times the control law, and switches
strategies at a step boundary.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from enum import StrEnum
from time import perf_counter_ns
from typing import Any, NamedTuple, Protocol

from .inverter import active_then_zero, vector_voltages
from .signals import Command, Reference, State, new_record

__all__ = ["Decision", "Machine", "PredictiveController", "Strategy", "instantiate"]

INF = math.inf
NAN = math.nan
TWO_PI = 2.0 * math.pi


class Machine(StrEnum):
    INDUCTION = "induction"
    PMSM = "pmsm"


class Decision(NamedTuple):
    vector: int  #: 0..6
    fraction: float  #: share of Ts the vector is applied, 0..1 (rest: zero vector)
    t_u: float  #: raw deadbeat time, s (NaN if none was computed)
    cal: int  #: predictions evaluated


class Strategy(Protocol):
    name: str

    def decide(self, m: Any, torque_ref: float, flux_ref: float) -> Decision: ...


def instantiate(machine: Machine, registry: Mapping[str, type], name: str) -> Strategy:
    """Strategy ``name`` from one machine's registry; ValueError lists the valid names."""
    if name not in registry:
        raise ValueError(
            f"unknown strategy {name!r} for machine {machine.value!r}; valid: {', '.join(registry)}"
        )
    strategy: Strategy = registry[name]()
    return strategy


class PredictiveController:
    """``step(state k, reference k) -> command k`` for any machine.

    Subclasses set ``machine`` and ``strategies`` (name → class, in registry order) and implement
    :meth:`_observe`, the state estimate from the measurements (left in ``est_torque`` (N·m),
    ``est_flux`` (|ψ̂_s|, Wb) and ``est_flux_angle`` (rad, αβ, [0, 2π))), and :meth:`_decide`, the
    control law proper: prediction, cost and selection. Only :meth:`_decide` is timed
    (``compute_ns``): paper 001 Table 11 times the strategies from the estimated flux, torque angle
    and currents as inputs. :meth:`_applied` sees the decision after the command is formed.
    """

    machine: Machine
    strategies: Mapping[str, type]

    def __init__(self, strategy: str, *, ts: float) -> None:
        self.ts = ts
        self._names = tuple(self.strategies)
        self.set_strategy(strategy)
        self.switches = (0, 0, 0)
        self._u_dc = NAN
        self._volts: tuple[complex, ...] = ()
        self.est_torque = 0.0
        self.est_flux = 0.0
        self.est_flux_angle = 0.0

    def set_strategy(self, name: str) -> None:
        """Switch the control law; takes effect at the next step. ValueError if unknown."""
        self.strategy: Strategy = instantiate(self.machine, self.strategies, name)
        self._index = float(self._names.index(name))

    @property
    def strategy_index(self) -> int:
        return int(self._index)

    def _observe(self, state: State) -> None:
        raise NotImplementedError

    def _decide(self, state: State, ref: Reference) -> Decision:
        raise NotImplementedError

    def decision_inputs(self, states: list[State]) -> list[Any] | None:
        """What ``strategy.decide`` takes for each of ``states`` (its first argument), when the
        estimate is a function of the state alone; None when it has memory (the IM's flux
        integrator). For timing strategies on recorded cases, as paper 001 Table 11 does."""
        return None

    def _applied(self, d: Decision, state: State) -> None:
        """Hook after the decision (the IM integrates its flux estimate with the applied voltage)."""

    def step(self, state: State, ref: Reference) -> Command:
        if state.u_dc != self._u_dc:
            self._u_dc = state.u_dc
            self._volts = vector_voltages(state.u_dc)
        self._observe(state)
        t0 = perf_counter_ns()
        d = self._decide(state, ref)
        elapsed = perf_counter_ns() - t0
        vector, fraction, t_u, cal = d
        pulses, self.switches = active_then_zero(vector, fraction, self.switches)
        self._applied(d, state)
        return new_record(
            Command,
            (
                state.k,
                state.t,
                *pulses,
                self._index,
                float(vector),
                fraction,
                t_u,
                float(cal),
                self.est_torque,
                self.est_flux,
                self.est_flux_angle,
                float(elapsed),
            ),
        )
