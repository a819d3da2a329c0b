"""The processes a test started: found through /proc, ended with all they started."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path

from predictive_drive.ros.placement import FASTDDS_PROFILES, FASTDDS_PROFILES_ENV, cpu_plan


def parents() -> dict[int, int]:
    """Every process's parent PID (from /proc)."""
    out = {}
    for d in Path("/proc").iterdir():
        if d.name.isdigit():
            try:
                stat = (d / "stat").read_text()
            except OSError:
                continue
            out[int(d.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    return out


def descendants(pid: int) -> list[int]:
    """PIDs whose parent chain leads to ``pid`` (from /proc)."""
    parents_ = parents()
    out, todo = [], [pid]
    while todo:
        p = todo.pop()
        kids = [c for c, pp in parents_.items() if pp == p]
        out += kids
        todo += kids
    return out


def ended(pid: int) -> bool:
    """Gone, or a zombie waiting for whoever reaps orphans here."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] == "Z"
    except OSError:
        return True


def wait_until(
    condition: Callable[[], object],
    what: str,
    *,
    timeout: float = 120.0,
    proc: subprocess.Popen | None = None,
    every: float = 0.05,
) -> None:
    """Wait until ``condition()`` holds; fail saying ``what`` did not happen when ``timeout`` s
    pass, or with ``proc``'s output when it has ended meanwhile."""
    deadline = time.monotonic() + timeout
    while not condition():
        if proc is not None:
            assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, f"{what} (waited {timeout} s)"
        time.sleep(every)


def readline_within(stream, timeout: float) -> str:  # noqa: ANN001 - a text pipe
    """The next line of a process's text pipe, or fail after ``timeout`` s without one (a plain
    readline waits for ever on a process that says nothing more and does not end). Reads the
    raw descriptor a byte at a time, so nothing is buffered past the line."""
    import os
    import select

    fd, line = stream.fileno(), b""
    deadline = time.monotonic() + timeout
    while not line.endswith(b"\n"):
        left = deadline - time.monotonic()
        assert left > 0 and select.select([fd], [], [], left)[0], (
            f"no line within {timeout} s (so far: {line!r})"
        )
        byte = os.read(fd, 1)
        if not byte:
            break  # the process ended
        line += byte
    return line.decode()


def bag_bytes(bag: Path) -> int:
    """How many bytes the bag's .mcap file holds so far (0 before it exists)."""
    files = list(Path(bag).glob("*.mcap"))
    return files[0].stat().st_size if files else 0


def signal_tree(pid: int, sig: int) -> None:
    """``sig`` to ``pid`` and every process below it (those already gone are skipped)."""
    for p in [*descendants(pid), pid]:
        try:
            os.kill(p, sig)
        except ProcessLookupError:
            pass


def kill_if_running(p: subprocess.Popen) -> None:
    """A test's teardown of a process it started: SIGKILL if it is still running, then reap it."""
    if p.poll() is None:
        p.kill()
        p.wait(timeout=10)


def end_all(procs: list[subprocess.Popen], grace: float = 20.0) -> None:
    """End processes a test started, with everything they started: SIGTERM, then SIGKILL for
    whatever is still there after ``grace`` s."""
    for p in procs:
        signal_tree(p.pid, signal.SIGTERM)
    for p in procs:
        try:
            p.wait(timeout=grace)
        except subprocess.TimeoutExpired:
            signal_tree(p.pid, signal.SIGKILL)
            p.wait(timeout=10)


@contextmanager
def dask_cluster(tmp: Path, workers: int = 2) -> Iterator[str]:
    """A Dask scheduler and ``workers`` workers (one process, one thread each) on localhost,
    started with the `dask` command as a user starts them; yields the scheduler's address and
    ends them all on exit."""
    import json

    from distributed import Client

    dask = str(Path(sys.executable).with_name("dask"))
    info = tmp / "scheduler.json"
    procs: list[subprocess.Popen] = []
    with open(tmp / "cluster.log", "w") as log:
        start = {"stdout": log, "stderr": subprocess.STDOUT, "start_new_session": True}
        try:
            procs.append(subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port",
                                           "0", "--dashboard-address", ":0", "--scheduler-file",
                                           str(info)], **start))  # fmt: skip
            wait_until(info.exists, "the Dask scheduler did not start", timeout=60)
            for _ in range(workers):
                procs.append(subprocess.Popen([dask, "worker", "--scheduler-file", str(info),
                                               "--nworkers", "1", "--nthreads", "1",
                                               "--no-dashboard", "--host", "127.0.0.1"],
                                              **start))  # fmt: skip
            address = json.loads(info.read_text())["address"]
            with Client(address, timeout=30) as c:
                c.wait_for_workers(workers, timeout=60)
            yield address
        finally:
            end_all(procs)


def assert_placed(nodes: dict[str, int]) -> None:
    """Every thread of every node process keeps to the CPU of the launcher's plan and runs under
    SCHED_BATCH (the defaults), and the nodes run with the project's Fast DDS profile, which Fast
    DDS parses without error."""
    plan = cpu_plan("paired")
    for name, pid in nodes.items():
        for task in Path(f"/proc/{pid}/task").iterdir():
            status = (task / "status").read_text()
            allowed = re.search(r"Cpus_allowed_list:\s*(\S+)", status).group(1)
            if plan:
                assert allowed == plan[name], (name, task.name, allowed)
            assert os.sched_getscheduler(int(task.name)) == os.SCHED_BATCH, (name, task.name)
        environ = Path(f"/proc/{pid}/environ").read_bytes().split(b"\0")
        if not any(os.environ.get(k) for k in FASTDDS_PROFILES_ENV):  # else the user's wins
            assert f"FASTRTPS_DEFAULT_PROFILES_FILE={FASTDDS_PROFILES}".encode() in environ
