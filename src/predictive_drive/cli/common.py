"""What the verbs share: strict JSON, the progress bar, refusing an option that does not apply,
and printing a recording's metrics (``run`` and ``report`` print the same)."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Protocol

from ..errors import ConfigError

if TYPE_CHECKING:
    from ..api.report import RecordingDetails
    from ..core.metrics import Metrics

__all__ = [
    "dumps",
    "given",
    "print_losses",
    "print_recording",
    "progress",
    "refuse",
    "runs_progress",
    "say_json",
    "scenario_argument",
    "seconds",
]


def _finite(obj: Any) -> Any:
    """NaN/inf → None, so ``--json`` prints strict JSON (null where a figure does not exist)."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _finite(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_finite(v) for v in obj]
    try:
        import numpy as np
    except ImportError:  # pragma: no cover - numpy is a requirement
        return obj
    if isinstance(obj, np.floating):
        return _finite(float(obj))
    if isinstance(obj, np.integer):
        return int(obj)
    return obj


def dumps(obj: Any) -> str:
    """One line of strict JSON."""
    return json.dumps(_finite(obj), indent=None, allow_nan=False)


class _Result(Protocol):
    def as_dict(self) -> dict[str, Any]: ...


def say_json(result: _Result) -> int:
    """Print a verb's typed result as one JSON object; exit status 0."""
    print(dumps(result.as_dict()))
    return 0


def progress(
    enabled: bool, unit: str = "step"
) -> tuple[Callable[[int, int], None] | None, Callable[[], None]]:
    """``(update(k, n), close())`` of a progress bar on stderr, or ``(None, no-op)``. ``n`` may
    grow between updates (a study plans its runs sweep by sweep): the bar follows it."""
    if not enabled:
        return None, lambda: None
    from tqdm import tqdm

    bar: dict[str, Any] = {}

    def update(k: int, n: int, name: str = "") -> None:
        if "bar" not in bar:
            bar["bar"] = tqdm(
                total=n, unit=unit, unit_scale=unit == "step", file=sys.stderr, leave=False
            )
        b = bar["bar"]
        if b.total != n:
            b.total = n
        if name:
            b.set_postfix_str(name, refresh=False)
        b.update(k - b.n)

    def close() -> None:
        if "bar" in bar:
            bar["bar"].close()

    return update, close


def runs_progress(
    what: str, *, quiet: bool
) -> tuple[Callable[[int, int], None] | None, Callable[[], None]]:
    """``(update(done, planned[, name]), close())`` for a verb that makes many runs (``sweep``,
    ``reproduce``), on stderr: a bar on a terminal (``name``, what the run that ended was, beside
    it); elsewhere (a log, a pipe) a line per finished run, ``what: run 2 of 3 done (14.2 s)``
    and ``: name`` where one is told; nothing when ``quiet`` (``--json``)."""
    if quiet:
        return None, lambda: None
    if sys.stderr.isatty():
        return progress(True, unit="run")
    t0 = time.perf_counter()

    def line(done: int, planned: int, name: str = "") -> None:
        print(
            f"{what}: run {done} of {planned} done ({time.perf_counter() - t0:.1f} s)"
            + (f": {name}" if name else ""),
            file=sys.stderr,
            flush=True,
        )

    return line, lambda: None


def seconds(text: str) -> float:
    """An option's simulated seconds (``--duration``): a finite number above 0, else the
    verb's usage error naming the option."""
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"expected a positive number of seconds, got {text!r}")
    return value


def scenario_argument(p: argparse.ArgumentParser) -> None:
    """The SCENARIO argument, its help listing the scenarios there are (``--help`` shows them)."""
    from ..config import scenario_names

    try:
        names = ", ".join(scenario_names())
    except ConfigError as e:  # an install without its scenario folder: say so where they go
        names = f"none found ({e})"
    p.add_argument(
        "scenario",
        help=f"a scenario by name: {names}; or the path of a scenario file (.yaml)",
    )


def given(args: argparse.Namespace, name: str) -> bool:
    """The option ``name`` was given on the command line (its default is None)."""
    value = getattr(args, name, None)
    return value is not None and value is not False and value != []


def refuse(args: argparse.Namespace, reason: str, *names: str) -> None:
    """ConfigError naming the first of ``names`` that was given, and why it does not apply."""
    for name in names:
        if given(args, name):
            raise ConfigError(f"--{name.replace('_', '-')} {reason}")


class _Recording(Protocol):
    """What ``run`` and ``report`` both say of a recording (read-only)."""

    @property
    def scenario(self) -> str: ...
    @property
    def strategy(self) -> str: ...
    @property
    def engine(self) -> str: ...
    @property
    def steps(self) -> int: ...
    @property
    def bag(self) -> Any: ...
    @property
    def metrics(self) -> Metrics: ...
    @property
    def details(self) -> RecordingDetails: ...
    @property
    def window_note(self) -> str: ...


#: the metrics ``run`` and ``report`` print, in order (how each is shown: core.metrics.METRICS)
SHOWN = ("t_rmse", "psi_rmse", "f_ave_hz", "f_sw_hz", "cal_ave", "deadbeat_share", "speed_rmse")
#: printed beside them where the plant recorded its period means (the figures fronts rank by)
CONTINUOUS = ("t_rmse_cont", "t_ripple_cont", "i_thd_cont")


def print_recording(r: _Recording, wall_s: float | None = None) -> None:
    """A recording's metrics, one per line with what it is, then its details."""
    from ..core.metrics import METRICS

    m = r.metrics
    print(
        f"scenario {r.scenario}  strategy {r.strategy}  engine {r.engine}  steps {r.steps}"
        + (f"  wall {wall_s:.2f} s" if wall_s is not None else "")
    )
    print(f"bag      {r.bag}")
    print(
        f"window   {m.t_start:.4g}-{m.t_end:.4g} s ({m.steps} steps)   the figures below are over "
        "it (the scenario's, cut to the run)"
    )
    if r.details.replay_of:  # the states were the recording's: only the commands are the node's
        print(
            f"replay   of {r.details.replay_of}: its states were fed to this controller, whose "
            "commands were recorded, not applied; T_RMSE, psi_RMSE, f_ave, f_sw, speed_RMSE, THD "
            "and the continuous figures are that recording's plant's, Cal_ave, deadbeat, "
            "compute and vectors this controller's"
        )
    rows = [(METRICS[k], getattr(m, k)) for k in SHOWN]
    if any(math.isfinite(getattr(m, k)) for k in CONTINUOUS):  # plant.period_means on
        rows += [(METRICS[k], getattr(m, k)) for k in CONTINUOUS]
    rows.append((METRICS["compute_ns_median"], m.compute_ns_median))
    w = max(11, *(len(shown.title) + 1 for shown, _ in rows))  # the titles' column
    for shown, value in rows:
        print(f"  {shown.title:<{w}}{shown.with_unit(value):>16}   {shown.description}")
    if m.thd == m.thd:  # NaN: no THD window
        shown = METRICS["thd"]
        harmonics = METRICS["thd_harmonics"].format(m.thd_harmonics)
        print(
            f"  {shown.title:<{w}}{shown.format(m.thd) + ' %':>16}   phase-a distortion, "
            f"{m.thd_cycles} cycles of {m.thd_fundamental_hz:.1f} Hz (harmonics alone "
            f"{harmonics} %)"
        )
    if all(math.isfinite(u) for u in m.utilization) and any(m.utilization):
        util = " ".join(f"V{i} {100 * u:.1f}%" for i, u in enumerate(m.utilization))
        print(f"  {'vectors':<{w}}{util}   {METRICS['utilization'].description}")
    d = r.details
    print_losses(m, d)
    if d.searched_steps:
        print(
            f"  {'search':<11}suboptimal steps: {d.suboptimal_steps} of {d.searched_steps}   "
            "steps whose search ran out of its node budget and applied the best sequence "
            "found so far (torque_controller.node_budget)"
        )
    if len(d.strategies) > 1:
        for sp in d.strategies:
            print(
                f"  {'strategy':<{w}}{sp.strategy:>16}   steps {sp.first}-{sp.last} "
                f"({sp.t_start:g}-{sp.t_end:g} s)"
            )
    from ..config import YOURS_KEEPS

    for node in d.own_nodes:
        model = {k: v for k, v in node.parameters.items() if k.split(".")[0] in YOURS_KEEPS}
        mine = {k: v for k, v in node.parameters.items() if k not in model}
        given = ", ".join(f"{k}={v}" for k, v in mine.items()) or "none"
        print(f"  {'your node':<{w}}{node.name}: {node.started}; parameters: {given}")
        if model and node.name == "torque_controller":
            passed = ", ".join(f"{k}={v}" for k, v in model.items())
            print(f"  {'':<{w}}and, passed by the launcher (the controller's model): {passed}")
    if d.outcome:
        print(f"  {'outcome':<{w}}{d.outcome}")
        print(
            f"  {'':<{w}}the recorder's verdict; its figures cover the whole run, T_RMSE above "
            "the window"
        )
    for e in d.parameter_events:
        changes = ", ".join(f"{k} = {v}" for k, v in e.changed.items())
        print(f"  {'parameter':<{w}}{e.t:>14.6g} s   {e.node}: {changes}")
    for st in d.load_steps:
        print(
            f"  load {st.load_torque:g} N·m from {st.t_start:g} s: current angle "
            f"{math.degrees(st.theta):.2f} deg, |i_s| {st.i_s:.4f} A (means over the step's "
            f"second half, measured), angle settled {st.settle_s:.3f} s after the step"
        )
    if r.window_note:
        print(f"  note: {r.window_note}")


def _no_efficiency(m: Metrics) -> str:
    """Why a run with losses has no η over its window ('' where it has one): the powers in and
    out flow opposite ways, the machine's stored energy making up the difference."""
    if math.isfinite(m.efficiency):
        return ""
    if m.p_out < 0.0 <= m.p_in:
        return " (no eta over the window: the load drives the machine, the DC link feeds it too)"
    return " (no eta over the window: the machine gives power both ways, from its stored energy)"


def print_losses(m: Metrics, d: RecordingDetails) -> None:
    """The losses, the efficiency and the hottest junction of a run with losses on (nothing for
    one without): the metrics window's means."""
    from ..core.metrics import METRICS

    if not math.isfinite(m.p_in):
        return

    def w(key: str) -> str:
        return METRICS[key].with_unit(getattr(m, key))

    rows = [
        ("P_cond", f"T {w('p_cond_t')}  D {w('p_cond_d')}",
         "conduction, six transistors / six diodes"),
        ("P_sw", f"T {w('p_sw_t')}  D {w('p_sw_d')}", "switching: E_on + E_off / E_rr"),
        ("inverter", w("p_inverter"), "its losses, conduction + switching"),
        ("machine", w("p_machine"),
         f"copper {w('p_copper')}, iron {w('p_iron')}, friction {w('p_friction')}"),
        ("eta", w("efficiency"), f"{w('p_out')} into the load of {w('p_in')} from the DC link"
         + _no_efficiency(m)),
    ]  # fmt: skip
    if m.tj_max_device:
        rated = d.rated_tj[0 if m.tj_max_device.startswith("t") else 1]
        rows.append(("T_j max", w("tj_max"),
                     f"{m.tj_max_device} at {m.tj_max_t:.4g} s (rated {rated:g} °C)"))  # fmt: skip
    if math.isfinite(m.t_winding_max):
        rows.append(("T_winding", w("t_winding_max"), "the winding's hottest"))
    for title, value, what in rows:
        print(f"  {title:<11}{value:>16}   {what}")
    for o in d.overheats:
        print(
            f"  {'OVER T_j':<11}{o.device:>16}   above its rated {o.rated:g} °C from "
            f"{o.t_first:.4g} s, up to {o.tj_max:.1f} °C at {o.t_max:.4g} s"
        )


def single_settings(texts: list[str] | None) -> dict[str, Any]:
    """``--set KEY=VALUE`` arguments → settings, one value per key (a grid is ``sweep``'s)."""
    from ..api.sweep import parse_set

    settings = {}
    for text in texts or []:
        key, values = parse_set(text)
        if len(values) != 1:
            raise ConfigError(f"--set {text}: one value per key here (a grid is `sweep`)")
        settings[key] = values[0]
    return settings
