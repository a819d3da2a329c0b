"""Run metrics from a :class:`Trace`, as the papers define them (paper 001 eq 7-9; the
definitions and their readings are in docs/physics.md, "Metrics").

Each metric says once how it is shown — title, unit, scale and format — as field metadata of
:class:`Metrics` (:func:`metric`); :data:`METRICS` holds them with the figures derived from a run
elsewhere (the zero-vector share, the compute-time ratios), so the command line, the sweep
tables, the figures and the paper tables format a metric from one place.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from ..errors import ConfigError
from .signals import COMMAND_INDEX, DEVICES, REFERENCE_INDEX, STATE_INDEX, strategy_name
from .timebase import every_steps, step_index
from .trace import Trace

__all__ = [
    "EQUAL_FSW_SHARE",
    "METRICS",
    "Cycles",
    "CurrentDistortion",
    "continuous_current",
    "continuous_current_thd",
    "continuous_mean_error",
    "continuous_ripple",
    "continuous_rmse",
    "LOSS_METRICS",
    "books_losses",
    "loss_figures",
    "fundamental_angle",
    "whole_cycles",
    "Metric",
    "Metrics",
    "Spectrum",
    "compute_metrics",
    "metric",
    "phase_a_spectrum",
    "step_window",
    "unequal_switching",
]

_KEY = "predictive_drive.metric"


@dataclass(frozen=True)
class Metric:
    """How a figure of a run is shown: ``title``, display ``unit`` ('' for a pure number),
    ``scale`` (the value times it is in the unit: 1e-3 shows Hz as kHz), ``fmt`` (a format spec)
    and what it is (``description``)."""

    title: str
    unit: str = ""
    scale: float = 1.0
    fmt: str = ".4f"
    description: str = ""

    def format(self, value: float | str | None) -> str:
        """The value in the display unit, '-' where there is none (None, NaN or '')."""
        if isinstance(value, str):  # a name (the hottest device)
            return value or "-"
        if value is None or value != value:
            return "-"
        shown = value * self.scale
        return format(round(shown) if self.fmt.endswith("d") else shown, self.fmt)

    def with_unit(self, value: float | str | None) -> str:
        """:meth:`format` followed by the unit, or '-' alone where there is no value."""
        text = self.format(value)
        return f"{text} {self.unit}".rstrip() if text != "-" else text

    @property
    def heading(self) -> str:
        """Title and unit, for a table's head: ``T_RMSE N·m``."""
        return f"{self.title} {self.unit}".rstrip()

    @property
    def axis(self) -> str:
        """Title and unit, for a figure's axis: ``T_RMSE (N·m)``."""
        return f"{self.title} ({self.unit})" if self.unit else self.title


def metric(
    title: str,
    unit: str = "",
    *,
    scale: float = 1.0,
    fmt: str = ".4f",
    description: str = "",
    default: Any = dataclasses.MISSING,
) -> Any:
    """A :class:`Metrics` field with the :class:`Metric` that shows it."""
    m = Metric(title, unit, scale, fmt, description)
    if default is dataclasses.MISSING:
        return dataclasses.field(metadata={_KEY: m})
    return dataclasses.field(default=default, metadata={_KEY: m})


@dataclass(frozen=True)
class Metrics:
    """Figures of one run over the window [t_start, t_end).

    t_rmse: sqrt(mean((T_e - T*)²)), N·m, true plant torque at sample k against the reference in
    force at step k. psi_rmse: same for |ψ_s| against ψ*, Wb. f_ave_hz: device transitions / (6·t),
    two transitions per leg change. f_sw_hz: device turn-on events per device per second (one per
    leg change, half f_ave): the carrier frequency of a PWM drive. cal_ave: mean predictions
    per step. utilization: share of steps choosing V0..V6 (steps of a field-oriented law pick no
    vector and count for none; NaN when no step of the window picked one).
    deadbeat_share: share of steps with 0 < t_u < Ts (NaN when no step picked a vector or
    reported a t_u). compute_ns_*: control law only (NaN where the controller did not report it).
    A figure a controller cannot have is NaN, shown "-".
    speed_rmse: ω_m against ω_m*, rad/s. thd: phase-a current distortion over ``thd_cycles`` whole
    electrical cycles of the THD window — every spectral line up to Nyquist but DC and the
    fundamental (at ``thd_fundamental_hz``) — and thd_harmonics the integer harmonics alone (see
    :class:`Spectrum`); NaN without a window.
    """

    t_start: float = metric("window from", "s", fmt=".4g")
    t_end: float = metric("window to", "s", fmt=".4g")
    steps: int = metric("steps", fmt="d", description="steps in the metrics window")
    t_rmse: float = metric(
        "T_RMSE", "N·m", description="sqrt(mean((T_e - T*)^2)), true torque at k vs T* used at k"
    )
    psi_rmse: float = metric(
        "psi_RMSE", "Wb", fmt=".5f", description="sqrt(mean((|psi_s| - psi*)^2)), true flux"
    )
    f_ave_hz: float = metric(
        "f_ave", "kHz", scale=1e-3, fmt=".3f",
        description="device transitions / (6 t), 2 per leg change",
    )  # fmt: skip
    f_sw_hz: float = metric(
        "f_sw", "kHz", scale=1e-3, fmt=".3f",
        description="turn-on events per device per s, 1 per leg change (PWM carrier)",
    )  # fmt: skip
    cal_ave: float = metric("Cal_ave", fmt=".2f", description="vector predictions per step")
    utilization: tuple[float, ...] = metric(
        "vectors",
        "%",
        scale=100.0,
        fmt=".1f",
        description="share of steps per vector, V0 zero",
    )
    deadbeat_share: float = metric(
        "deadbeat", "%", scale=100.0, fmt=".2f", description="steps with 0 < t_u < Ts"
    )
    compute_ns_mean: float = metric(
        "compute mean", "µs/step", scale=1e-3, fmt=".2f", description="mean, control law only"
    )
    compute_ns_median: float = metric(
        "compute", "µs/step", scale=1e-3, fmt=".2f", description="median, control law only"
    )
    speed_rmse: float = metric(
        "speed_RMSE", "rad/s", fmt=".3f",
        description="omega_m vs omega_m*, its steps (start, reversal) included",
    )  # fmt: skip
    compute_ns_median_by_strategy: dict[str, float] = metric(
        "compute", "µs/step", scale=1e-3, fmt=".2f", description="median per strategy"
    )
    thd: float = metric(
        "THD_a", "%", scale=100.0, fmt=".2f",
        description="phase-a distortion over whole cycles, every line up to Nyquist",
        default=math.nan,
    )  # fmt: skip
    thd_harmonics: float = metric(
        "THD_a harmonics", "%", scale=100.0, fmt=".2f",
        description="phase-a distortion of the integer harmonics alone", default=math.nan,
    )  # fmt: skip
    thd_cycles: int = metric("THD cycles", fmt="d", default=0)
    thd_fundamental_hz: float = metric("THD fundamental", "Hz", fmt=".1f", default=math.nan)
    t_rmse_cont: float = metric(
        "T_RMSE cont", "N·m", default=math.nan,
        description="sqrt(mean((T_e - T*)^2)) over continuous time, between the samples too",
    )  # fmt: skip
    t_ripple_cont: float = metric(
        "T_ripple cont", "N·m", default=math.nan,
        description="sqrt(mean((T_e - mean T_e)^2)) over continuous time: the ripple about "
        "the window's mean torque (what a speed loop leaves of the torque error)",
    )  # fmt: skip
    psi_rmse_cont: float = metric(
        "psi_RMSE cont", "Wb", fmt=".5f", default=math.nan,
        description="sqrt(mean((|psi_s| - psi*)^2)) over continuous time",
    )  # fmt: skip
    i_thd_cont: float = metric(
        "THD_i cont", "%", scale=100.0, fmt=".2f", default=math.nan,
        description="current distortion over whole cycles of the THD window, continuous time, "
        "all three phases, over the fundamental",
    )  # fmt: skip
    i_fundamental_cont: float = metric(
        "I_1 cont", "A", fmt=".4g", default=math.nan,
        description="the current's fundamental over whole cycles of the THD window, continuous "
        "time, as a space-vector amplitude (a phase's peak)",
    )  # fmt: skip
    i_distortion_cont: float = metric(
        "I_dist cont", "A", fmt=".4g", default=math.nan,
        description="sqrt(mean|i_s - i_1|^2) over the THD window: what THD_i cont divides by "
        "I_1 cont and a TDD by a reference current (same scale)",
    )  # fmt: skip
    t_mean_error_cont: float = metric(
        "T_mean err cont", "N·m", default=math.nan,
        description="mean(T_e - T*) over continuous time: how far the mean torque misses T*",
    )  # fmt: skip
    psi_mean_error_cont: float = metric(
        "psi_mean err cont", "Wb", fmt=".5f", default=math.nan,
        description="mean(|psi_s| - psi*) over continuous time",
    )  # fmt: skip

    # -- losses and temperatures (docs/physics.md#losses-and-temperature): means over the window
    # of the plant's loss fields, NaN for a run without them ----------------------------------
    p_cond_t: float = metric(
        "P_cond T", "W", fmt=".3g", default=math.nan,
        description="conduction losses of the six transistors",
    )  # fmt: skip
    p_cond_d: float = metric(
        "P_cond D", "W", fmt=".3g", default=math.nan,
        description="conduction losses of the six diodes",
    )  # fmt: skip
    p_sw_t: float = metric(
        "P_sw T", "W", fmt=".3g", default=math.nan,
        description="switching losses of the six transistors (E_on + E_off)",
    )  # fmt: skip
    p_sw_d: float = metric(
        "P_sw D", "W", fmt=".3g", default=math.nan,
        description="switching losses of the six diodes (E_rr)",
    )  # fmt: skip
    p_inverter: float = metric(
        "P_inverter", "W", fmt=".3g", default=math.nan,
        description="the inverter's losses: conduction and switching",
    )  # fmt: skip
    p_copper: float = metric("P_copper", "W", fmt=".3g", default=math.nan,
                             description="the machine's copper losses, R(T)·i²")  # fmt: skip
    p_iron: float = metric("P_iron", "W", fmt=".3g", default=math.nan,
                           description="the machine's iron losses")  # fmt: skip
    p_friction: float = metric("P_friction", "W", fmt=".3g", default=math.nan,
                               description="the machine's friction losses")  # fmt: skip
    p_machine: float = metric(
        "P_machine", "W", fmt=".3g", default=math.nan,
        description="the machine's losses: copper, iron and friction",
    )  # fmt: skip
    p_in: float = metric(
        "P_in", "W", fmt=".4g", default=math.nan,
        description="from the DC link: u_dc·i_dc of the plant's equations + switching + iron",
    )  # fmt: skip
    p_out: float = metric("P_out", "W", fmt=".4g", default=math.nan,
                          description="into the load")  # fmt: skip
    efficiency: float = metric(
        "eta", "%", scale=100.0, fmt=".2f", default=math.nan,
        description="energy into the load / from the DC link over the window (generating: the "
        "other way round; NaN where they flow opposite ways)",
    )  # fmt: skip
    tj_max: float = metric(
        "T_j max", "°C", fmt=".1f", default=math.nan,
        description="the hottest junction in the window",
    )  # fmt: skip
    tj_max_t: float = metric("T_j max at", "s", fmt=".4g", default=math.nan,
                             description="when the hottest junction was hottest")  # fmt: skip
    #: which device was hottest (:data:`~.signals.DEVICES`; '' without junction temperatures)
    tj_max_device: str = metric("T_j max in", default="")
    t_winding_max: float = metric("T_winding max", "°C", fmt=".1f", default=math.nan,
                                  description="the winding's hottest in the window")  # fmt: skip

    def as_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d["utilization"] = list(self.utilization)
        return d


#: how each figure of a run is shown: the :class:`Metrics` fields, and the figures derived from
#: a run elsewhere (a paper table's zero-vector share, the compute times of a controller replay,
#: a replay's agreement with the recording)
METRICS: dict[str, Metric] = {
    **{f.name: f.metadata[_KEY] for f in dataclasses.fields(Metrics)},
    "zero_share": Metric("V0", "%", 100.0, ".1f", "share of steps choosing the zero vector"),
    "i_tdd_cont": Metric(
        "TDD_i cont",
        "%",
        100.0,
        ".2f",
        "I_dist cont over one reference current of the operating point (a study states it)",
    ),  # fmt: skip
    "compute_us_per_step": Metric("compute", "µs/step", 1.0, ".2f", "median, control law only"),
    "compute_ratio": Metric(
        "compute ratio", "", 1.0, ".3f", "decision time relative to conventional MPTC"
    ),
    "compute_ns_hot": Metric(
        "compute", "µs/step", 1e-3, ".2f", "decision time per step in a tight replay loop"
    ),
    "vector_agreement": Metric(
        "vector", "%", 100.0, ".2f", "replayed steps whose new command picks the recorded vector"
    ),
    "pulse_agreement": Metric(
        "pulses", "%", 100.0, ".2f", "replayed steps whose new command has the recorded pulses"
    ),
}


#: two runs whose switching frequencies differ by more than this share do not compare at
#: equal switching frequency (docs/reproduction.md#fronts-distortion-against-switching-frequency)
EQUAL_FSW_SHARE = 0.2


def unequal_switching(f_sw_hz: dict[str, float]) -> str | None:
    """A sentence when runs (label → f_sw, Hz) switch at frequencies more than
    :data:`EQUAL_FSW_SHARE` apart — their distortion does not compare — else None."""
    known = {k: v for k, v in f_sw_hz.items() if math.isfinite(v) and v > 0}
    if len(known) < 2:
        return None
    lo, hi = min(known, key=known.__getitem__), max(known, key=known.__getitem__)
    if known[hi] <= (1.0 + EQUAL_FSW_SHARE) * known[lo]:
        return None
    return (
        f"not comparable at equal switching frequency: f_sw {known[lo] / 1e3:.3g} kHz "
        f"({lo}) to {known[hi] / 1e3:.3g} kHz ({hi}), {known[hi] / known[lo]:.2g} times; "
        f"`reproduce fronts` compares strategies at equal f_sw"
    )


def step_window(trace: Trace, t_start: float, t_end: float) -> tuple[int, int]:
    """Steps [k0, k1) whose sample time lies in [t_start, t_end), clipped to the commands."""
    k0 = max(0, step_index(t_start, trace.ts))
    k1 = trace.steps if math.isinf(t_end) else min(trace.steps, step_index(t_end, trace.ts))
    if k1 <= k0:
        raise ValueError(
            f"metrics window [{t_start}, {t_end}) s holds no step of this run "
            f"({trace.steps} steps of {trace.ts} s)"
        )
    return k0, k1


@dataclass(frozen=True)
class Spectrum:
    """One-sided amplitude spectrum of the phase-a current over whole electrical cycles.

    ``amplitude[b]`` is the peak amplitude (A) at ``b / period`` Hz: bin ``cycles`` is the
    fundamental, bin ``h · cycles`` harmonic h. ``thd`` = sqrt(Σ A_b²) / A_1 over every bin up to
    the Nyquist frequency except DC and the fundamental: FCS control switches irregularly and
    spreads its ripple over all frequencies, not only the harmonics, so this is the RMS of the
    current's distortion over the fundamental's. ``thd_harmonics`` counts the integer harmonics
    h ≥ 2 alone (the textbook definition; lower for FCS control).
    """

    t_start: float
    period: float  #: analysed length, s
    cycles: int
    amplitude: np.ndarray

    @property
    def fundamental_hz(self) -> float:
        return self.cycles / self.period

    @property
    def thd(self) -> float:
        a = self.amplitude.copy()
        fund = a[self.cycles]
        a[0] = 0.0
        a[self.cycles] = 0.0
        return float(np.sqrt(np.sum(a**2)) / fund)

    @property
    def thd_harmonics(self) -> float:
        a = self.amplitude
        return float(np.sqrt(np.sum(a[2 * self.cycles :: self.cycles] ** 2)) / a[self.cycles])


@dataclass(frozen=True)
class Cycles:
    """The whole electrical cycles of the fundamental that fit in a window: ``n`` steps from
    ``k0`` span ``cycles`` turns, in the ``direction`` the fundamental turns (+1 or -1)."""

    k0: int
    n: int
    cycles: int
    direction: int


def whole_cycles(trace: Trace, t_start: float, t_end: float, *, slips: bool = False) -> Cycles:
    """The whole electrical cycles that fit in [t_start, t_end): counted on the unwrapped angle
    of the fundamental, so the window holds an integer number of its periods (no leakage at
    steady speed). That angle is the rotor's electrical angle θ_e for a synchronous machine; an
    induction motor's currents turn faster or slower than its rotor by the slip (``slips``), so
    there it is the stator flux's. ConfigError (a ValueError) if the window holds no step or
    not one whole cycle."""
    try:
        k0, k1 = step_window(trace, t_start, t_end)
    except ValueError:
        raise ConfigError(
            f"THD window [{t_start}, {t_end}) s holds no step of this run ({trace.steps} steps "
            f"of {trace.ts} s)"
        ) from None
    if slips:
        psi = trace.col("state", "psi_alpha") + 1j * trace.col("state", "psi_beta")
        theta = np.unwrap(np.angle(psi[k0 : k1 + 1]))
    else:
        theta = np.unwrap(trace.truth("theta_e")[k0 : k1 + 1])
    turned = np.abs(theta - theta[0])
    cycles = int(turned[-1] // (2.0 * math.pi))
    if cycles < 1:
        raise ConfigError(
            f"THD window [{t_start}, {t_end}) s holds no whole electrical cycle "
            f"({turned[-1] / (2 * math.pi):.2f} turns)"
        )
    # the first sample of the next cycle; one that lands on it to within rounding is it (a
    # held synchronous machine whose cycles are whole periods)
    n = int(np.searchsorted(turned, cycles * 2.0 * math.pi - 1e-9))
    return Cycles(k0, n, cycles, 1 if theta[-1] >= theta[0] else -1)


def phase_a_spectrum(
    trace: Trace, t_start: float, t_end: float, *, slips: bool = False
) -> Spectrum:
    """Spectrum of i_a (= i_α, amplitude-invariant Clarke) sampled at the steps of the whole
    electrical cycles that fit in [t_start, t_end) (:func:`whole_cycles`)."""
    w = whole_cycles(trace, t_start, t_end, slips=slips)
    k0, n, cycles = w.k0, w.n, w.cycles
    i_a = trace.truth("i_alpha")[k0 : k0 + n]
    amp = np.abs(np.fft.rfft(i_a)) * (2.0 / n)
    amp[0] /= 2.0
    return Spectrum(k0 * trace.ts, n * trace.ts, cycles, amp)


def continuous_rmse(trace: Trace, field: str, ref: str, k0: int, k1: int) -> float:
    """sqrt of the mean over periods k0..k1-1 of ∫(x - x*)² dt / Ts, from the plant's period
    means of x and x² (``<field>_avg``, ``<field>_sq_avg``: state k+1 holds period k's) and the
    reference in force over each period (reference k); NaN for a recording without them
    (``plant.period_means`` off)."""
    mean = trace.col("state", f"{field}_avg")[k0 + 1 : k1 + 1]
    square = trace.col("state", f"{field}_sq_avg")[k0 + 1 : k1 + 1]
    r = trace.col("reference", ref)[k0:k1]
    v = float(np.mean(square - 2.0 * r * mean + r * r))
    return math.sqrt(max(0.0, v)) if v == v else math.nan


def continuous_mean_error(trace: Trace, field: str, ref: str, k0: int, k1: int) -> float:
    """mean over periods k0..k1-1 of (1/Ts)∫(x - x*) dt: how far the mean misses the reference
    (signed), from the period means of x (NaN without them)."""
    mean = trace.col("state", f"{field}_avg")[k0 + 1 : k1 + 1]
    v = float(np.mean(mean - trace.col("reference", ref)[k0:k1]))
    return v if v == v else math.nan


def continuous_ripple(trace: Trace, field: str, k0: int, k1: int) -> float:
    """sqrt(mean x² - (mean x)²) over periods k0..k1-1 in continuous time, from the period
    means of x and x² (NaN without them)."""
    mean = float(np.mean(trace.col("state", f"{field}_avg")[k0 + 1 : k1 + 1]))
    square = float(np.mean(trace.col("state", f"{field}_sq_avg")[k0 + 1 : k1 + 1]))
    v = square - mean * mean
    return math.sqrt(max(0.0, v)) if v == v else math.nan


@dataclass(frozen=True)
class CurrentDistortion:
    """The stator current over whole cycles of its fundamental, in continuous time
    (:func:`continuous_current`): ``fundamental`` |I_1| and ``distortion`` sqrt(mean|i_s -
    i_1|²), both as space-vector amplitudes (A; a phase's peak for a balanced fundamental), so
    ``thd`` = distortion/fundamental is each phase's distortion RMS over its fundamental's RMS,
    and a TDD divides ``distortion`` by a reference amplitude instead (:meth:`tdd`)."""

    fundamental: float
    distortion: float

    @property
    def thd(self) -> float:
        return self.distortion / self.fundamental if self.fundamental > 0 else math.nan

    def tdd(self, base: float) -> float:
        """The distortion over ``base`` (A, an amplitude: the operating point's current)."""
        return self.distortion / base


def fundamental_angle(trace: Trace, w: Cycles, *, slips: bool = False) -> np.ndarray:
    """The fundamental's angle (rad, unwrapped) at the samples k0..k0+n of ``w``: the rotor's
    electrical angle θ_e for a synchronous machine; for an induction motor (``slips``) the
    straight line fitted (least squares) to the stator flux's unwrapped angle, its ripple left
    out."""
    k0, n = w.k0, w.n
    if not slips:
        return np.unwrap(trace.truth("theta_e")[k0 : k0 + n + 1])
    psi = trace.col("state", "psi_alpha") + 1j * trace.col("state", "psi_beta")
    angle = np.unwrap(np.angle(psi[k0 : k0 + n + 1]))
    steps = np.arange(n + 1, dtype=float)
    slope, offset = np.polyfit(steps, angle, 1)
    return np.asarray(offset + slope * steps)


def continuous_current(trace: Trace, w: Cycles, *, slips: bool = False) -> CurrentDistortion:
    """The stator current's fundamental and distortion over the whole cycles ``w``, continuous
    in time, all three phases together (docs/physics.md#continuous-time-figures).

    I_1 is the least-squares fit of one vector turning with the fundamental, I_1 = mean of
    i_s·e^{-jθ_1(t)} over the window, taken from the plant's period means of the current in the
    rotor's frame (``i_d_avg``, ``i_q_avg``): i_s·e^{-jθ_1} = i_r·e^{-jφ}, φ = θ_1 - θ_e the
    angle the fundamental leads the rotor by — constant for a synchronous machine, turning at
    the slip for an induction motor, whose period means of e^{-jφ} are e^{-jφ_mid}·sinc(Δφ/2)
    (divided out). No line of the switching ripple folds onto the fundamental as it does in
    period means of i_αβ (a period's mean is a sample of its mean: lines at m/Ts ± f_1 alias
    onto f_1). Then distortion² = mean|i_s|² - |I_1|²: the power of everything but the
    fundamental — harmonics, switching ripple at any frequency, DC, a negative sequence. NaN
    without the period means (or from a recording made before the plant published them)."""
    sl = slice(w.k0 + 1, w.k0 + w.n + 1)  # the periods k0..k0+n-1
    r = trace.col("state", "i_d_avg")[sl] + 1j * trace.col("state", "i_q_avg")[sl]
    square = float(np.mean(trace.col("state", "current_sq_avg")[sl]))
    if not (np.isfinite(r).all() and math.isfinite(square)):
        return CurrentDistortion(math.nan, math.nan)
    lead = fundamental_angle(trace, w, slips=slips) - np.unwrap(
        trace.truth("theta_e")[w.k0 : w.k0 + w.n + 1]
    )
    turn = np.diff(lead)  # Δφ over each period
    mid = lead[:-1] + 0.5 * turn
    fund = abs(complex(np.mean(r * np.exp(-1j * mid) / np.sinc(turn / (2.0 * math.pi)))))
    v = square - fund * fund
    return CurrentDistortion(fund, math.sqrt(max(0.0, v)))


def continuous_current_thd(trace: Trace, w: Cycles, *, slips: bool = False) -> float:
    """:func:`continuous_current`'s THD: the distortion's RMS over the fundamental's."""
    return continuous_current(trace, w, slips=slips).thd


def compute_metrics(
    trace: Trace,
    *,
    t_start: float = 0.0,
    t_end: float = math.inf,
    thd_window: tuple[float, ...] = (),
    slips: bool = False,
) -> Metrics:
    """A run's figures over [t_start, t_end); the THD over ``thd_window`` (``slips``: an
    induction motor's, see :func:`phase_a_spectrum`; ConfigError if that window holds no whole
    electrical cycle)."""
    k0, k1 = step_window(trace, t_start, t_end)
    n = k1 - k0
    te = trace.col("state", "torque")[k0:k1]
    t_ref = trace.col("reference", "torque_ref")[k0:k1]
    psi = np.hypot(trace.col("state", "psi_alpha")[k0:k1], trace.col("state", "psi_beta")[k0:k1])
    psi_ref = trace.col("reference", "flux_ref")[k0:k1]
    speed = trace.truth("omega_m")[k0:k1]
    speed_ref = trace.col("reference", "speed_ref")[k0:k1]
    transitions = trace.col("state", "transitions")[k0 + 1 : k1 + 1].sum()
    vec = trace.col("command", "vector")[k0:k1]
    fcs = np.isfinite(vec)  # steps decided by a finite-control-set law (not FOC)
    t_u = trace.col("command", "t_u")[k0:k1]
    ns = trace.col("command", "compute_ns")[k0:k1]
    strat = trace.col("command", "strategy")[k0:k1]
    with np.errstate(invalid="ignore"):
        deadbeat = np.count_nonzero((t_u > 0.0) & (t_u < trace.ts))
    # a law that picks no vector (field-oriented control, a controller of one's own that does
    # not say) has no utilization, and no deadbeat share unless it reports deadbeat times
    chose = bool(fcs.any())
    has_t_u = chose or bool(np.isfinite(t_u).any())
    by_strategy = {}
    for s in np.unique(strat):  # NaN (a controller of the user's own) once, as one strategy
        steps = np.isnan(strat) if np.isnan(s) else strat == s
        name = strategy_name(trace.strategy_names, float(s), trace.external)
        by_strategy[name] = float(np.median(ns[steps]))
    m = Metrics(
        t_start=k0 * trace.ts,
        t_end=k1 * trace.ts,
        steps=n,
        t_rmse=float(np.sqrt(np.mean((te - t_ref) ** 2))),
        psi_rmse=float(np.sqrt(np.mean((psi - psi_ref) ** 2))),
        f_ave_hz=float(transitions / (6.0 * n * trace.ts)),
        f_sw_hz=float(transitions / (12.0 * n * trace.ts)),
        cal_ave=float(trace.col("command", "cal")[k0:k1].mean()),
        utilization=(
            tuple(float(x) for x in np.bincount(vec[fcs].astype(int), minlength=7)[:7] / n)
            if chose
            else (math.nan,) * 7
        ),
        deadbeat_share=float(deadbeat / n) if has_t_u else math.nan,
        compute_ns_mean=float(ns.mean()),
        compute_ns_median=float(np.median(ns)),
        speed_rmse=float(np.sqrt(np.mean((speed - speed_ref) ** 2))),
        compute_ns_median_by_strategy=by_strategy,
        t_rmse_cont=continuous_rmse(trace, "torque", "torque_ref", k0, k1),
        t_ripple_cont=continuous_ripple(trace, "torque", k0, k1),
        psi_rmse_cont=continuous_rmse(trace, "flux", "flux_ref", k0, k1),
        t_mean_error_cont=continuous_mean_error(trace, "torque", "torque_ref", k0, k1),
        psi_mean_error_cont=continuous_mean_error(trace, "flux", "flux_ref", k0, k1),
    )
    m = dataclasses.replace(m, **loss_figures(trace, k0, k1))
    if not thd_window:
        return m
    sp = phase_a_spectrum(trace, thd_window[0], thd_window[1], slips=slips)
    cont = continuous_current(
        trace, whole_cycles(trace, thd_window[0], thd_window[1], slips=slips), slips=slips
    )
    return dataclasses.replace(
        m,
        thd=sp.thd,
        thd_harmonics=sp.thd_harmonics,
        thd_cycles=sp.cycles,
        thd_fundamental_hz=sp.fundamental_hz,
        i_thd_cont=cont.thd,
        i_fundamental_cont=cont.fundamental,
        i_distortion_cont=cont.distortion,
    )


#: the figures of a run that books losses (:func:`loss_figures`), in the order tables show them;
#: NaN ('' for the device) for a run without losses
LOSS_METRICS = (
    "p_inverter", "p_cond_t", "p_cond_d", "p_sw_t", "p_sw_d", "p_machine", "p_copper", "p_iron",
    "p_friction", "p_in", "p_out", "efficiency", "tj_max", "tj_max_t", "tj_max_device",
    "t_winding_max",
)  # fmt: skip


def books_losses(m: Metrics | None) -> bool:
    """Whether the run of metrics ``m`` booked losses (its inverter's are a number)."""
    return m is not None and math.isfinite(m.p_inverter)


def loss_figures(trace: Trace, k0: int, k1: int) -> dict[str, Any]:
    """The losses and temperatures of periods k0..k1-1 (the run's losses record; its row k+1
    holds period k's powers): their means, the efficiency from the energies, the hottest
    junction and winding; {} for a run without them."""
    if not trace.has_losses:
        return {}
    p_dc = trace.col("losses", "p_dc")[k0 + 1 : k1 + 1]

    def mean(field: str) -> float:
        return float(np.mean(trace.col("losses", field)[k0 + 1 : k1 + 1]))

    out: dict[str, Any] = {f: mean(f) for f in ("p_cond_t", "p_cond_d", "p_sw_t", "p_sw_d",
                                                "p_copper", "p_iron", "p_friction")}  # fmt: skip
    out["p_inverter"] = out["p_cond_t"] + out["p_cond_d"] + out["p_sw_t"] + out["p_sw_d"]
    out["p_machine"] = out["p_copper"] + out["p_iron"] + out["p_friction"]
    p_in = float(np.mean(p_dc)) + out["p_sw_t"] + out["p_sw_d"] + out["p_iron"]
    p_out = mean("p_shaft")
    out["p_in"], out["p_out"] = p_in, p_out
    if p_in > 0.0 and p_out > 0.0:
        out["efficiency"] = p_out / p_in
    elif p_in < 0.0 and p_out < 0.0:
        out["efficiency"] = p_in / p_out
    tj = np.column_stack([trace.col("losses", f"tj_{d}")[k0:k1] for d in DEVICES])
    if np.isfinite(tj).any():
        k, d = np.unravel_index(int(np.nanargmax(tj)), tj.shape)
        out["tj_max"] = float(tj[k, d])
        out["tj_max_t"] = (k0 + int(k)) * trace.ts
        out["tj_max_device"] = DEVICES[int(d)]
    winding = trace.col("losses", "t_winding")[k0:k1]
    if np.isfinite(winding).any():
        out["t_winding_max"] = float(np.nanmax(winding))
    return out


class _Sums:
    """Sums of squared errors and transitions over a run of steps."""

    __slots__ = ("n", "t_err2", "psi_err2", "est_err2", "speed_err2", "transitions")

    def __init__(self) -> None:
        self.n = 0
        self.t_err2 = self.psi_err2 = self.est_err2 = self.speed_err2 = self.transitions = 0.0

    def add(
        self, t_err: float, psi_err: float, est_err: float, speed_err: float, tr: float
    ) -> None:
        self.n += 1
        self.t_err2 += t_err * t_err
        self.psi_err2 += psi_err * psi_err
        self.est_err2 += est_err * est_err
        self.speed_err2 += speed_err * speed_err
        self.transitions += tr

    def merge(self, other: _Sums) -> None:
        self.n += other.n
        self.t_err2 += other.t_err2
        self.psi_err2 += other.psi_err2
        self.est_err2 += other.est_err2
        self.speed_err2 += other.speed_err2
        self.transitions += other.transitions

    def figures(self, ts: float) -> dict[str, float]:
        n = self.n
        return {
            "t_rmse": math.sqrt(self.t_err2 / n),
            "psi_rmse": math.sqrt(self.psi_err2 / n),
            "torque_estimate_rmse": math.sqrt(self.est_err2 / n),
            "speed_rmse": math.sqrt(self.speed_err2 / n),
            "f_ave_hz": self.transitions / (6.0 * n * ts),
        }


def _running_sum(start: float, values: np.ndarray, square: bool) -> float:
    """``start`` plus each value (squared) in turn, as ``x += v * v`` does step by step: the
    same float (an accumulation is sequential, unlike numpy's pairwise ``sum``)."""
    terms = np.empty(len(values) + 1)
    terms[0] = start
    terms[1:] = values * values if square else values
    return float(np.add.accumulate(terms)[-1])


class LiveMetrics:
    """Running figures while a run is in progress (for /diagnostics), fed record by record.

    Records may arrive interleaved across topics (the graph gives no cross-topic order); state k,
    reference k and command k are paired by k. A snapshot covers the steps since the last one
    (one every ``period`` s of simulated time); :meth:`total` covers the whole run so far.
    """

    #: WARN when the controller's torque estimate is off the true torque by more than this share of
    #: the torque limit, RMS over the period (a parameter-mismatch symptom)
    ESTIMATE_WARN_SHARE = 0.05

    def __init__(self, *, ts: float, torque_limit: float, period: float = 0.1) -> None:
        self.ts = ts
        self.torque_limit = torque_limit
        self.every = every_steps(period, ts)
        self._pending: dict[int, dict[str, tuple[float, ...]]] = {}
        self._period = _Sums()
        self._run = _Sums()
        self.steps = 0
        self._last_k = -1
        self._last_t = 0.0
        self._last_strategy = math.nan

    def add(self, record: str, row: tuple[float, ...]) -> dict[str, float] | None:
        """Feed one record; returns a snapshot when a diagnostics period completes, else None."""
        k = int(row[0])  # k is the first field of every record
        slot = self._pending.setdefault(k, {})
        slot[record] = row
        if len(slot) < 3:
            return None
        del self._pending[k]
        return self.add_step(slot["state"], slot["reference"], slot["command"])

    def add_step(
        self, s: tuple[float, ...], r: tuple[float, ...], c: tuple[float, ...]
    ) -> dict[str, float] | None:
        """Feed step k's state, reference and command at once (what :meth:`add` does when the
        third of them arrives); returns a snapshot when a diagnostics period completes."""
        k = int(s[0])
        S, R, C = STATE_INDEX, REFERENCE_INDEX, COMMAND_INDEX
        te = s[S.torque]
        errors = (
            te - r[R.torque_ref],
            math.hypot(s[S.psi_alpha], s[S.psi_beta]) - r[R.flux_ref],
            c[C.torque_est] - te,
            s[S.omega_m_true] - r[R.speed_ref],
            s[S.transitions],
        )
        self._period.add(*errors)
        self.steps += 1
        self._last_k = k
        self._last_t = s[S.t]
        self._last_strategy = c[C.strategy]
        if self.steps % self.every:
            return None
        return self.flush()

    def add_steps(self, s: np.ndarray, r: np.ndarray, c: np.ndarray) -> dict[str, float] | None:
        """:meth:`add_step` of consecutive steps at once (rows of state, reference and command),
        the same figures bit for bit (the sums accumulate in step order); the steps must not
        run past the end of a diagnostics period (``every - steps % every`` of them at most).
        Returns the snapshot when they complete one."""
        m = len(s)
        if m == 0:
            return None
        if m > self.every - self.steps % self.every:
            raise ValueError("add_steps: the steps run past the end of a diagnostics period")
        S, R, C = STATE_INDEX, REFERENCE_INDEX, COMMAND_INDEX
        te = s[:, S.torque]
        flux = [
            math.hypot(a, b) for a, b in zip(s[:, S.psi_alpha].tolist(), s[:, S.psi_beta].tolist())
        ]
        p = self._period
        p.t_err2 = _running_sum(p.t_err2, te - r[:, R.torque_ref], True)
        p.psi_err2 = _running_sum(p.psi_err2, np.asarray(flux) - r[:, R.flux_ref], True)
        p.est_err2 = _running_sum(p.est_err2, c[:, C.torque_est] - te, True)
        p.speed_err2 = _running_sum(p.speed_err2, s[:, S.omega_m_true] - r[:, R.speed_ref], True)
        p.transitions = _running_sum(p.transitions, s[:, S.transitions], False)
        p.n += m
        self.steps += m
        self._last_k = int(s[-1, 0])
        self._last_t = float(s[-1, S.t])
        self._last_strategy = float(c[-1, C.strategy])
        if self.steps % self.every:
            return None
        return self.flush()

    def _snapshot(self, sums: _Sums) -> dict[str, float]:
        return {
            "k": float(self._last_k),
            "t": self._last_t,
            "steps": float(self.steps),
            **sums.figures(self.ts),
            "strategy": self._last_strategy,
        }

    def flush(self) -> dict[str, float] | None:
        """Snapshot of the steps since the last one (None if there are none)."""
        if self._period.n == 0:
            return None
        snap = self._snapshot(self._period)
        self._run.merge(self._period)
        self._period = _Sums()
        return snap

    def total(self) -> dict[str, float] | None:
        """Snapshot of every step so far (None before the first)."""
        run = _Sums()
        run.merge(self._run)
        run.merge(self._period)
        return self._snapshot(run) if run.n else None

    def level(self, snap: dict[str, float]) -> tuple[int, str]:
        """(diagnostic level, what is wrong or "") for a snapshot: 0 OK or 1 WARN."""
        limit = self.ESTIMATE_WARN_SHARE * self.torque_limit
        if snap["torque_estimate_rmse"] > limit:
            return 1, (
                f"controller torque estimate off by {snap['torque_estimate_rmse']:.3g} N·m RMS "
                f"(> {limit:.3g}): model mismatch?"
            )
        return 0, ""
