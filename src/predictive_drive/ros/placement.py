"""The launcher ↔ node contract, free of rclpy: the environment a launcher hands each node process
(its launcher's PID, CPUs, scheduling policy, Fast DDS profile, ROS domain) and how a node applies
it to itself. ``ros2 run`` users get the same by ``taskset -c`` and ``chrt --batch 0``."""

from __future__ import annotations

import os
import sys
import tempfile
from collections.abc import Callable, MutableMapping, Sequence
from pathlib import Path

from ..errors import GraphError

__all__ = [
    "AFFINITIES",
    "CPUS_ENV",
    "FASTDDS_PROFILES",
    "FASTDDS_PROFILES_ENV",
    "LAUNCHER_ENV",
    "SCHED_ENV",
    "SCHED_POLICIES",
    "STOP_REASON_FILE",
    "apply_placement",
    "cpu_plan",
    "launcher_pid",
    "ros_env",
    "ros_log_dir",
    "stop_reason",
    "write_stop_reason",
]

#: set by the launcher to its PID for its children: a node whose parent is no longer that process
#: (the launcher was killed outright, e.g. SIGKILL, and could not stop them) ends the run itself
LAUNCHER_ENV = "PREDICTIVE_DRIVE_LAUNCHER_PID"
#: set by the launcher for each child: the CPUs (comma-separated ids) the node process keeps to,
#: applied before rclpy starts its threads (what ``taskset -c`` does for ``ros2 run``)
CPUS_ENV = "PREDICTIVE_DRIVE_CPUS"
#: ``--affinity`` values: ``paired`` keeps each lock-step pair on one CPU, ``none`` leaves the
#: placement to the kernel
AFFINITIES = ("paired", "none")
#: set by the launcher for each child: the Linux scheduling policy of every thread of the node
SCHED_ENV = "PREDICTIVE_DRIVE_SCHED"
#: ``--sched`` values → policy. ``batch`` (SCHED_BATCH, same priority as normal): a thread that
#: wakes does not preempt the one running on its CPU, so a node finishes publishing to all its
#: readers before the reader it woke on its CPU runs; ``other``: the kernel's default
SCHED_POLICIES = {"batch": os.SCHED_BATCH, "other": os.SCHED_OTHER}
#: Fast DDS settings for the graph (see the file's comment); the 2.x and 3.x variable names
FASTDDS_PROFILES = Path(__file__).with_name("fastdds_profiles.xml")
FASTDDS_PROFILES_ENV = ("FASTRTPS_DEFAULT_PROFILES_FILE", "FASTDDS_DEFAULT_PROFILES_FILE")


def ros_log_dir(env: MutableMapping[str, str], log_dir: Path | None = None) -> None:
    """Where rcl writes its log files: ``log_dir`` (a run's ``logs/``), or a folder of this
    user's under the temp folder — not ``~/.ros/log``, which a user without a writable HOME does
    not have (rclpy then fails to start) — unless the user chose with ROS_LOG_DIR or ROS_HOME."""
    if env.get("ROS_LOG_DIR") or env.get("ROS_HOME"):
        return
    if log_dir is None:
        log_dir = Path(tempfile.gettempdir()) / f"predictive_drive_ros_log_{os.getuid()}"
    env["ROS_LOG_DIR"] = str(log_dir)


def ros_env(domain: int, *, log_dir: Path | None = None) -> dict[str, str]:
    """The environment of the launcher's children: its ROS domain, discovery on localhost, its
    PID, the project's Fast DDS profile (unless the user has one), the ament prefix, and rcl's
    log folder (:func:`ros_log_dir`: ``log_dir``, the run's ``logs/``)."""
    env = dict(os.environ)
    ros_log_dir(env, log_dir)
    env["ROS_DOMAIN_ID"] = str(domain)
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    env["PYTHONUNBUFFERED"] = "1"
    env[LAUNCHER_ENV] = str(os.getpid())  # nodes end themselves if this process dies
    if not any(env.get(k) for k in FASTDDS_PROFILES_ENV):  # a user's own profiles win
        env.update(dict.fromkeys(FASTDDS_PROFILES_ENV, str(FASTDDS_PROFILES)))
    # the PyPI wheels do not set it; the ament index lives under the venv's share/
    prefixes = [p for p in env.get("AMENT_PREFIX_PATH", "").split(os.pathsep) if p]
    if sys.prefix not in prefixes:
        prefixes.insert(0, sys.prefix)
    env["AMENT_PREFIX_PATH"] = os.pathsep.join(prefixes)
    return env


#: the file in a run's log folder where the launcher writes why it stopped the run, before it
#: stops the nodes: the recorder puts it in the bag's outcome (it cannot see a peer's exit)
STOP_REASON_FILE = "stop_reason.txt"


def write_stop_reason(logs: Path, reason: str) -> None:
    """The launcher: the run is stopped for ``reason`` (one line)."""
    (logs / STOP_REASON_FILE).write_text(reason.splitlines()[0] if reason else "")


def stop_reason(logs: Path) -> str:
    """A node: why its launcher stopped the run ('' when it did not say so)."""
    try:
        return (logs / STOP_REASON_FILE).read_text().strip()
    except OSError:
        return ""


def launcher_pid() -> int:
    """The PID of the launcher that started this node process (0: started by hand)."""
    return int(os.environ.get(LAUNCHER_ENV, "0"))


def cpu_plan(affinity: str, cpus: Sequence[int] | None = None) -> dict[str, str]:
    """Node → CPU list for the separate-process graph (empty: no pinning).

    ``paired``: plant and torque_controller share one CPU, speed_pi and metrics_logger another.
    Plant and controller take turns on the critical path (state k → command k → state k+1), so on
    one CPU each wakes the other without a cross-CPU wake-up; the PI and the logger work beside
    them. On this project's 2-vCPU machine that is ~1.5-1.7x the steps/s of free placement
    (``predictive-drive bench`` prints both). Fewer than two usable CPUs: no pinning.
    """
    if affinity not in AFFINITIES:
        raise GraphError(f"--affinity: {affinity!r} is not one of {', '.join(AFFINITIES)}")
    usable = sorted(os.sched_getaffinity(0) if cpus is None else cpus)
    if affinity == "none" or len(usable) < 2:
        return {}
    a, b = str(usable[0]), str(usable[1])
    return {"plant": a, "torque_controller": a, "speed_pi": b, "metrics_logger": b}


def apply_placement() -> None:
    """Apply the placement its launcher chose to this process: the CPUs (:data:`CPUS_ENV`) and the
    scheduling policy (:data:`SCHED_ENV`) of every thread it has now (imports may have started
    some) and, since this runs before rclpy and DDS start theirs, of every later one (threads
    inherit both)."""
    cpus = os.environ.get(CPUS_ENV, "").strip()
    sched = os.environ.get(SCHED_ENV, "").strip()
    if cpus:
        try:
            chosen = {int(c) for c in cpus.split(",")}
            _each_thread(lambda tid: os.sched_setaffinity(tid, chosen))
        except (ValueError, OSError) as e:
            raise SystemExit(
                f"{CPUS_ENV}={cpus!r}: cannot keep to these CPUs ({e}); expected "
                f"comma-separated ids of {sorted(os.sched_getaffinity(0))}"
            ) from None
    if sched:
        if sched not in SCHED_POLICIES:
            raise SystemExit(
                f"{SCHED_ENV}={sched!r}: unknown scheduling policy; expected one of "
                f"{', '.join(SCHED_POLICIES)}"
            )
        policy = SCHED_POLICIES[sched]
        try:
            _each_thread(lambda tid: os.sched_setscheduler(tid, policy, os.sched_param(0)))
        except OSError as e:
            raise SystemExit(f"{SCHED_ENV}={sched!r}: cannot use this policy ({e})") from None


def _each_thread(apply: Callable[[int], None]) -> None:
    for tid in os.listdir("/proc/self/task"):
        try:
            apply(int(tid))
        except ProcessLookupError:
            pass  # a thread that ended meanwhile
