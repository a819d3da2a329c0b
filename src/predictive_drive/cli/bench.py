"""``predictive-drive bench``: throughput figures of this machine."""

from __future__ import annotations

import argparse
import math

from ..api.bench import bench
from ..errors import ConfigError
from .common import refuse, say_json

HELP = "throughput figures of this machine (compare them only as ratios within one call)"


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--repeats", type=int, help="repeats of the core loop (median; default 5)")
    p.add_argument("--steps", type=int, help="steps of each in-process run (default 20000)")
    p.add_argument("--no-ros", action="store_true", help="skip the graph engines")
    p.add_argument(
        "--no-horizons", action="store_true", help="skip the long-horizon laws (mptc, direct_mpc)"
    )
    p.add_argument("--no-losses", action="store_true", help="skip the losses-and-temperatures row")
    p.add_argument(
        "--quick", action="store_true", help="short runs: a smoke test, not a measurement"
    )
    p.add_argument(
        "--graph",
        metavar="KEY,...",
        help="only these graph runs, by key (ros, ros_immediate, ros_sched_other, ros_unpinned, "
        "composed, ros_example_dtc; the --json keys without _steps_per_s)",
    )
    p.add_argument(
        "--external",
        metavar="torque_controller=COMMAND",
        help="also time your own torque controller in the graph, beside ours in the same call "
        "(the ros run, and only the graph runs --graph names besides); its figure is "
        "ros_external_LABEL",
    )
    p.add_argument("--label", metavar="NAME", help="with --external: names its figure")


def main(a: argparse.Namespace) -> int:
    if a.quick:
        refuse(a, "sets what --quick sets already (1 repeat of 2,000 steps)", "repeats", "steps")
    if a.no_ros:
        refuse(a, "chooses graph runs, and --no-ros skips them all", "graph", "external")
    if a.external is None:
        refuse(a, "names your controller's figure: give --external too", "label")
    node, sep, command = (a.external or "").partition("=")
    if a.external is not None and (node != "torque_controller" or not sep or not command):
        raise ConfigError(
            f"--external {a.external}: bench times a torque controller of your own: "
            "--external torque_controller=COMMAND"
        )
    d = bench(
        repeats=5 if a.repeats is None else a.repeats,
        steps=20000 if a.steps is None else a.steps,
        ros=not a.no_ros,
        quick=a.quick,
        graph=[k for k in (a.graph or "").split(",") if k],
        horizons=not a.no_horizons,
        external=command or None,
        label=a.label,
        losses=not a.no_losses,
    )
    if a.json:
        return say_json(d)
    rt = d.real_time_steps_per_s
    print(
        f"core in-process loop (im_paper, db_mptc, {d.steps} steps, median of "
        f"{len(d.core_steps_per_s_runs)}): {d.core_steps_per_s:,.0f} steps/s "
        f"({d.core_steps_per_s / rt:.2f}x real time)"
    )
    core = d.core_steps_per_s
    print(
        f"in-process with MCAP recording: {d.inprocess_recorded_steps_per_s:,.0f} steps/s "
        f"({d.inprocess_recorded_steps_per_s / core:.2f} of the core loop; each run against the "
        f"core run before it: {d.inprocess_recorded_of_core:.2f}, the median)"
    )
    print(
        f"reading the recording back and evaluating it (report): {d.report_steps_per_s:,.0f} "
        f"steps/s ({d.report_steps_per_s / core:.2f} x the core loop; each against the core run "
        f"before it: {d.report_x_core:.2f} x, the median)"
    )
    for g in d.graph:
        if g.steps_per_s is None and g.run.example_dtc and math.isnan(g.startup_s):
            print(f"{g.run.key} ({g.run.what}): no figure (examples/dtc_im is not here)")
        elif g.steps_per_s is None:
            print(f"{g.run.key} ({g.run.what}): no figure (too few progress samples for a slope)")
        else:
            print(
                f"{g.run.key} ({g.run.what}): {g.steps_per_s:,.0f} steps/s "
                f"({g.steps_per_s / rt:.2f}x real time, {g.steps_per_s / core:.2f} of the core "
                f"loop's median, {g.steps_per_s / g.core_near_steps_per_s:.2f} of the core loop "
                f"run right before and after it; slope over 20-90 % of one run, start-up "
                f"{g.startup_s:.1f} s excluded)"
            )
    if (lr := d.losses) is not None:
        print(
            f"losses and temperatures (im_paper, db_mptc, 2 µs dead time, {lr.steps} steps): "
            f"{lr.losses_steps_per_s:,.0f} steps/s against {lr.real_steps_per_s:,.0f} with "
            f"constant device drops: {lr.of_real:.2f} of it (each run against the drops run "
            f"before it, the median); {lr.of_core:.2f} of the ideal core loop; booked "
            f"{lr.booking}"
        )
    for name, us in d.compute_us_per_step.items():
        print(f"controller compute {name:<8} {us:6.2f} µs/step (median)")
    for h in d.horizons:
        decoder = f", {h.decoder} decoder" if h.decoder != "-" else ""
        print(
            f"{h.strategy} N={h.horizon:<2} ({h.scenario}, {h.steps} steps{decoder}): "
            f"{h.steps_per_s:,.0f} steps/s ({h.of_core:.3f} of the core loop's median, "
            f"{h.of_core_near:.3f} of the core loop run right before and after it); compute "
            f"{h.compute_us_median:,.1f} µs median, {h.compute_us_p99:,.1f} µs p99; "
            f"{h.nodes_mean:,.0f} nodes/step"
        )
    return 0
