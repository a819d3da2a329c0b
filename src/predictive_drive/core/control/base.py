"""What every inner controller shares, whatever its family
(docs/physics.md#what-the-controller-sees; docs/physics.md).

A controller turns state k and reference k into command k: it estimates what it needs from the
measurements, runs its control law (the strategy in force; the only part timed), and modulates
the law's output into the per-phase pulses every plant understands, plus the diagnostics the
command carries (:data:`~predictive_drive.core.signals.COMMAND_DIAGNOSTICS`). A law may hand back
a voltage vector and its share of Ts (the MPTC families, :class:`VectorController`) or a voltage
reference turned into three duties (SVPWM); the base does not care which.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from time import perf_counter_ns
from typing import Any, ClassVar, NamedTuple, Protocol

import numpy as np

from ...errors import ConfigError
from ..fields import choice, flag, quantity
from ..inverter import VECTOR_STATES, active_then_zero, clarke, vector_voltages
from ..machines import Machine
from ..machines.pmsm import PMSMCoefficients, pmsm_exact_step, pmsm_predict_current
from ..signals import Command, PhasePulses, Reference, State, new_record
from .kernels import kernel_unavailable
from .search import SearchResult

__all__ = [
    "AFTER",
    "AFTER_TABLE",
    "NO_EFFORT_TABLE",
    "NO_EFFORT",
    "NODE_BUDGET",
    "budget_field",
    "compiled",
    "rows",
    "search_field",
    "SEARCHES",
    "PREDICTIONS",
    "SWITCHABLE",
    "Controller",
    "check_horizon",
    "horizon_field",
    "parse_switch",
    "prediction_field",
    "SwitchingEffort",
    "lambda_sw_field",
    "pmsm_predicted",
    "Decision",
    "Strategy",
    "VectorController",
    "delay_compensation",
    "instantiate",
]


def pmsm_predicted(
    c: PMSMCoefficients, ts: float, state: State, u_ab: complex, *, rotor_motion: bool = False
) -> State:
    """A PMSM family's :meth:`Controller._predict`: the measured current and angle one period
    ahead under ``u_ab`` by the model ``c`` — forward Euler in dq, or with ``rotor_motion`` the
    period solved exactly at the measured speed (:func:`~..machines.pmsm.pmsm_exact_step`)."""
    i_ab, omega_m = complex(state.i_alpha, state.i_beta), state.omega_m
    exact = pmsm_exact_step(c, ts, c.p * omega_m) if rotor_motion else None
    i, the = pmsm_predict_current(c, ts, i_ab, state.theta_e, omega_m, u_ab, exact=exact)
    return state._replace(i_alpha=i.real, i_beta=i.imag, theta_e=the % TWO_PI)


#: how a PMSM finite-control-set family predicts the end of a period
#: (docs/physics.md#predicting-the-pmsm-over-a-period)
PREDICTIONS = ("frozen_rotor", "rotor_motion")


def prediction_field() -> Any:
    """The ``prediction`` field of the PMSM finite-control-set families (``mptc_pmsm``,
    ``mpc_pmsm``): paper 001's model with the rotor frozen over the period, or the rotor's
    motion through it."""
    return choice(
        "the model's period: frozen_rotor (paper 001: the currents at the period's end taken "
        "at the rotor angle of its start, or forward Euler in dq for direct_mpc) or "
        "rotor_motion (the rotor turning through the period at the measured speed)",
        PREDICTIONS,
        default="frozen_rotor",
    )


def delay_compensation() -> Any:
    """The ``delay_compensation`` field every family's settings have."""
    return flag(
        "compensate one period of computation delay: predict the state at k+1 with the command "
        "in force, decide for the period after (plant.actuation_delay_steps)"
    )


NAN = math.nan
TWO_PI = 2.0 * math.pi


def lambda_sw_field(unit: str) -> Any:
    """The ``lambda_sw`` field of a finite-control-set family: its cost per leg commutation, in
    the unit of the family's cost (docs/physics.md#switching-effort)."""
    return quantity(
        "switching-effort weight: cost per leg commutation a candidate causes from the switching "
        "state in force, the return to the zero vector within the period included (0: none)",
        unit,
        ge=0,
        default=0.0,
    )


def _legs(a: tuple[int, int, int], b: tuple[int, int, int]) -> int:
    return sum(x != y for x, y in zip(a, b))


class SwitchingEffort:
    """λ_sw × the leg commutations each candidate causes (docs/physics.md#switching-effort),
    tabulated once per weight by the switching state in force (its code S_a·4 + S_b·2 + S_c).

    ``full[code][n]``: vector n for the whole period (V0: the zero vector nearer to the state in
    force, as :func:`~..inverter.active_then_zero` picks it); ``then_zero[code][n]``: vector
    n ≥ 1 for part of the period, then the zero vector nearer to it (always one leg more).
    """

    def __init__(self, weight: float) -> None:
        self.weight = weight
        states = [((c >> 2) & 1, (c >> 1) & 1, c & 1) for c in range(8)]
        full, then_zero = [], []
        for prev in states:
            on = sum(prev)
            zero = min(on, 3 - on)
            legs = [zero, *(_legs(prev, VECTOR_STATES[n]) for n in range(1, 7))]
            full.append(tuple(weight * x for x in legs))
            then_zero.append(tuple(weight * (x + (n > 0)) for n, x in enumerate(legs)))
        self.full: tuple[tuple[float, ...], ...] = tuple(full)
        self.then_zero: tuple[tuple[float, ...], ...] = tuple(then_zero)

    @staticmethod
    def code(switches: tuple[int, int, int]) -> int:
        return switches[0] * 4 + switches[1] * 2 + switches[2]

    def applied(self, code: int, vector: int, fraction: float) -> float:
        """The cost of vector ``vector`` applied for ``fraction`` of Ts, then the zero vector."""
        if vector == 0 or fraction <= 0.0:
            return self.full[code][0]
        return self.full[code][vector] if fraction >= 1.0 else self.then_zero[code][vector]


#: what a running controller lets a live parameter change: its law and, for families with long
#: horizons, the horizon N (docs/physics.md#long-horizons)
SWITCHABLE = ("strategy", "horizon")


def horizon_field(strategies: str, maximum: int) -> Any:
    """The ``horizon`` field of a family whose laws ``strategies`` look N periods ahead."""
    return quantity(
        f"prediction horizon N, periods the cost sums over ({strategies}; 1: one step, the "
        f"papers' law); switchable at run time",
        ge=1,
        le=maximum,
        integer=True,
        default=1,
    )


#: the long horizons' default budget a step (docs/physics.md#a-budget-per-step): at N = 10
#: about three times the median search's nodes on ipmsm_steady_mpc, so the slowest step takes
#: about three times the median's time; an exact search finishes below it at N ≤ 5
NODE_BUDGET = 8000


def budget_field(unit: str, default: int) -> Any:
    """The ``node_budget`` field of a family with long horizons: the most ``unit`` a step's
    search evaluates (docs/physics.md#a-budget-per-step)."""
    return quantity(
        f"the most {unit} a step's search evaluates once it holds a complete sequence; "
        "then the best found so far is applied and the step counted suboptimal (0: no limit)",
        ge=0,
        integer=True,
        default=default,
    )


#: which implementation of a long horizon's search runs (:mod:`.kernels`)
SEARCHES = ("auto", "compiled", "python")


def search_field(what: str) -> Any:
    """The field that picks a long horizon's search: ``what`` compiled (numba), in Python (the
    reference) or auto (compiled where numba is installed); all decide alike, bit for bit."""
    return choice(
        f"{what}: compiled (numba), python (the reference), or auto (compiled where numba is "
        "installed); every one decides the same, bit for bit",
        SEARCHES,
        default="auto",
    )


def compiled(
    name: str, key: str, factory: Callable[[], Callable[..., SearchResult]]
) -> Callable[..., SearchResult] | None:
    """The compiled search ``factory`` makes where ``name`` (one of :data:`SEARCHES`) asks for
    it and numba is installed — made at its first call, so a controller that never searches
    never imports numba (a second or so); None for the Python reference; ConfigError (naming
    ``torque_controller.<key>``) for ``compiled`` without numba."""
    if name == "python":
        return None
    reason = kernel_unavailable()
    if reason is not None:
        if name == "compiled":
            raise ConfigError(f"torque_controller.{key}: compiled, but {reason}")
        return None
    made: list[Callable[..., SearchResult]] = []

    def search(*args: Any) -> SearchResult:
        if not made:
            made.append(factory())
        return made[0](*args)

    return search


def rows(values: Sequence[complex]) -> np.ndarray:
    """Complex numbers as rows (real, imaginary): how a compiled search takes them."""
    return np.array([(v.real, v.imag) for v in values])


def check_horizon(params: Any, strategies: tuple[str, ...]) -> None:
    """ConfigError if ``params`` (a family's settings) give a horizon to a law without one."""
    if params.horizon > 1 and params.strategy not in strategies:
        raise ConfigError(
            f"torque_controller.horizon {params.horizon}: {params.strategy} looks one period "
            f"ahead; only {', '.join(strategies)} take a horizon (1..N)"
        )


def parse_switch(text: str) -> tuple[str, Any]:
    """A switch as the command line and the launcher write it: a strategy's name, or
    ``horizon=N`` → (parameter, value); ValueError for a value that is not a whole number."""
    key, sep, value = text.partition("=")
    if not sep:
        return "strategy", text
    if key != "horizon":
        raise ValueError(
            f"{text!r}: a switch is a strategy's name or horizon=N (the settings a running "
            f"controller changes: {', '.join(SWITCHABLE)})"
        )
    try:
        return key, int(value)
    except ValueError:
        raise ValueError(f"{text!r}: horizon=N takes a whole number of periods") from None


#: the switching effort's costs when λ_sw = 0 (adding 0.0 changes no cost)
NO_EFFORT = (0.0,) * 7
#: the switching state's code after vector n for the whole period from the state of code c
#: (``AFTER[c][n]``): the vector's, or for V0 the zero vector nearer to c
AFTER = tuple(
    tuple((7 if bin(c).count("1") >= 2 else 0) if n == 0 else SwitchingEffort.code(
        VECTOR_STATES[n]) for n in range(7))
    for c in range(8)
)  # fmt: skip
#: :data:`AFTER` and no switching effort, as a compiled search takes them
AFTER_TABLE = np.array(AFTER, np.int64)
NO_EFFORT_TABLE = np.zeros((8, 7))


class Strategy(Protocol):
    """A control law of a family; each family states what its laws are asked (``decide``)."""

    name: str


def instantiate(family: str, registry: Mapping[str, type], name: str) -> Any:
    """Strategy ``name`` from one family's registry; ValueError lists the valid names."""
    if name not in registry:
        raise ValueError(
            f"unknown strategy {name!r} for controller family {family!r}; "
            f"valid: {', '.join(registry)}"
        )
    return registry[name]()


class Controller:
    """``step(state k, reference k) -> command k``; the base of every controller family.

    A family's class sets ``family`` (its registry name), ``machine`` (the machine its model
    describes), ``params_type`` (its settings dataclass, with ``motor`` and ``strategy``) and
    ``strategies`` (name → class, in registry order: the ``strategy`` index of the commands), and
    implements :meth:`_observe` (the estimate from the measurements), :meth:`_decide` (the law
    proper, the only part timed into ``compute_ns``) and :meth:`_command` (the law's output →
    the command: pulses and the diagnostic fields). :meth:`_dc_link` sees the measured DC-link
    voltage whenever it changes. Strategies switch at a step boundary.

    With ``delay_compensation`` (docs/physics.md#computation-delay) the command k acts during
    period k+1: the family's :meth:`_predict` turns the measured state k into the state at k+1
    under the voltage of the command in force during period k (the one issued at k-1), and the
    law decides on that, as Cortés et al. (IEEE TIE 2012) do.
    """

    family: ClassVar[str]
    machine: ClassVar[Machine]
    params_type: ClassVar[type]
    strategies: ClassVar[Mapping[str, type]]
    #: the strategies that look ``horizon`` periods ahead, and the largest horizon
    horizon_strategies: ClassVar[tuple[str, ...]] = ()
    max_horizon: ClassVar[int] = 1

    def __init__(self, params: Any, *, ts: float) -> None:
        self.params = params
        self.ts = ts
        self._names = tuple(self.strategies)
        self.horizon = int(getattr(params, "horizon", 1))  #: N, periods
        self.set_strategy(params.strategy)
        self._u_dc = NAN
        self._compensate = bool(getattr(params, "delay_compensation", False))
        self.u_in_force = 0j  #: average αβ voltage of the command acting this period, V

    def refusal(self, name: str) -> str | None:
        """Why strategy ``name`` cannot run in this controller, in words (None: it can). A
        live switch asks this first and is refused with it, the running strategy staying."""
        if name not in self.strategies:
            return (
                f"unknown strategy {name!r} for controller family {self.family!r}; "
                f"valid: {', '.join(self.strategies)}"
            )
        if self.horizon > 1 and name not in self.horizon_strategies:
            return (
                f"{name} looks one period ahead, and torque_controller.horizon is "
                f"{self.horizon} (a horizon for {', '.join(self.horizon_strategies)}): set "
                f"horizon 1 first"
            )
        return None

    def horizon_refusal(self, value: Any) -> str | None:
        """Why the horizon cannot become ``value`` (None: it can)."""
        if not self.horizon_strategies:
            return (
                f"controller family {self.family!r} has no horizon: its laws look one period ahead"
            )
        if isinstance(value, bool) or not isinstance(value, int):
            return f"torque_controller.horizon must be a whole number of periods, got {value!r}"
        if not 1 <= value <= self.max_horizon:
            return f"torque_controller.horizon must be 1..{self.max_horizon} (periods), got {value}"
        if value > 1 and self.strategy.name not in self.horizon_strategies:
            return (
                f"torque_controller.horizon {value}: {self.strategy.name} looks one period "
                f"ahead; only {', '.join(self.horizon_strategies)} take a horizon"
            )
        return None

    def switch_refusal(self, key: str, value: Any) -> str | None:
        """Why a live change of ``key`` (one of :data:`SWITCHABLE`) to ``value`` cannot be made
        (None: it can); the running setting stays."""
        if key == "strategy":
            return self.refusal(str(value))
        return self.horizon_refusal(value)

    def switch(self, key: str, value: Any) -> None:
        """Change ``key`` (one of :data:`SWITCHABLE`) at the next step; ValueError (the
        :meth:`switch_refusal`) if it cannot."""
        if key == "strategy":
            self.set_strategy(str(value))
            return
        reason = self.horizon_refusal(value)
        if reason is not None:
            raise ValueError(reason)
        self.horizon = int(value)
        self._horizon_set()

    def _horizon_set(self) -> None:
        """The horizon changed (a family with a plan from the last decision drops it)."""

    @property
    def law_horizon(self) -> float:
        """The horizon of the law in force (NaN for a law without one): the command's field."""
        return float(self.horizon) if self.strategy.name in self.horizon_strategies else NAN

    def set_strategy(self, name: str) -> None:
        """Switch the control law; takes effect at the next step. ValueError (the
        :meth:`refusal`) if it cannot run here."""
        reason = self.refusal(name)
        if reason is not None:
            raise ValueError(reason)
        self.strategy: Any = instantiate(self.family, self.strategies, name)
        self._index = float(self._names.index(name))
        self._horizon_set()

    def _dc_link(self, u_dc: float) -> None:
        """The measured DC-link voltage (V) changed (and at the first step)."""

    def _observe(self, state: State) -> None:
        raise NotImplementedError

    def _predict(self, state: State, u_ab: complex) -> State:
        """State k with its measured currents and angle moved one period ahead under the
        average voltage ``u_ab`` (V, αβ): what the law sees with delay compensation."""
        raise NotImplementedError

    def _decide(self, state: State, ref: Reference) -> Any:
        raise NotImplementedError

    def _command(self, out: Any, state: State, compute_ns: float) -> Command:
        """Command k from the law's output: :meth:`command` of its pulses and diagnostics."""
        raise NotImplementedError

    def command(
        self,
        state: State,
        pulses: PhasePulses,
        diagnostics: tuple[float, ...],
        compute_ns: float,
        suboptimal: float = NAN,
    ) -> Command:
        """The command record: the diagnostics are the command's
        :data:`~predictive_drive.core.signals.COMMAND_DIAGNOSTICS` but ``suboptimal`` (a
        search's budget, NaN: no search), in that order."""
        return new_record(
            Command,
            (state.k, state.t, *pulses, self._index, *diagnostics, suboptimal, compute_ns),
        )

    def decision_inputs(self, states: list[State]) -> list[Any] | None:
        """What ``strategy.decide`` takes for each of ``states`` (its first argument), when the
        estimate is a function of the state alone; None when it has memory. For timing strategies
        on recorded cases, as paper 001 Table 11 does."""
        return None

    def step(self, state: State, ref: Reference) -> Command:
        if state.u_dc != self._u_dc:
            self._u_dc = state.u_dc
            self._dc_link(state.u_dc)
        if self._compensate:
            state = self._predict(state, self.u_in_force)
        self._observe(state)
        t0 = perf_counter_ns()
        out = self._decide(state, ref)
        elapsed = perf_counter_ns() - t0
        cmd = self._command(out, state, float(elapsed))
        if self._compensate:  # a leg's average voltage over the period is its duty·U_dc
            self.u_in_force = state.u_dc * clarke(cmd.duty_a, cmd.duty_b, cmd.duty_c)
        return cmd


class Decision(NamedTuple):
    """A finite-control-set law's choice: a voltage vector for a share of Ts, then zero."""

    vector: int  #: 0..6
    fraction: float  #: share of Ts the vector is applied, 0..1 (rest: zero vector)
    t_u: float  #: raw deadbeat time, s (NaN if none was computed)
    cal: int  #: predictions evaluated
    #: a long horizon's search: 1.0 if its budget ran out, 0.0 if it finished; NaN: none
    suboptimal: float = NAN


class VectorController(Controller):
    """The MPTC families: the law picks a :class:`Decision`; it is applied as the vector for its
    share of Ts and then the zero vector (000 or 111, whichever needs fewer switch changes).

    :meth:`_observe` leaves the estimate the command reports in ``est_torque`` (N·m),
    ``est_flux`` (|ψ̂_s|, Wb) and ``est_flux_angle`` (rad, αβ, [0, 2π)); ``_volts`` holds V0..V6
    for the measured DC link. :meth:`_applied` sees the decision after the command is formed.
    """

    def __init__(self, params: Any, *, ts: float) -> None:
        super().__init__(params, ts=ts)
        self.switches = (0, 0, 0)
        self._volts: tuple[complex, ...] = ()
        self.est_torque = 0.0
        self.est_flux = 0.0
        self.est_flux_angle = 0.0

    def _dc_link(self, u_dc: float) -> None:
        self._volts = vector_voltages(u_dc)

    def _applied(self, d: Decision, state: State) -> None:
        """Hook after the decision (the IM integrates its flux estimate with the applied voltage)."""

    def _command(self, d: Decision, state: State, compute_ns: float) -> Command:
        vector, fraction, t_u, cal, suboptimal = d
        pulses, self.switches = active_then_zero(vector, fraction, self.switches)
        self._applied(d, state)
        # built in one piece (not through command()): this is every MPTC step's hot path
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
                self.law_horizon,
                self.est_torque,
                self.est_flux,
                self.est_flux_angle,
                NAN,  # current_angle, i_d_ref, i_q_ref, mtpa_gradient: field-oriented only
                NAN,
                NAN,
                NAN,
                suboptimal,
                compute_ns,
            ),
        )
