"""``predictive-drive reproduce fronts``: every strategy's front of distortion against switching
frequency at each steady operating point (:mod:`predictive_drive.reports.fronts`), FOC + SVPWM
the baseline, run as a sweep on the local cores or a Dask cluster — and a controller of one's own
through the ROS graph beside them; each run checked against the operating point, the fronts
compared at common switching frequencies and ranked there
(docs/reproduction.md#fronts-distortion-against-switching-frequency)."""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..config import apply_settings, load_scenario_text, read_device, resolve_scenario_path
from ..core.control.mtpa import mtpa_point
from ..core.devices import Device
from ..core.machines import Machine
from ..core.scenario import Scenario
from ..core.signals import EXTERNAL_PREFIX, external_name
from ..errors import ConfigError
from ..reports.fronts import (
    COMMON_FSW,
    FRONTS,
    KNOBS,
    LOSS,
    PREDICTION,
    RANKED,
    SHOWN,
    TOLERANCE,
    Curve,
    OperatingPoint,
    interpolate,
    joined,
    loss_reading,
    mixed,
    pareto,
    reading,
)
from .study import Reproduction, StudyRuns
from .sweep import Case

__all__ = [
    "Excluded",
    "FrontCurve",
    "FrontPoint",
    "FrontTable",
    "FrontsChoice",
    "FrontsResult",
    "base_current",
    "external_curve",
    "held",
    "interpolate",
    "joined",
    "on_fronts",
    "pareto",
    "prediction_setting",
    "reading",
    "reproduce_fronts",
    "subset",
    "with_knob_values",
]

FRONTS_STUDY = "fronts"

_HOW = (
    "each point one run at a steady operating point (the shaft held by a load machine, T* "
    "held), its figures over the scenario's window in continuous time (the plant's period "
    "means): T_ripple cont = RMS of the torque about its mean, T_RMSE cont = RMS of the torque "
    "against T*, THD_i cont = the stator current's distortion over its own fundamental (every "
    "frequency, three phases, over whole fundamental periods), TDD = the same distortion over "
    "the operating point's current (base_current_a), f_sw = turn-on events per device per "
    "second. A point holds the operating point when its mean torque lies within 2 % of T*, its "
    "mean |psi_s| within 2 % of psi* and its current's fundamental within 2 % of the operating "
    "point's current and no junction of its inverter goes above its rated temperature over the "
    "window; the rest are listed (excluded) with their miss, not on the front. The "
    "front of a curve is its points no other of its points beats in both f_sw and the figure; "
    "a column reads the front's point within 3 % of its frequency as measured, else "
    "interpolates log-log between the neighbours that enclose it when they are at most twice "
    "apart and one regime (the figure steps by no more than the cube of their f_sw ratio: a "
    "steeper step is a jump between two ways of switching), else '-'. Rank: lowest first at "
    "each frequency. Losses: every run with the drive's own inverter devices (the point's "
    "device file, junction temperatures fed back every ms as the losses section's defaults "
    "do); P_inverter = the six transistors' and diodes' conduction and switching losses, means "
    "over the window. At equal loss: the front of a curve against P_inverter (its points no "
    "other of its points beats in both the loss and the figure), read at the point's loss "
    "columns as the f_sw columns are (within 0.5 % as measured, else log-log between the "
    "neighbours that enclose the column), the neighbours one regime by the f_sw rule on their "
    "own (f_sw, figure) pairs, else '-'; rank lowest first at each loss."
)


@dataclass(frozen=True)
class FrontPoint:
    """One run of a curve: its knob value and control period, figures
    (:data:`~..reports.fronts.SHOWN`, by metric key), how far it missed the operating point
    (``misses``: torque, flux and current, signed shares), whether it held it (and if not why),
    and on which figures' fronts it lies."""

    value: float
    ts: float
    figures: dict[str, float]
    misses: dict[str, float]
    holds: bool
    reason: str
    on_front: dict[str, bool]
    wall_s: float
    #: on which figures' fronts against the inverter's loss it lies
    on_loss_front: dict[str, bool] = field(default_factory=dict)


@dataclass(frozen=True)
class FrontCurve:
    """A strategy traced over its knob at one operating point; ``prediction``: the PMSM
    prediction its runs used where the family has the choice (read from the settings applied),
    else None; ``external``: the command of a controller of one's own (None: a built-in)."""

    name: str
    strategy: str
    scenario: str
    knob: str
    settings: dict[str, Any]
    points: list[FrontPoint]
    prediction: str | None = None
    external: str | None = None

    def front(self, key: str) -> list[FrontPoint]:
        """The points on the front of figure ``key``, by rising f_sw."""
        on = [p for p in self.points if p.on_front[key]]
        return sorted(on, key=lambda p: (p.figures["f_sw_hz"], p.figures[key]))

    def loss_front(self, key: str) -> list[FrontPoint]:
        """The points on the front of figure ``key`` against the inverter's loss, by rising
        loss."""
        on = [p for p in self.points if p.on_loss_front.get(key)]
        return sorted(on, key=lambda p: (p.figures[LOSS], p.figures[key]))


@dataclass(frozen=True)
class Excluded:
    """A run that left the operating point: its curve, knob value, period, f_sw, misses (signed
    shares) and why."""

    curve: str
    value: float
    ts: float
    f_sw_hz: float
    misses: dict[str, float]
    reason: str


@dataclass(frozen=True)
class FrontTable:
    """One operating point: its curves, each front read at the common frequencies (``at[metric]
    [curve]``, None where the table leaves it blank) with the mean torque's miss there
    (``torque_miss_at[metric][curve]``, a signed share), the ranking there (``ranking[metric]``,
    per frequency the curves best first) beside the papers' ranking; the same at equal inverter
    loss (``loss_columns`` W: ``at_loss``, ``torque_miss_at_loss``, ``ranking_loss``) with the
    runs' ``device``; the references (T* N·m, ψ* Wb), the current the TDD divides by
    (``base_current_a``, an amplitude, and what it is) and the runs that left the operating
    point."""

    point: str
    caption: str
    curves: list[FrontCurve]
    at: dict[str, dict[str, list[float | None]]]
    torque_miss_at: dict[str, dict[str, list[float | None]]]
    ranking: dict[str, list[list[str]]]
    papers_ranking: tuple[str, ...]
    papers_source: str
    torque_ref: float
    flux_ref: float
    base_current_a: float
    base_current: str
    excluded: list[Excluded]
    device: str = ""
    loss_columns: tuple[float, ...] = ()
    at_loss: dict[str, dict[str, list[float | None]]] = field(default_factory=dict)
    torque_miss_at_loss: dict[str, dict[str, list[float | None]]] = field(default_factory=dict)
    ranking_loss: dict[str, list[list[str]]] = field(default_factory=dict)


@dataclass(frozen=True)
class FrontsResult(Reproduction):
    """``reproduce fronts``: every operating point's curves and their comparison."""

    frequencies: tuple[float, ...]
    tolerance: dict[str, float]
    points: list[FrontTable]
    runs: int
    wall_s: float
    figures: list[Path] = field(default_factory=list)
    #: figures not drawn, and why (nothing to put on their log axes)
    figure_notes: list[str] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        out: dict[str, Any] = {
            **self.head(),
            "figure_notes": self.figure_notes,
            "frequencies_hz": list(self.frequencies),
            "tolerance": self.tolerance,
            "runs": self.runs,
            "wall_s": self.wall_s,
            "points": [dataclasses.asdict(t) for t in self.points],
        }
        if self.figures:
            out["figures"] = [str(p) for p in self.figures]
        return out


def with_knob_values(
    study: Mapping[str, OperatingPoint],
    *,
    lambda_sw: Sequence[float] | None = None,
    fsw_khz: Sequence[float] | None = None,
    lambda_u: Sequence[float] | None = None,
    periods_us: Sequence[float] | None = None,
) -> dict[str, OperatingPoint]:
    """The study with every finite-control-set curve traced over ``lambda_sw``, every
    direct_mpc curve over ``lambda_u``, every FOC curve over the carriers ``fsw_khz`` (ts =
    1/f_sw) and every finite-control-set curve at the other periods ``periods_us`` (µs; empty:
    the papers' period alone) instead of its own; ConfigError names a value outside the knob's
    range (:data:`~..reports.fronts.KNOBS`)."""
    given = {
        "torque_controller.lambda_sw": lambda_sw,
        "torque_controller.lambda_u": lambda_u,
        "ts": None,
    }
    if fsw_khz is not None:
        for f in fsw_khz:
            if not (math.isfinite(f) and f > 0):
                raise ConfigError(f"--fsw-khz: {f!r} is not a positive number of kHz")
        given["ts"] = [1.0 / (1e3 * f) for f in fsw_khz]
    periods = None if periods_us is None else tuple(p / 1e6 for p in periods_us)
    lo, hi = KNOBS["ts"]
    for us in periods_us or ():
        if not (math.isfinite(us) and lo <= us / 1e6 <= hi):
            raise ConfigError(f"--periods-us: {us!r} is outside {lo * 1e6:g}..{hi * 1e6:g}")
    for key, values in given.items():
        if values is None:
            continue
        lo, hi = KNOBS[key]
        if not values:
            raise ConfigError(f"{_knob_option(key)}: give at least one value")
        for v in values:
            if not (math.isfinite(v) and lo <= v <= hi):
                shown = v if key != "ts" else 1e-3 / v
                rng = f"{lo:g}..{hi:g}" if key != "ts" else f"{1e-3 / hi:g}..{1e-3 / lo:g} kHz"
                raise ConfigError(f"{_knob_option(key)}: {shown!r} is outside {rng}")
    out = {}
    for name, op in study.items():
        curves = []
        for c in op.curves:
            c = dataclasses.replace(c, values=tuple(given.get(c.knob) or c.values))
            if periods is not None and c.periods:
                c = dataclasses.replace(c, periods=periods)
            curves.append(c)
        out[name] = dataclasses.replace(op, curves=tuple(curves))
    return out


def _knob_option(key: str) -> str:
    return {"torque_controller.lambda_sw": "--lambda-sw", "torque_controller.lambda_u":
            "--lambda-u"}.get(key, "--fsw-khz")  # fmt: skip


def subset(
    study: Mapping[str, OperatingPoint],
    *,
    points: Sequence[str] | None = None,
    curves: Sequence[str] | None = None,
    horizons: bool = True,
) -> dict[str, OperatingPoint]:
    """The study's operating points ``points`` (all if None) with their curves named in
    ``curves`` (all if None), and without the long horizons (N > 1) unless ``horizons``;
    ConfigError names what the study has not, listing what it has, or a choice that leaves
    nothing to run."""
    if points is not None:
        unknown = [p for p in points if p not in study]
        if unknown:
            raise ConfigError(
                f"--points {unknown[0]}: not an operating point of the study; one of "
                f"{', '.join(study)}"
            )
    chosen = {n: op for n, op in study.items() if points is None or n in points}
    names = {c.name for op in chosen.values() for c in op.curves}
    for c in curves or ():
        if c not in names:
            raise ConfigError(
                f"--curves {c}: no curve of that name at {', '.join(chosen)}; the curves: "
                f"{', '.join(sorted(names))}"
            )
    out = {}
    for n, op in chosen.items():
        kept = tuple(
            c
            for c in op.curves
            if (curves is None or c.name in curves) and (horizons or c.horizon == 1)
        )
        if kept:
            out[n] = dataclasses.replace(op, curves=kept)
    if not out:
        raise ConfigError("--points, --curves and --no-horizons leave no curve to run")
    return out


def external_curve(
    study: Mapping[str, OperatingPoint],
    command: str,
    *,
    label: str | None = None,
    knobs: Mapping[str, Sequence[Any]] | None = None,
) -> dict[str, OperatingPoint]:
    """The study (of one operating point) with a torque controller of one's own added as a
    curve: ``command`` starts it (run through the ROS graph on the point's finite-control-set
    scenario, docs/ros.md#your-controller-on-the-fronts), ``label`` names it
    (``external:LABEL``), ``knobs`` (at most one of its own parameters, ``torque_controller.
    NAME``, and the period ``ts``) the values it is traced over — all of them at each period;
    none: one run as its section says. ConfigError for a study of several points or a knob
    that is not its own."""
    if len(study) != 1:
        raise ConfigError(
            f"--external: your controller goes on one operating point; choose it with --points "
            f"(one of {', '.join(study)})"
        )
    ((name, op),) = study.items()
    knobs = dict(knobs or {})
    periods = tuple(float(v) for v in knobs.pop("ts", ()))
    if len(knobs) > 1 or any(not k.startswith("torque_controller.") for k in knobs):
        raise ConfigError(
            f"--knob {', '.join(knobs)}: your controller is traced over one of its own "
            f"parameters (torque_controller.NAME=V1,V2,...) and/or its period (ts=T1,T2,...)"
        )
    lo, hi = KNOBS["ts"]
    for p in periods:
        if not (math.isfinite(p) and lo <= p <= hi):
            raise ConfigError(f"--knob ts: {p!r} s is outside {lo:g}..{hi:g} s")
    scenario = op.scenario
    if not scenario:
        raise ConfigError(f"--external: the operating point {name} names no scenario to run on")
    strategy = external_name(label or "torque_controller")  # a name bags and files can hold
    if knobs:
        ((knob, values),) = knobs.items()
        curve = Curve(
            strategy, scenario, knob, tuple(values), label=strategy, periods=periods,
            period_values=len(values), external=command,
        )  # fmt: skip
    else:  # over its period, or one run as its section says (NaN: the scenario's own period)
        curve = Curve(
            strategy, scenario, "ts", periods or (math.nan,), label=strategy, external=command
        )
    return {name: dataclasses.replace(op, curves=(*op.curves, curve))}


@dataclass(frozen=True)
class FrontsChoice:
    """What of the study a user runs (``reproduce fronts`` options): the knobs' values
    (``lambda_sw``, ``lambda_u``, ``fsw_khz``, ``periods_us``: None, each curve's own), the
    operating points and curves (None: all), the long horizons or not, and a controller of
    one's own (``external``: its command; ``label``; ``knobs``: what it is traced over)."""

    lambda_sw: Sequence[float] | None = None
    lambda_u: Sequence[float] | None = None
    fsw_khz: Sequence[float] | None = None
    periods_us: Sequence[float] | None = None
    points: Sequence[str] | None = None
    curves: Sequence[str] | None = None
    horizons: bool = True
    external: str | None = None
    label: str | None = None
    knobs: Mapping[str, Sequence[Any]] | None = None

    def study(self, base: Mapping[str, OperatingPoint] = FRONTS) -> dict[str, OperatingPoint]:
        """The study this choice makes of ``base``, checked before anything runs."""
        if self.external is None and (self.label is not None or self.knobs):
            raise ConfigError(
                "--label and --knob name and trace a controller of your own: give --external "
                "torque_controller=COMMAND"
            )
        out = with_knob_values(
            subset(base, points=self.points, curves=self.curves, horizons=self.horizons),
            lambda_sw=self.lambda_sw,
            lambda_u=self.lambda_u,
            fsw_khz=self.fsw_khz,
            periods_us=self.periods_us,
        )
        if self.external is not None:
            out = external_curve(out, self.external, label=self.label, knobs=self.knobs)
        return out


def base_current(sc: Scenario, torque: float, flux: float) -> tuple[float, str]:
    """The current the operating point takes (A, amplitude) and what it is: a PMSM's MTPA
    current for T* (paper 002 eq 8, 10: FOC's reference there); an induction motor's as
    rotor-field orientation asks it at T*, ψ* (i_d = ψ_r*/L_m, i_q = T*·L_r/(1.5 p L_m ψ_r*),
    ψ_r* = (L_m/L_s)ψ*)."""
    m = sc.plant.motor
    if sc.machine == Machine.PMSM:
        i_s = mtpa_point(torque, p=m.p, psi_f=m.psi_f, l_d=m.l_d, l_q=m.l_q).i_s
        return i_s, f"the MTPA current for T* = {torque:g} N·m (paper 002 eq 8, 10)"
    psi_r = m.l_m / m.l_s * flux
    i = complex(psi_r / m.l_m, torque * m.l_r / (1.5 * m.p * m.l_m * psi_r))
    return abs(i), (
        f"the current rotor-field orientation asks at T* = {torque:g} N·m, psi* = {flux:g} Wb"
    )


#: what a finite-control-set PMSM family without the ``prediction`` choice predicts with
FROZEN_ONLY = "frozen_rotor (the family has no other)"


def _prediction(sc: Scenario) -> str | None:
    """The PMSM prediction the scenario's controller runs with: its ``prediction`` where its
    family has the choice, paper 001's frozen rotor for a finite-control-set family without it,
    None for any other (a field-oriented or an induction motor's family, a user's node)."""
    value = getattr(sc.controller, "prediction", None)
    if value is not None:
        return str(value)
    if sc.machine != Machine.PMSM or sc.controller is None or sc.family.startswith("foc"):
        return None
    return FROZEN_ONLY


def prediction_setting(sc: Scenario) -> dict[str, Any]:
    """What the fronts add to a curve's settings on scenario ``sc``: the rotor-motion
    compensated prediction (:data:`~..reports.fronts.PREDICTION`) for a PMSM family whose
    settings declare the choice (``prediction``); nothing for any other."""
    if sc.machine != Machine.PMSM or sc.controller is None:
        return {}
    if "prediction" not in {f.name for f in dataclasses.fields(sc.controller)}:
        return {}
    return {"torque_controller.prediction": PREDICTION}


def _curve_settings(op: OperatingPoint, curve: Curve, path: Path, text: str) -> dict[str, Any]:
    """The settings the fronts add to a curve's own: the point's inverter devices (every
    curve's plant) and, for a built-in, :func:`prediction_setting`."""
    devices = {"plant.losses.device": op.device} if op.device else {}
    if curve.external is not None:
        return devices
    return {**devices, **prediction_setting(load_scenario_text(text, str(path)))}


@dataclass(frozen=True)
class _Plan:
    """An operating point's runs: per curve its cases; the scenario each curve's runs load
    (one, the first, with its settings applied: what the curve reports)."""

    name: str
    op: OperatingPoint
    cases: dict[str, list[Case]]
    loaded: dict[str, Scenario]


def _plans(study: Mapping[str, OperatingPoint], settings: dict[str, Any]) -> list[_Plan]:
    """Per operating point, its cases by curve; every scenario the cases make is checked before
    anything runs (a bad setting is refused naming the key)."""
    clash = sorted(set(settings) & set(KNOBS))
    if clash:
        raise ConfigError(
            f"--set {clash[0]}: the fronts study sweeps it itself (--lambda-sw, --lambda-u, "
            f"--fsw-khz and --periods-us choose its values)"
        )
    plans = []
    for name, op in study.items():
        cases: dict[str, list[Case]] = {}
        loaded: dict[str, Scenario] = {}
        for c in op.curves:
            path = resolve_scenario_path(c.scenario)
            text = path.read_text(encoding="utf-8")
            own = ["torque_controller"] if c.external is not None else []
            extra = {**_curve_settings(op, c, path, text), **settings, **c.settings}
            cases[c.name] = []
            seen = set()
            for point in c.points():
                point = {k: v for k, v in point.items() if v == v}  # NaN: the section's own
                case = Case(c.strategy, {**extra, **point})
                cases[c.name].append(case)
                key = repr(sorted(case.settings.items()))
                if key in seen:
                    raise ConfigError(f"{c.name}: two runs with {dict(case.settings)}")
                seen.add(key)
                where = f"{path} with " + ", ".join(f"{k}={v}" for k, v in case.settings.items())
                sc = load_scenario_text(
                    apply_settings(text, case.settings, path, own=own), where, own=own
                )
                if c.external is None:
                    sc.with_strategy(case.strategy)
                if not sc.plant.period_means:
                    raise ConfigError(
                        f"{where}: the fronts need plant.period_means: true (distortion "
                        f"between the samples)"
                    )
                loaded.setdefault(c.name, sc)
        plans.append(_Plan(name, op, cases, loaded))
    return plans


def reproduce_fronts(
    runner: StudyRuns,
    *,
    figures: str | Path | None = None,
    settings: dict[str, Any] | None = None,
    study: Mapping[str, OperatingPoint] = FRONTS,
) -> FrontsResult:
    """Run every curve of every operating point of ``study`` (in-process, on the local cores or
    the Dask cluster of ``runner``; a controller of one's own through the ROS graph) and
    compare the fronts. ``settings`` apply to every run (e.g. a real drive's delay with its
    compensation); a shortened run (``runner.duration``) clips the windows: a quick look, not
    the study."""
    settings = dict(settings or {})
    plans = _plans(study, settings)
    t0 = time.perf_counter()
    tables = []
    for plan in plans:
        rows: dict[tuple[str, int], Any] = {}
        by_scenario: dict[tuple[str, str | None], list[tuple[Curve, int, Case]]] = {}
        for c in plan.op.curves:
            for i, case in enumerate(plan.cases[c.name]):
                bag = runner.bag(
                    f"fronts_{plan.name}_{c.name}_{i}".replace(" ", "_").replace(":", "-"),
                    needed=c.external is not None,
                )
                by_scenario.setdefault((c.scenario, c.external), []).append(
                    (c, i, dataclasses.replace(case, bag=bag))
                )
        for (scenario, command), group in by_scenario.items():
            own = group[0][0].strategy.removeprefix(EXTERNAL_PREFIX) if command else None
            done = runner.runs(
                scenario,
                [case for _, _, case in group],
                names=[f"{plan.name} {c.name}" for c, _, _ in group],
                external=None if command is None else {"torque_controller": command},
                label=own,
            )
            for (c, i, _), row in zip(group, done):
                rows[(c.name, i)] = row
        tables.append(_table(plan, rows))
    out = FrontsResult(
        scenario=FRONTS_STUDY,
        engine=runner.where,
        duration=runner.duration,
        settings=settings,
        paper="each strategy's distortion against its switching frequency at a steady "
        "operating point, FOC + SVPWM the baseline",
        how=_HOW,
        frequencies=COMMON_FSW,
        tolerance=dict(TOLERANCE),
        points=tables,
        runs=sum(len(v) for p in plans for v in p.cases.values()),
        wall_s=time.perf_counter() - t0,
    )
    if figures is None:
        return out
    from ..reports.figures import fronts_figures, save

    notes: list[str] = []
    drawn = save(fronts_figures(out, notes), figures, prefix="fronts_")
    return dataclasses.replace(out, figures=drawn, figure_notes=notes)


_MISSED = {"torque": "mean torque", "flux": "mean |psi_s|", "current": "current's fundamental"}


def _point(
    c: Curve,
    case: Case,
    sc: Scenario,
    row: Any,
    refs: tuple[float, float, float],
    device: Device | None,
) -> FrontPoint:
    """A run's point: its figures, its misses of the operating point (T*, ψ*, the base current)
    and whether it held it — not where a junction of its ``device`` went above its rated
    temperature over the window (a drive cannot run there, whatever its figures)."""
    m = row.metrics
    torque, flux, base = refs
    f = {k: float(getattr(m, k)) for k in SHOWN if k != "i_tdd_cont"}
    f["i_tdd_cont"] = f_tdd = m.i_distortion_cont / base
    if f_tdd != f_tdd:
        f["i_tdd_cont"] = math.nan
    misses, reason = held(m, torque, flux, base)
    hot = overheated(m, device)
    if hot:
        reason = f"{reason}; {hot}" if reason else hot
    ts = float(case.settings.get("ts", sc.ts))
    value = float(case.settings.get(c.knob, math.nan)) if c.knob != "ts" else ts
    return FrontPoint(value, ts, f, misses, not reason, reason, {}, row.wall_s)


def held(m: Any, torque: float, flux: float, base: float) -> tuple[dict[str, float], str]:
    """How far a run's metrics ``m`` missed its operating point — its mean torque T* N·m, its
    mean |ψ_s| ψ* Wb, its current's fundamental the point's current ``base`` A (signed shares)
    — and why it left it ('' where it held it within :data:`~..reports.fronts.TOLERANCE`)."""
    misses = {
        "torque": m.t_mean_error_cont / torque,
        "flux": m.psi_mean_error_cont / flux,
        "current": m.i_fundamental_cont / base - 1.0,
    }
    lost = [
        f"{_MISSED[k]} {100 * v:+.2f} %" if v == v else f"{_MISSED[k]} not measured"
        for k, v in misses.items()
        if not abs(v) <= TOLERANCE[k]  # NaN: not measured, not held
    ]
    if not lost:
        return misses, ""
    return misses, "left the operating point: " + ", ".join(lost) + " (tolerance " + ", ".join(
        f"{100 * TOLERANCE[k]:g} %" for k in TOLERANCE
    ) + ")"  # fmt: skip


def overheated(m: Any, device: Device | None) -> str:
    """What a run's metrics ``m`` say of a junction above its rating in ``device`` (its
    transistor's or diode's ``t_j_max``): '' where none went above it or nothing was booked."""
    name = str(getattr(m, "tj_max_device", ""))
    if device is None or not name:
        return ""
    rated = device.rated_tj(name)
    tj = float(m.tj_max)
    if not tj > rated:
        return ""
    return f"a junction above its rating: {tj:.1f} °C in {name} at {m.tj_max_t:.4g} s (rated {rated:g} °C)"


def _table(plan: _Plan, rows: Mapping[tuple[str, int], Any]) -> FrontTable:
    op = plan.op
    first = plan.loaded[op.curves[0].name]
    torque = abs(first.speed_pi_params.torque_values[-1])
    flux = first.speed_pi_params.flux_ref
    base, base_text = base_current(first, torque, flux)
    device = read_device(op.device, "plant.losses.device") if op.device else None
    curves, excluded = [], []
    for c in op.curves:
        sc = plan.loaded[c.name]
        raw = [
            _point(c, case, sc, rows[(c.name, i)], (torque, flux, base), device)
            for i, case in enumerate(plan.cases[c.name])
        ]
        points = on_fronts(raw)
        excluded += [
            Excluded(c.name, p.value, p.ts, p.figures["f_sw_hz"], p.misses, p.reason)
            for p in points
            if not p.holds
        ]
        curves.append(
            FrontCurve(
                c.name,
                c.strategy,
                c.scenario,
                c.knob,
                c.settings,
                points,
                _prediction(sc),
                c.external,
            )  # fmt: skip
        )
    at: dict[str, dict[str, list[float | None]]] = {}
    miss_at: dict[str, dict[str, list[float | None]]] = {}
    for key in RANKED:
        at[key], miss_at[key] = {}, {}
        for fc in curves:
            at[key][fc.name], miss_at[key][fc.name] = _read(fc, key)
    ranking = {key: [_ranked(at[key], i) for i in range(len(COMMON_FSW))] for key in RANKED}
    at_loss: dict[str, dict[str, list[float | None]]] = {}
    miss_at_loss: dict[str, dict[str, list[float | None]]] = {}
    for key in RANKED:
        at_loss[key], miss_at_loss[key] = {}, {}
        for fc in curves:
            at_loss[key][fc.name], miss_at_loss[key][fc.name] = _read_loss(fc, key, op.loss_columns)
    columns = range(len(op.loss_columns))
    ranking_loss = {key: [_ranked(at_loss[key], i) for i in columns] for key in RANKED}
    return FrontTable(
        plan.name, op.caption, curves, at, miss_at, ranking, op.papers_ranking,
        op.papers_source, torque, flux, base, base_text, excluded, op.device, op.loss_columns,
        at_loss, miss_at_loss, ranking_loss,
    )  # fmt: skip


def on_fronts(raw: Sequence[FrontPoint]) -> list[FrontPoint]:
    """A curve's points, each marked with the ranked figures' fronts it lies on: against f_sw
    (``on_front``) and against the inverter's loss (``on_loss_front``)."""
    fronts = {key: _pareto(raw, "f_sw_hz", key) for key in RANKED}
    by_loss = {key: _pareto(raw, LOSS, key) for key in RANKED}
    return [
        dataclasses.replace(
            p,
            on_front={k: fronts[k][i] for k in RANKED},
            on_loss_front={k: by_loss[k][i] for k in RANKED},
        )  # fmt: skip
        for i, p in enumerate(raw)
    ]


def _pareto(points: Sequence[FrontPoint], x: str, key: str) -> list[bool]:
    """Which of a curve's points lie on its front of ``key`` against figure ``x`` (f_sw or the
    inverter's loss): only those that hold the operating point."""
    return pareto(
        [(p.figures[x], p.figures[key]) if p.holds else (math.nan, math.nan) for p in points]
    )


def _read(c: FrontCurve, key: str) -> tuple[list[float | None], list[float | None]]:
    """The curve's front of ``key`` at the common frequencies, and the mean torque's miss
    there (read the same way, linear in the mix)."""
    front = c.front(key)
    pairs = [(p.figures["f_sw_hz"], p.figures[key]) for p in front]
    return _mix(front, [reading(pairs, f) for f in COMMON_FSW], pairs)


def _read_loss(
    c: FrontCurve, key: str, columns: Sequence[float]
) -> tuple[list[float | None], list[float | None]]:
    """The curve's front of ``key`` against the inverter's loss at ``columns`` W
    (:func:`~..reports.fronts.loss_reading`), and the mean torque's miss there."""
    front = c.loss_front(key)
    triples = [(p.figures[LOSS], p.figures[key], p.figures["f_sw_hz"]) for p in front]
    pairs = [(w, v) for w, v, _ in triples]
    return _mix(front, [loss_reading(triples, w) for w in columns], pairs)


def _mix(
    front: Sequence[FrontPoint],
    readings: Sequence[tuple[int, int, float] | None],
    pairs: Sequence[tuple[float, float]],
) -> tuple[list[float | None], list[float | None]]:
    """Each reading's value (:func:`~..reports.fronts.mixed`) and mean torque miss (linear in
    the mix); None where the front does not say."""
    values = [mixed(pairs, r) for r in readings]
    misses: list[float | None] = []
    for r in readings:
        if r is None:
            misses.append(None)
            continue
        i, j, s = r
        a, b = front[i].misses["torque"], front[j].misses["torque"]
        misses.append(a + s * (b - a))
    return values, misses


def _ranked(values: Mapping[str, list[float | None]], i: int) -> list[str]:
    """The curves with a figure at column ``i``, lowest first."""
    known = [(x, n) for n, v in values.items() if (x := v[i]) is not None]
    return [n for _, n in sorted(known)]
