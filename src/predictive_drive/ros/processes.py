"""Node processes a tool starts and owns: a ROS domain of its own, the parameter files a node is
started with, the process itself (its log with the run), and its end by PID.

A process started here runs in its own session (a Ctrl-C in the terminal reaches only its owner,
which ends it: SIGINT, then SIGTERM, then SIGKILL) with :func:`~.placement.ros_env`'s
environment (its domain, discovery on localhost, its owner's PID).
"""

from __future__ import annotations

import fcntl
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml

from ..errors import GraphError

__all__ = [
    "STOP_GRACE",
    "isolated_domain",
    "node_command",
    "parameter_args",
    "start_process",
    "stop_processes",
]

DOMAIN_RANGE = range(1, 101)  # 101..232 left to tests and users
LOCK_DIR = Path(tempfile.gettempdir()) / "predictive_drive_domains"


@contextmanager
def isolated_domain() -> Iterator[int]:
    """A ROS_DOMAIN_ID no other predictive_drive run on this machine holds (flock'ed). The lock
    folder and files are open to every user (mode 1777 and 0666), so a second user's runs take
    other domains instead of failing on a lock file the first one created."""
    LOCK_DIR.mkdir(exist_ok=True)
    try:
        os.chmod(LOCK_DIR, 0o1777)  # mkdir's mode is cut by the umask; an older one is mended
    except PermissionError:
        pass  # another user's folder: theirs to open
    start = os.getpid() % len(DOMAIN_RANGE)
    for i in range(len(DOMAIN_RANGE)):
        d = DOMAIN_RANGE[(start + i) % len(DOMAIN_RANGE)]
        path = LOCK_DIR / f"{d}.lock"
        try:
            fd = os.open(path, os.O_RDONLY | os.O_CREAT, 0o666)  # flock needs no write access
        except PermissionError:
            continue  # another user's file we cannot even read: their domain
        try:
            os.fchmod(fd, 0o666)
        except PermissionError:
            pass  # another user's file: readable is enough
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(fd)
            continue
        try:
            yield d
        finally:
            fcntl.flock(fd, fcntl.LOCK_UN)
            os.close(fd)
        return
    raise GraphError("no free ROS domain id: 100 predictive_drive runs at once?")


#: s a child may take to close once asked (messages in flight, the bag), before SIGTERM
STOP_GRACE = 45.0


def _stopped(pid: int) -> bool:
    """The process is stopped by a signal (SIGSTOP, a debugger): it cannot close until resumed."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] in ("T", "t")
    except (OSError, IndexError):
        return False


def stop_processes(procs: dict[str, subprocess.Popen[bytes]], *, grace: float = STOP_GRACE) -> None:
    """End every still-running child by PID: SIGINT (it finishes what is in flight and closes),
    then SIGTERM, then SIGKILL, each with a timeout; says so when it waits for a stopped one."""
    for sig, wait in ((signal.SIGINT, grace), (signal.SIGTERM, 2.0), (signal.SIGKILL, 5.0)):
        alive = {n: p for n, p in procs.items() if p.poll() is None}
        if not alive:
            return
        for p in alive.values():
            try:
                os.kill(p.pid, sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + wait
        said = set()
        while time.monotonic() < deadline and any(p.poll() is None for p in alive.values()):
            for n, p in alive.items():
                if n not in said and p.poll() is None and _stopped(p.pid):
                    said.add(n)
                    print(
                        f"predictive-drive: {n} (pid {p.pid}) is stopped by a signal; waiting up "
                        f"to {wait:.0f} s for it to go on and close",
                        file=sys.stderr,
                        flush=True,
                    )
            time.sleep(0.05)


def node_command(module: str) -> list[str]:
    """The command of one of this package's node processes, by module under ``ros/`` (as
    ``python -m``: the interpreter running this, whatever install it is)."""
    return [sys.executable, "-m", f"predictive_drive.ros.{module}"]


def parameter_args(
    scenario_file: str | Path, overrides: Mapping[str, Any], logs: Path
) -> list[str]:
    """``--ros-args --params-file SCENARIO --params-file OVERRIDES``: the overrides (node name →
    parameters) written to ``logs/overrides.yaml``. Node-specific entries beat wildcard ones and
    later files beat earlier ones, so the overrides win over the scenario's values."""
    doc = {node: {"ros__parameters": dict(params)} for node, params in overrides.items()}
    path = logs / "overrides.yaml"
    path.write_text(yaml.safe_dump(doc))
    return ["--ros-args", "--params-file", str(scenario_file), "--params-file", str(path)]


def start_process(
    command: list[str], *, log: Path, env: Mapping[str, str]
) -> subprocess.Popen[bytes]:
    """Start ``command`` in a session of its own, its output (both streams) into ``log``."""
    with log.open("wb") as out:  # the child keeps its own fd
        return subprocess.Popen(
            command,
            env=dict(env),
            stdout=out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            start_new_session=True,
        )
