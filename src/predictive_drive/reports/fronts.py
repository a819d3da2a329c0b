"""The fronts study (``predictive-drive reproduce fronts``;
docs/reproduction.md#fronts-distortion-against-switching-frequency): each strategy's distortion
against its switching frequency at a steady operating point, traced over its switching-effort
knob and its control period, with field-oriented control and SVPWM as the baseline on the same
machine and point — the comparison power electronics accepts (Geyer & Quevedo, IEEE TPEL 2014,
2015; Karamanakos et al.).

A study is data: per operating point its scenarios (the MPTC family's and the FOC twin's, the
same drive: ``test_a_steady_point_is_the_same_drive_for_mptc_and_field_orientation``) and its
curves, each a strategy with the setting it is traced over and the values. Knobs:

- the finite-control-set strategies, the deadbeat ones too, over ``torque_controller.lambda_sw``
  (direct_mpc over its ``lambda_u``): at the papers' period, 50 µs, over the curve's values, and
  at :data:`PERIODS` — 20 to 500 µs, about 1.6 times apart — over its :data:`PERIOD_VALUES`
  smallest (the papers' law, λ = 0, and the next): the period sets how often the law may switch
  at all, the weight how much of that it uses, so the front reaches from about 2.5 times to a
  tenth of the papers' rate (roughly 0.5-10 kHz);
- field-oriented control over the control period ``ts``, which is its carrier period (f_sw =
  1/Ts), its current loop tuned at every period by the technical optimum (kp = L/(2·1.5·Ts)) and
  holding the period's mean current (``current_target: period_mean``,
  docs/physics.md#field-oriented-control-and-mtpa);
- the long horizons (mptc at N = 2, 3, 5 over λ_sw; direct_mpc at N = 1, 3, 5, 10 over its
  switching weight λ_u), one curve per N;
- mptc over its loss-aware weight ``torque_controller.lambda_e`` (``mptc lambda_e``: each
  candidate's commutations priced in joules by the point's device file,
  docs/physics.md#a-loss-aware-switching-cost), at the papers' period.

Every run has the drive's own inverter devices (``plant.losses.device``: the Si IGBT module
for paper 000's induction motor, the SiC MOSFET for the PMSMs, docs/physics.md#the-devices)
with the losses section's defaults (junction temperatures fed back every millisecond), so each
point has its inverter loss beside its f_sw: the fronts are read at equal switching frequency
(:data:`COMMON_FSW`) and at equal inverter loss (each point's :attr:`OperatingPoint.loss_columns`,
W), in one regime only (:func:`loss_reading`).

A point is on a front only if it holds the operating point: its mean torque within
:data:`TOLERANCE` of T*, its mean |ψ_s| of ψ* and its current's fundamental of the operating
point's current (the base of the TDD), all in continuous time.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "COMMON_FSW",
    "DIRECT_HORIZONS",
    "IGBT",
    "LOSS",
    "LOSS_SNAP",
    "SIC",
    "FRONTS",
    "KNOBS",
    "MAX_GAP",
    "MAX_SLOPE",
    "MPTC_HORIZONS",
    "PAPERS_TS",
    "PERIODS",
    "PERIOD_VALUES",
    "PREDICTION",
    "RANKED",
    "SHOWN",
    "SNAP_SHARE",
    "TOLERANCE",
    "Curve",
    "OperatingPoint",
    "interpolate",
    "joined",
    "loss_interpolate",
    "loss_reading",
    "mixed",
    "pareto",
    "reading",
]

#: the switching frequencies the table reads each front at, Hz
COMMON_FSW = (0.5e3, 1e3, 2e3, 3e3, 4e3, 5e3, 7e3, 10e3)
#: the figures of every point (metric keys), and those the fronts are drawn and ranked by: the
#: torque's ripple about its mean and its distortion against T* (T_RMSE cont), the current's
#: distortion over its own fundamental (THD) and over the operating point's current (TDD)
SHOWN = (
    "f_sw_hz", "t_ripple_cont", "t_rmse_cont", "i_thd_cont", "i_tdd_cont", "t_mean_error_cont",
    "psi_mean_error_cont", "i_fundamental_cont", "psi_rmse_cont", "t_rmse", "p_inverter",
    "p_cond_t", "p_cond_d", "p_sw_t", "p_sw_d", "tj_max",
)  # fmt: skip
#: the figure the fronts are read against besides f_sw: the inverter's losses (metric key)
LOSS = "p_inverter"
RANKED = ("t_ripple_cont", "t_rmse_cont", "i_thd_cont", "i_tdd_cont")
#: what holding the operating point asks of a run (shares): its mean torque against T*, its
#: mean |ψ_s| against ψ*, its current's fundamental against the operating point's current
TOLERANCE = {"torque": 0.02, "flux": 0.02, "current": 0.02}
#: a front is interpolated between neighbours at most this ratio apart in f_sw ...
MAX_GAP = 2.0
#: ... whose figures differ by no more than this power of their f_sw ratio (a steeper step is a
#: jump from one way of switching to another, not a front: across it the table says '-')
MAX_SLOPE = 3.0
#: a front's point within this share of a column's frequency is that column's value as measured
SNAP_SHARE = 0.03
#: a front's point within this share of a loss column is that column's value as measured (the
#: SiC drives' losses span a tenth of their value: closer than the f_sw columns)
LOSS_SNAP = 0.005
#: the papers' control period, s: the finite-control-set curves' values all run at it
PAPERS_TS = 5e-5
#: the other periods the finite-control-set curves run at, s, each over its smallest values:
#: from 20 to 500 µs about 1.6 times apart, so that a law's points at neighbouring periods lie
#: within :data:`MAX_GAP` of each other in f_sw
PERIODS = (2e-5, 3.2e-5, 8e-5, 1.25e-4, 2e-4, 3.2e-4, 5e-4)
PERIOD_VALUES = 2
#: the PMSM prediction the finite-control-set curves run with wherever their family has the
#: choice (``torque_controller.prediction``): the rotor's motion over the period compensated
#: (docs/physics.md), not paper 001's frozen rotor, whose torque prediction runs high
PREDICTION = "rotor_motion"
#: the settings a curve may be traced over, with the range each may take
KNOBS: dict[str, tuple[float, float]] = {
    "torque_controller.lambda_sw": (0.0, 1e3),
    "torque_controller.lambda_u": (1e-9, 1e3),
    "torque_controller.lambda_e": (0.0, 1e6),
    "ts": (1e-5, 1e-2),
}
#: the drives' inverter devices (config/devices): the Si IGBT module for paper 000's induction
#: motor (582 V DC link), the SiC MOSFET for the PMSMs (312 V, 400 V)
IGBT = "semikron_skm150gb124d"
SIC = "wolfspeed_c3m0065100j"

_LAMBDA = "torque_controller.lambda_sw"
#: 0.5 to 20 kHz carriers, no two more than twice apart
_FOC_TS = tuple(1e-3 / f for f in (0.5, 1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 15.0, 20.0))


def pareto(points: Sequence[tuple[float, float]]) -> list[bool]:
    """Which of (f_sw, figure) pairs lie on the front: no other pair has a lower-or-equal f_sw
    and a lower-or-equal figure, one of them lower. NaN pairs never do."""
    out = []
    for i, (f, v) in enumerate(points):
        if not (math.isfinite(f) and math.isfinite(v)):
            out.append(False)
            continue
        dominated = any(
            j != i and g <= f and w <= v and (g < f or w < v)
            for j, (g, w) in enumerate(points)
            if math.isfinite(g) and math.isfinite(w)
        )
        out.append(not dominated)
    return out


def joined(
    a: tuple[float, float], b: tuple[float, float], *, max_gap: float = MAX_GAP,
    max_slope: float = MAX_SLOPE,
) -> bool:  # fmt: skip
    """Whether two neighbouring front points (f_sw, figure), rising in f_sw, are one stretch of
    the front: at most ``max_gap`` times apart in f_sw, and one regime — the figure steps by no
    more than the ``max_slope`` power of their f_sw ratio (a steeper step is a jump from one way
    of switching to another)."""
    (f0, v0), (f1, v1) = a, b
    if not f0 < f1 <= max_gap * f0:
        return f0 == f1 and v0 == v1
    if v0 <= 0.0 or v1 <= 0.0:
        return True
    return abs(math.log(v1 / v0)) <= max_slope * math.log(f1 / f0)


def reading(
    front: Sequence[tuple[float, float]], f: float, *, snap: float = SNAP_SHARE,
    max_gap: float = MAX_GAP, max_slope: float = MAX_SLOPE,
    joins: Callable[[int], bool] | None = None,
) -> tuple[int, int, float] | None:  # fmt: skip
    """How the front (f_sw, figure) pairs, rising in f_sw, give its value at ``f`` Hz: (i, j,
    s), the value being front[i]'s and front[j]'s mixed by s in log f_sw — a point within
    ``snap`` of ``f`` as measured (i = j, s = 0), else the two neighbours that enclose ``f`` if
    :func:`joined` (``joins(i)``, where given: whether front[i] and front[i + 1] are one
    stretch); None where the front does not say."""
    if not front:
        return None
    near = min(range(len(front)), key=lambda i: abs(math.log(front[i][0] / f)))
    if abs(front[near][0] / f - 1.0) <= snap:
        return near, near, 0.0
    for i, ((f0, _), (f1, _)) in enumerate(zip(front, front[1:])):
        if f0 < f < f1:
            one = joins(i) if joins is not None else joined(
                front[i], front[i + 1], max_gap=max_gap, max_slope=max_slope
            )  # fmt: skip
            if not one:
                return None
            return i, i + 1, math.log(f / f0) / math.log(f1 / f0)
    return None


def interpolate(
    front: Sequence[tuple[float, float]], f: float, *, snap: float = SNAP_SHARE,
    max_gap: float = MAX_GAP, max_slope: float = MAX_SLOPE,
) -> float | None:  # fmt: skip
    """The front's figure at ``f`` Hz (:func:`reading`): log-log between the neighbours
    (linear where a figure is not positive); None where the front does not say."""
    return mixed(front, reading(front, f, snap=snap, max_gap=max_gap, max_slope=max_slope))


def loss_reading(
    front: Sequence[tuple[float, float, float]], w: float, *, snap: float = LOSS_SNAP
) -> tuple[int, int, float] | None:
    """:func:`reading` of a front against the inverter's loss: ``front`` of (loss W, figure,
    f_sw Hz) rising in loss, read at ``w`` W — a point within ``snap`` of ``w`` as measured,
    else between the two neighbours that enclose ``w`` if they are one regime: :func:`joined`
    as the f_sw columns take it, on their own (f_sw, figure) pairs (at most :data:`MAX_GAP`
    apart in f_sw, the figure stepping by no more than the :data:`MAX_SLOPE` power of their
    f_sw ratio). The loss of a finite-control-set law moves little as its f_sw halves (the
    conduction loss stays), so the step is judged where the regimes show: against f_sw."""

    def one_regime(i: int) -> bool:
        a, b = sorted([(front[i][2], front[i][1]), (front[i + 1][2], front[i + 1][1])])
        return joined(a, b)

    return reading([(x, v) for x, v, _ in front], w, snap=snap, joins=one_regime)


def loss_interpolate(
    front: Sequence[tuple[float, float, float]], w: float, *, snap: float = LOSS_SNAP
) -> float | None:
    """The front's figure at ``w`` W of inverter loss (:func:`loss_reading`), log-log between
    the neighbours; None where the front does not say."""
    return mixed([(x, v) for x, v, _ in front], loss_reading(front, w, snap=snap))


def mixed(front: Sequence[tuple[float, float]], r: tuple[int, int, float] | None) -> float | None:
    """The value of a :func:`reading` ``r`` of ``front``: log-log between its two points
    (linear where a figure is not positive); None for no reading."""
    if r is None:
        return None
    i, j, s = r
    v0, v1 = front[i][1], front[j][1]
    if i == j:
        return v0
    if v0 > 0 and v1 > 0:
        return math.exp(math.log(v0) + s * (math.log(v1) - math.log(v0)))
    return v0 + s * (v1 - v0)


@dataclass(frozen=True)
class Curve:
    """One strategy traced over one knob: ``knob`` (a key of :data:`KNOBS`, or a parameter of a
    controller of one's own) takes ``values`` in turn on scenario ``scenario``, with ``settings``
    besides, at the scenario's period and at each of ``periods`` over the first
    :data:`PERIOD_VALUES` values. ``label`` names the curve (the strategy's name unless a
    setting tells two curves of one strategy apart); ``external``: the command of a controller
    of one's own (run through the ROS graph, named ``external:LABEL``, its points the first
    ``period_values`` values at each period)."""

    strategy: str
    scenario: str
    knob: str
    values: tuple[float, ...]
    settings: dict[str, Any] = field(default_factory=dict)
    label: str = ""
    periods: tuple[float, ...] = ()
    period_values: int = PERIOD_VALUES
    external: str | None = None

    @property
    def name(self) -> str:
        return self.label or self.strategy

    @property
    def horizon(self) -> int:
        """The law's horizon N (1 unless the curve sets one)."""
        return int(self.settings.get("torque_controller.horizon", 1))

    def points(self) -> list[dict[str, Any]]:
        """Each run's own settings: the knob's value, and the period where it is not the
        scenario's."""
        out: list[dict[str, Any]] = [{self.knob: v} for v in self.values]
        for ts in self.periods:
            out += [{"ts": ts, self.knob: v} for v in sorted(self.values)[: self.period_values]]
        return out


@dataclass(frozen=True)
class OperatingPoint:
    """A steady operating point: the curves run at it, and the papers' ranking of its strategies
    (best first, by the paper's torque figure; empty where no paper ranks them)."""

    caption: str
    curves: tuple[Curve, ...]
    papers_ranking: tuple[str, ...] = ()
    papers_source: str = ""
    #: the point's finite-control-set scenario: where a controller of one's own runs
    scenario: str = ""
    #: the drive's inverter devices, every run's ``plant.losses.device`` ('': no losses)
    device: str = ""
    #: the inverter losses (W) the fronts are read and ranked at, chosen for the point's range
    loss_columns: tuple[float, ...] = ()


def _fcs(
    scenario: str, strategies: tuple[str, ...], values: dict[str, tuple[float, ...]]
) -> tuple[Curve, ...]:
    return tuple(Curve(s, scenario, _LAMBDA, values[s], periods=PERIODS) for s in strategies)


def _horizons(
    strategy: str, scenario: str, knob: str, values: tuple[float, ...], horizons: tuple[int, ...]
) -> tuple[Curve, ...]:
    """One curve per horizon N of a long-horizon law (docs/physics.md#long-horizons), named
    ``<strategy> N=<N>`` (plain ``mptc`` at N = 1: the papers' law)."""
    return tuple(
        Curve(
            strategy, scenario, knob, values, {"torque_controller.horizon": n},
            label=strategy if n == 1 and strategy == "mptc" else f"{strategy} N={n}",
            periods=PERIODS,
        )
        for n in horizons
    )  # fmt: skip


def _loss_aware(scenario: str, values: tuple[float, ...], device: str) -> Curve:
    """mptc over its loss-aware weight λ_e, the controller pricing commutations with the
    point's own device file, at the papers' period."""
    return Curve(
        "mptc", scenario, "torque_controller.lambda_e", values,
        {"torque_controller.device": device}, label="mptc lambda_e",
    )  # fmt: skip


_LAMBDA_U = (1e-4, 1e-3, 3e-3, 0.01, 0.03, 0.1, 0.3, 1.0)
#: the horizons the fronts trace: mptc's and direct_mpc's
MPTC_HORIZONS = (2, 3, 5)
DIRECT_HORIZONS = (1, 3, 5, 10)


_IM_LAMBDA = {
    "mptc": (0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5),
    "mptc_db": (0.0, 0.05, 0.1, 0.2, 0.3, 0.4),
    "db_mptc": (0.0, 0.1, 0.2, 0.25, 0.3, 0.35, 0.4, 0.5),
}
_PMSM_LAMBDA = (0.0, 0.005, 0.01, 0.02, 0.03, 0.04)
_PMSM = ("mptc", "simplified1", "simplified2", "simplified3")
#: the loss-aware weights λ_e (N·m/J for the IM, 1/J for the PMSMs' normalised cost): from the
#: papers' law to about a third of its switching loss
_IM_LAMBDA_E = (0.0, 50.0, 100.0, 150.0, 200.0, 250.0, 300.0)
_PMSM_LAMBDA_E = (0.0, 300.0, 600.0, 1000.0, 1500.0, 2000.0)
#: the inverter losses each point's fronts are read at, W (the range its runs span)
#: (the IGBT's switching losses are most of the IM's; the SiC drives' losses are nearly all
#: conduction, so their columns lie close together)
_IM_LOSSES = (8.0, 10.0, 12.0, 13.0, 14.0, 15.0, 20.0, 30.0)
_IPMSM_LOSSES = (21.0, 21.25, 21.5, 21.75, 22.0, 22.5, 23.0, 24.0)
_HS_IPMSM_LOSSES = (1.0, 1.25, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0)

FRONTS: dict[str, OperatingPoint] = {
    "im_steady": OperatingPoint(
        "paper 000's induction motor (Li et al., EMCA 2022) held at 2772 r/min, T* = 3 N·m",
        (
            *_fcs("im_steady", ("mptc", "mptc_db", "db_mptc"), _IM_LAMBDA),
            *_horizons("mptc", "im_steady", _LAMBDA, _IM_LAMBDA["mptc"], MPTC_HORIZONS),
            _loss_aware("im_steady", _IM_LAMBDA_E, IGBT),
            Curve("ifoc", "im_steady_foc", "ts", _FOC_TS),
        ),
        ("db_mptc", "mptc_db", "mptc"),
        "paper 000 Table 2, T_RMSE",
        "im_steady",
        IGBT,
        _IM_LOSSES,
    ),
    "ipmsm_steady": OperatingPoint(
        "paper 001's interior PMSM (Li et al., CTA 2023, §6) held at 1000 r/min, T* = 15 N·m",
        (
            *_fcs("ipmsm_steady", _PMSM, dict.fromkeys(_PMSM, _PMSM_LAMBDA)),
            *_horizons("mptc", "ipmsm_steady", _LAMBDA, _PMSM_LAMBDA, MPTC_HORIZONS),
            _loss_aware("ipmsm_steady", _PMSM_LAMBDA_E, SIC),
            *_horizons(
                "direct_mpc",
                "ipmsm_steady_mpc",
                "torque_controller.lambda_u",
                _LAMBDA_U,
                DIRECT_HORIZONS,
            ),  # fmt: skip
            Curve("foc_formula", "ipmsm_steady_foc", "ts", _FOC_TS),
        ),
        ("mptc", "simplified2", "simplified1", "simplified3"),
        "paper 001 Table 9, T_rip",
        "ipmsm_steady",
        SIC,
        _IPMSM_LOSSES,
    ),
    "hs_ipmsm_steady": OperatingPoint(
        "paper 002's high-speed interior PMSM (Yuan et al., JMEE 2018) held at 100 rad/s, "
        "T* = 4 N·m",
        (
            *_fcs("hs_ipmsm_steady", _PMSM, dict.fromkeys(_PMSM, _PMSM_LAMBDA + (0.06,))),
            *_horizons("mptc", "hs_ipmsm_steady", _LAMBDA, _PMSM_LAMBDA + (0.06,), MPTC_HORIZONS),
            _loss_aware("hs_ipmsm_steady", _PMSM_LAMBDA_E, SIC),
            *_horizons(
                "direct_mpc",
                "hs_ipmsm_steady_mpc",
                "torque_controller.lambda_u",
                _LAMBDA_U,
                DIRECT_HORIZONS,
            ),  # fmt: skip
            Curve("foc_formula", "hs_ipmsm_steady_foc", "ts", _FOC_TS),
        ),
        scenario="hs_ipmsm_steady",
        device=SIC,
        loss_columns=_HS_IPMSM_LOSSES,
    ),
}
