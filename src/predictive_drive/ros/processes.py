"""Node processes a tool starts and owns: a ROS domain of its own, the parameter files a node is
started with, the process itself (its log with the run), and its end by PID.

A process started here runs in its own session (a Ctrl-C in the terminal reaches only its owner,
which ends it: SIGINT, then SIGTERM, then SIGKILL) with :func:`~.placement.ros_env`'s
environment (its domain, discovery on localhost, its owner's PID).
"""

from __future__ import annotations

import fcntl
import os
import shlex
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import yaml

from .. import interrupts
from ..errors import ConfigError, GraphError

__all__ = [
    "AGAIN",
    "OWN_NODE_GRACE",
    "command_line",
    "end_own_nodes",
    "ended_how",
    "STOP_GRACE",
    "cpu_state",
    "TERM_GRACE",
    "SharedMemory",
    "domains_in_use",
    "ending_with_this_process",
    "is_stopped",
    "isolated_domain",
    "node_command",
    "parameter_args",
    "start_process",
    "stop_processes",
]

DOMAIN_RANGE = range(1, 101)  # 101..232 left to tests and users
#: the domains' lock files, machine-wide as the domain ids are: in /tmp whatever TMPDIR says (a
#: TMPDIR of its own, as each pytest worker's runs had, gave each its own lock files, and two runs
#: took one domain at once), in the temporary folder only where there is no /tmp
LOCK_DIR = (Path("/tmp") if Path("/tmp").is_dir() else Path(tempfile.gettempdir())) / (
    "predictive_drive_domains"
)


@contextmanager
def isolated_domain(domains: range = DOMAIN_RANGE) -> Iterator[int]:
    """A ROS_DOMAIN_ID of ``domains`` no other predictive_drive run (or test process) on this
    machine holds (flock'ed). The lock folder and files are open to every user (mode 1777 and
    0666), so a second user's runs take other domains instead of failing on a lock file the
    first one created."""
    LOCK_DIR.mkdir(exist_ok=True)
    try:
        os.chmod(LOCK_DIR, 0o1777)  # mkdir's mode is cut by the umask; an older one is mended
    except PermissionError:
        pass  # another user's folder: theirs to open
    start = os.getpid() % len(domains)
    for i in range(len(domains)):
        d = domains[(start + i) % len(domains)]
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
    raise GraphError(
        f"no free ROS domain id in {domains.start}..{domains.stop - 1}: "
        f"{len(domains)} predictive_drive runs at once?"
    )


def domains_in_use() -> list[int]:
    """The ROS domain ids predictive_drive runs on this machine hold now (their lock files are
    locked), for a message that tells a user which domain a running graph is on."""
    held = []
    for d in DOMAIN_RANGE:
        try:
            fd = os.open(LOCK_DIR / f"{d}.lock", os.O_RDONLY)
        except OSError:
            continue  # no run ever took it, or another user's we cannot read
        try:
            fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
        except OSError:
            held.append(d)
        finally:
            os.close(fd)  # a lock taken here goes with its descriptor
    return held


#: s a child may take to close once asked (messages in flight, the bag), before SIGTERM
STOP_GRACE = 45.0
#: s a child may take to close once told to finish quickly (SIGTERM), before SIGKILL: its
#: publishers wait at most 1 s for acknowledgements, the logger takes what is in flight (until a
#: second passes without a message) and closes the bag
TERM_GRACE = 15.0


#: s a stop waits for children before it says which it still waits for, and how long
SAY_WAITING = 5.0

#: what a second Ctrl-C while children close does
AGAIN = (
    "predictive-drive: interrupted again: asking the nodes to finish quickly (Ctrl-C once more "
    "leaves them to close on their own)"
)


def cpu_state(pid: int) -> tuple[float, bool] | None:
    """The CPU time (user + system, s) process ``pid`` has used, all its threads, and whether its
    main thread is running or waiting for a CPU (state R) rather than waiting for something
    (None: gone). On a loaded machine a computing process gets a share of a CPU only, but it is
    always R."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
        return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK"), fields[0] == "R"
    except (OSError, IndexError, ValueError):
        return None


def is_stopped(pid: int) -> bool:
    """The process is stopped by a signal (SIGSTOP, a debugger): it cannot close until resumed."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0] in ("T", "t")
    except (OSError, IndexError):
        return False


def stop_processes(
    procs: dict[str, subprocess.Popen[bytes]],
    *,
    grace: float = STOP_GRACE,
    urgent: bool = False,
    announce: str = "",
) -> list[str]:
    """End every still-running child by PID: SIGINT (it finishes what is in flight and closes),
    then SIGTERM (it finishes quickly: use it at once, ``urgent``, when a peer is gone and the
    acknowledgements it owes will never come), then SIGKILL, each with a timeout; says so when
    it waits for a stopped one. A Ctrl-C (or SIGTERM) while it waits moves on to SIGTERM; one
    more leaves the children to finish on their own. ``announce``: a line for stderr, printed
    once presses are counted (one that comes right after it is acted on, never raised).
    Returns the children still running then (none when it saw them all end)."""
    phases = [(signal.SIGINT, grace), (signal.SIGTERM, TERM_GRACE), (signal.SIGKILL, 5.0)]
    with interrupts.counting() as presses:
        if announce:
            print(announce, file=sys.stderr, flush=True)
        acted = 0  # presses acted on: each moves the stop on by one step
        for sig, wait in phases[1:] if urgent else phases:
            alive = {n: p for n, p in procs.items() if p.poll() is None}
            if not alive:
                return []
            for p in alive.values():
                try:
                    os.kill(p.pid, sig)
                except ProcessLookupError:
                    pass
            then = {signal.SIGINT: "SIGTERM", signal.SIGTERM: "SIGKILL"}.get(sig)
            pressed = _pressed_since(presses, acted)
            if _wait_for(alive, wait, pressed, sent=sig.name, then=then) and sig != signal.SIGKILL:
                acted += 1
                if sig != signal.SIGINT:
                    break  # pressed again while they finish quickly: leave them to it
                print(AGAIN, file=sys.stderr, flush=True)
    return [n for n, p in procs.items() if p.poll() is None]


def ended_how(code: int | None) -> str:
    """How a child ended, in words: by its exit status, or by the signal that killed it."""
    if code is None:
        return "is still running"
    if code < 0:
        return f"was killed by signal {-code} ({signal.Signals(-code).name})"
    return f"exited with status {code}"


#: s a user's node may take to exit on its own once its part is over (after its last message),
#: and then to end once sent SIGTERM, before SIGKILL
OWN_NODE_GRACE = 5.0


def end_own_nodes(procs: Mapping[str, subprocess.Popen[bytes]], *, after: str) -> None:
    """End the user's nodes ``procs`` still running once their part is over (``after``: what
    is over, e.g. "the run's last step"): each may exit on its own within
    :data:`OWN_NODE_GRACE` s; then SIGTERM; then, :data:`OWN_NODE_GRACE` s later, SIGKILL,
    each said on stderr. The contract asks a node to exit after its last message; one that does
    not must not keep the command waiting."""
    deadline = time.monotonic() + OWN_NODE_GRACE
    while time.monotonic() < deadline and any(p.poll() is None for p in procs.values()):
        time.sleep(0.05)
    for sig, then in ((signal.SIGTERM, "ending it"), (signal.SIGKILL, "killing it")):
        alive = {n: p for n, p in procs.items() if p.poll() is None}
        for name, p in alive.items():
            waited = "" if sig == signal.SIGTERM else "; it ignored SIGTERM"
            print(
                f"predictive-drive: your {name} (pid {p.pid}) has not exited "
                f"{OWN_NODE_GRACE:g} s after {after}{waited}: {then} ({sig.name})",
                file=sys.stderr,
                flush=True,
            )
            try:
                os.kill(p.pid, sig)
            except ProcessLookupError:
                pass
        deadline = time.monotonic() + OWN_NODE_GRACE
        while time.monotonic() < deadline and any(p.poll() is None for p in alive.values()):
            time.sleep(0.05)


def _pressed_since(presses: list[int], before: int) -> Callable[[], bool]:
    return lambda: presses[0] > before


def _wait_for(
    alive: dict[str, subprocess.Popen[bytes]],
    wait: float,
    pressed: Callable[[], bool],
    *,
    sent: str = "",
    then: str | None = None,
) -> bool:
    """Wait up to ``wait`` s for ``alive`` to end; True when ``pressed()`` cut it short. After
    :data:`SAY_WAITING` s it names the children it still waits for (``sent`` them, ``then``
    next: a node of one's own may ignore a signal, and a silent minute is no answer)."""
    start = time.monotonic()
    deadline = start + wait
    said = set()
    while time.monotonic() < deadline and any(p.poll() is None for p in alive.values()):
        if pressed():
            return True
        now = time.monotonic()
        if then and now - start > SAY_WAITING and "waiting" not in said:
            said.add("waiting")
            names = ", ".join(f"{n} (pid {p.pid})" for n, p in alive.items() if p.poll() is None)
            again = f"{then} now" if then == "SIGTERM" else "leave it to end on its own"
            print(
                f"predictive-drive: still waiting for {names} to end after {sent}: up to "
                f"{deadline - now:.0f} s more, then {then} (Ctrl-C again: {again})",
                file=sys.stderr,
                flush=True,
            )
        for n, p in alive.items():
            if n not in said and p.poll() is None and is_stopped(p.pid):
                said.add(n)
                print(
                    f"predictive-drive: {n} (pid {p.pid}) is stopped by a signal; waiting up "
                    f"to {wait:.0f} s for it to go on and close",
                    file=sys.stderr,
                    flush=True,
                )
        time.sleep(0.05)
    return False


#: where Fast DDS keeps its shared-memory segments, ports and their locks and semaphores
SHM_DIR = Path("/dev/shm")
_FASTDDS_SHM = ("fastrtps_", "sem.fastrtps_")


def _shm_files(pid: int | str) -> set[str]:
    """Fast DDS's files in /dev/shm that process ``pid`` maps or holds open (empty when it is
    gone or not ours to read)."""
    names: set[str] = set()
    proc = Path(f"/proc/{pid}")
    try:
        for line in (proc / "maps").read_text().splitlines():
            path = line.rpartition(" ")[2]
            if path.startswith("/dev/shm/"):
                names.add(path[9:])
        for fd in (proc / "fd").iterdir():
            target = os.readlink(fd)
            if target.startswith("/dev/shm/"):
                names.add(target[9:])
    except OSError:
        pass
    return {n for n in names if n.startswith(_FASTDDS_SHM)}


class SharedMemory:
    """The Fast DDS shared-memory files of the node processes a tool started.

    A node killed outright (SIGKILL, a crash) cannot release them: its own segment and port
    stay, and the shared ports it had opened keep its reference and outlive every survivor (8-16
    files per killed node, measured). :meth:`sample` records, while the children run, what each
    maps or holds open; :meth:`clean`, once they have ended, removes those of them no process on
    the machine uses any more — only files these children used, never another's."""

    def __init__(self) -> None:
        self.seen: set[str] = set()

    def sample(self, pids: list[int]) -> None:
        for pid in pids:
            self.seen |= _shm_files(pid)

    def clean(self) -> list[str]:
        """Remove what the children left that nothing uses; returns the names removed."""
        if not self.seen:
            return []
        # a port's named mutex is opened only while the port is (un)registered, so no sample
        # sees it mapped: it goes with its port
        ports = (n for n in self.seen if n.startswith("fastrtps_port") and not n.endswith("_el"))
        candidates = self.seen | {f"sem.{n}_mutex" for n in ports}
        in_use: set[str] = set()
        for proc in Path("/proc").iterdir():
            if proc.name.isdigit():
                in_use |= _shm_files(proc.name) & candidates
        removed = []
        for name in sorted(candidates - in_use):
            try:
                (SHM_DIR / name).unlink()
                removed.append(name)
            except FileNotFoundError:
                pass  # its owner removed it on the way out
            except OSError:
                pass  # not ours to remove: left as it is
        return removed


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


#: run a command so that it ends when the process that started it dies, even by SIGKILL: what a
#: user's own node gets, which cannot watch the launcher as this package's nodes do. SIGTERM at
#: once (Linux's PR_SET_PDEATHSIG survives exec), and SIGKILL GRACE s later from a watchdog
#: forked before the exec (a child of the node: it goes when the node does) for a node that
#: ignores SIGTERM. The launcher's placement (CPUs, scheduling policy: placement.CPUS_ENV,
#: SCHED_ENV) is applied before the exec, so the node's threads inherit it as ours do.
#: ``python -c THIS PARENT_PID GRACE COMMAND...``
_END_WITH_PARENT = """
import ctypes, os, signal, sys, time
from predictive_drive.ros.placement import apply_placement
apply_placement()
launcher, grace = int(sys.argv[1]), float(sys.argv[2])
def started(pid):  # None: gone or a zombie
    try:
        fields = open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()
    except OSError:
        return None
    return None if fields[0] == "Z" else fields[19]
ctypes.CDLL(None, use_errno=True).prctl(1, signal.SIGTERM)  # 1: PR_SET_PDEATHSIG
born = started(launcher)
if os.getppid() != launcher or born is None:
    os._exit(1)  # the launcher died already
node = os.getpid()
if os.fork() == 0:
    while os.getppid() == node and started(launcher) == born:
        time.sleep(0.2)
    deadline = time.monotonic() + grace
    while os.getppid() == node and time.monotonic() < deadline:
        time.sleep(0.1)
    if os.getppid() == node:
        os.kill(node, signal.SIGKILL)
    os._exit(0)
os.execvp(sys.argv[3], sys.argv[3:])
"""


def ending_with_this_process(command: list[str]) -> list[str]:
    """``command`` wrapped so that it ends when this process dies (see :data:`_END_WITH_PARENT`:
    SIGTERM, and SIGKILL :data:`OWN_NODE_GRACE` s later); the same PID runs the command once it
    starts."""
    return [sys.executable, "-c", _END_WITH_PARENT, str(os.getpid()), str(OWN_NODE_GRACE), *command]


def command_line(text: str, *, option: str) -> list[str]:
    """A user's command line as the launcher will start it (POSIX shell words, no shell): its
    words, once its program is found and executable; ConfigError naming ``option`` (what the
    user wrote it in, e.g. ``--external torque_controller=...``) and why otherwise. Checked
    before anything starts, so a typo costs no run."""
    try:
        words = shlex.split(text)
    except ValueError as e:  # "No closing quotation", "No escaped character"
        raise ConfigError(
            f"{option}{text}: does not parse as a command line ({str(e).lower()})"
        ) from None
    if not words:
        raise ConfigError(f"{option}{text}: an empty command")
    program = words[0]
    if "/" not in program:
        why = "" if shutil.which(program) else "is not found on PATH"
    elif not Path(program).exists():
        why = "does not exist"
    elif Path(program).is_dir():
        why = "is a directory, not a program"
    elif not os.access(program, os.X_OK):
        why = "is not executable (chmod +x it, or start it with its interpreter)"
    else:
        why = ""
    if why:
        raise ConfigError(f"{option}{text}: {program!r} {why}")
    return words


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
