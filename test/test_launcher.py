"""The launcher's own machinery against real peers: a strategy switch whose first request is
lost is sent again; children are stopped SIGINT → SIGTERM → SIGKILL; a closing node that hangs
is ended by SIGALRM."""

from __future__ import annotations

import contextlib
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from predictive_drive.config import load_scenario
from procs import kill_if_running

pytestmark = pytest.mark.process


class _Dropped(Exception):
    """Raised by the fake controller's set_parameters service: no answer goes out."""


@contextlib.contextmanager
def controller_that_loses_the_first_request(domain: int, clock_s: float) -> Iterator[list]:
    """A node /drive/torque_controller with a real `strategy` parameter whose first
    set_parameters request is taken and never answered (as a request lost on a fresh
    discovery), publishing /clock at ``clock_s``; yields the requests it took."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor
    from rosgraph_msgs.msg import Clock

    from predictive_drive.interface import TOPICS
    from predictive_drive.ros.transport import qos, ros_context

    taken: list = []
    stop = threading.Event()
    with ros_context(domain) as ctx:
        node = rclpy.create_node("torque_controller", namespace="/drive", context=ctx)
        node.declare_parameter("strategy", "mptc")
        srv = next(s for s in node.services if s.srv_name.endswith("/set_parameters"))
        answer = srv.callback

        def set_parameters(request, response):
            taken.append(request)
            if len(taken) == 1:
                raise _Dropped
            return answer(request, response)

        srv.callback = set_parameters
        clock = node.create_publisher(Clock, TOPICS["clock"].name, qos(TOPICS["clock"].qos))
        ex = SingleThreadedExecutor(context=ctx)
        ex.add_node(node)

        def spin() -> None:
            sec, ns = int(clock_s), round((clock_s % 1) * 1e9)
            while not stop.is_set():
                msg = Clock()
                msg.clock.sec, msg.clock.nanosec = sec, ns
                clock.publish(msg)
                with contextlib.suppress(_Dropped):
                    ex.spin_once(timeout_sec=0.05)

        t = threading.Thread(target=spin, daemon=True)
        t.start()
        try:
            yield taken
        finally:
            stop.set()
            t.join(timeout=5)
            ex.shutdown(timeout_sec=1.0)
            node.destroy_node()


def test_a_lost_switch_request_is_sent_again(tmp_path):
    """The launcher's watcher sends the switch when /clock reaches it; its first request is lost;
    after RESEND_AFTER it is sent again and answered: the strategy is set, no error."""
    from predictive_drive.ros.launcher import _ClockWatcher
    from predictive_drive.ros.params import RESEND_AFTER
    from predictive_drive.ros.processes import isolated_domain

    sc = load_scenario("im_short")
    with (
        isolated_domain() as domain,
        controller_that_loses_the_first_request(domain, 0.05) as taken,
    ):
        w = _ClockWatcher(domain, sc, [(0.05, "db_mptc")], None, tmp_path)
        try:
            t0 = time.monotonic()
            while (w.pending or w._inflight is not None) and time.monotonic() - t0 < 30:
                w.spin(0.05)
            took = time.monotonic() - t0
            errors = w.final_errors()
        finally:
            w.close()
    assert errors == []
    assert len(taken) == 2 and took > RESEND_AFTER  # answered only when sent again
    assert [p.value.string_value for p in taken[1].parameters] == ["db_mptc"]


def test_a_ctrl_c_inside_the_watchers_callback_is_raised_when_its_spin_returns(tmp_path, capfd):
    """The command line's Ctrl-C lands while the launcher's watcher draws progress from /clock
    (the more often the slower the terminal draws): it is raised once the spin has returned,
    in the launcher's own loop. The drawing is not cut, and rclpy's executor does not log the
    press as a FATAL callback exception with its traceback (was: both, before the stop's line;
    the launcher's loop then stopped the run as usual)."""
    import os

    from predictive_drive import interrupts
    from predictive_drive.ros.launcher import _ClockWatcher
    from predictive_drive.ros.processes import isolated_domain

    drawn: list[int] = []

    def progress(k: int) -> None:
        if not drawn:
            os.kill(os.getpid(), signal.SIGINT)  # the press, inside the callback
        time.sleep(0.01)  # the handler runs here when the press is not held back
        drawn.append(k)

    before = signal.signal(signal.SIGINT, interrupts.interrupt)
    try:
        with (
            isolated_domain() as domain,
            controller_that_loses_the_first_request(domain, 0.05),  # it publishes /clock
        ):
            w = _ClockWatcher(domain, load_scenario("im_short"), [], progress, tmp_path)
            try:
                with pytest.raises(KeyboardInterrupt):
                    deadline = time.monotonic() + 30
                    while time.monotonic() < deadline:
                        w.spin(0.05)
            finally:
                w.close()
    finally:
        signal.signal(signal.SIGINT, before)
    assert drawn  # the callback the press came in ran to its end (and any after it in the batch)
    assert "Exception in" not in capfd.readouterr().err


def test_the_param_command_sends_a_lost_request_again(monkeypatch):
    from predictive_drive.ros.params import param
    from predictive_drive.ros.processes import isolated_domain

    with isolated_domain() as domain, controller_that_loses_the_first_request(domain, 0.0) as taken:
        monkeypatch.setenv("ROS_DOMAIN_ID", str(domain))
        assert param(node="torque_controller", name="strategy", value="db_mptc") == "db_mptc"
    assert len(taken) == 2


CHILD = """
import signal, sys, time
log, quits_on = sys.argv[1], sys.argv[2].split(",")
def on(sig, _f):
    name = signal.Signals(sig).name
    open(log, "a").write(name + "\\n")
    if name in quits_on:
        sys.exit(0)
for s in (signal.SIGINT, signal.SIGTERM):
    signal.signal(s, on)
print("ready", flush=True)
while True:
    time.sleep(0.05)
"""


@pytest.mark.parametrize("urgent", [False, True])
def test_children_are_stopped_sigint_then_sigterm_then_sigkill(tmp_path, monkeypatch, urgent):
    """One child ends on SIGINT, one only on SIGTERM, one never: each gets what it needs and no
    more, the last is killed; urgent (a peer is gone) starts at SIGTERM."""
    from predictive_drive.ros import processes

    monkeypatch.setattr(processes, "TERM_GRACE", 1.0)
    quits = {"on_int": "SIGINT", "on_term": "SIGTERM", "never": "-"}
    procs = {}
    for name, q in quits.items():
        procs[name] = subprocess.Popen(
            [sys.executable, "-c", CHILD, str(tmp_path / name), q],
            stdout=subprocess.PIPE, start_new_session=True,
        )  # fmt: skip
    try:
        for p in procs.values():
            assert p.stdout.readline() == b"ready\n"
        assert processes.stop_processes(procs, grace=1.0, urgent=urgent) == []
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.kill()
            p.wait(timeout=10)

    def got(name: str) -> list[str]:
        f = tmp_path / name
        return f.read_text().split() if f.exists() else []

    if urgent:
        assert (got("on_int"), got("on_term"), got("never")) == (["SIGTERM"],) * 3
        assert procs["on_int"].returncode == -signal.SIGKILL  # it ends on SIGINT only
        assert procs["on_term"].returncode == 0
    else:
        assert got("on_int") == ["SIGINT"] and procs["on_int"].returncode == 0
        assert got("on_term") == ["SIGINT", "SIGTERM"] and procs["on_term"].returncode == 0
        assert got("never") == ["SIGINT", "SIGTERM"]
    assert procs["never"].returncode == -signal.SIGKILL


def test_a_press_that_answers_the_stop_line_moves_the_stop_on(tmp_path, monkeypatch):
    """The stop's line ("Ctrl-C again to ...") is printed once presses are counted: a Ctrl-C
    that comes the instant it is read moves the stop on to SIGTERM (the child ends at once)
    instead of being raised in the command (the flaky repeated-Ctrl-C test of the graph: a
    press between the line and the stop taking presses over escaped, the stop began again
    and the bag was killed unclosed)."""
    import io
    import os

    from predictive_drive.ros import processes

    class Escaped(Exception):
        pass

    def escape(_signum, _frame):  # what the command line's handler does with a press
        raise Escaped

    class Reader(io.StringIO):  # a user who presses Ctrl-C the moment the line shows
        def write(self, text):
            n = super().write(text)
            if "Ctrl-C again" in text:
                os.kill(os.getpid(), signal.SIGINT)
            return n

    said = Reader()
    monkeypatch.setattr(sys, "stderr", said)
    p = subprocess.Popen(
        [sys.executable, "-c", CHILD, str(tmp_path / "child"), "SIGTERM"],
        stdout=subprocess.PIPE, start_new_session=True,
    )  # fmt: skip
    before = signal.signal(signal.SIGINT, escape)
    try:
        assert p.stdout.readline() == b"ready\n"
        t0 = time.monotonic()
        left = processes.stop_processes(
            {"child": p}, grace=60.0, announce="stopping (Ctrl-C again to hurry)"
        )
        assert left == [] and time.monotonic() - t0 < 30  # not the 60 s of the SIGINT phase
    finally:
        signal.signal(signal.SIGINT, before)
        if p.poll() is None:
            p.kill()
        p.wait(timeout=10)
    assert said.getvalue().splitlines()[1] == processes.AGAIN  # the press was acted on


def test_a_node_that_hangs_at_its_exit_after_closing_is_ended_by_sigalrm():
    """The alarm set by closing() lasts through the process's exit: a teardown that hangs after
    the close (here an exit handler; in a run, rclpy's or Fast DDS's) ends by SIGALRM (was: the
    alarm was cleared at the block's end, and a node left by its launcher hung for minutes)."""
    code = (
        "import atexit, time\n"
        "from predictive_drive.ros import node_base\n"
        "node_base.CLOSE_TIMEOUT = 1\n"
        "atexit.register(time.sleep, 30)\n"
        "with node_base.closing():\n"
        "    print('closing', flush=True)\n"
    )
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE)
    try:
        assert p.stdout.readline() == b"closing\n"
        p.wait(timeout=20)
    finally:
        kill_if_running(p)
    assert p.returncode == -signal.SIGALRM


def test_a_signal_inside_the_stop_handler_does_not_hang_the_node(tmp_path):
    """A second signal that arrives while a node handles its first (a double Ctrl-C, the
    launcher's SIGTERM after the terminal's SIGINT) runs the handler again inside itself. Here
    every line the handler executes sends another (test/reentrant_signals.py): the node still
    ends. Was: the handler set a threading.Event, whose lock the nested call waited for forever
    (a torque controller left in a futex for minutes, its run's test failing after 90 s)."""
    import os

    from predictive_drive.config import resolve_scenario_path
    from predictive_drive.ros.placement import LAUNCHER_ENV, ros_env

    env = ros_env(int(os.environ["ROS_DOMAIN_ID"]), log_dir=tmp_path)
    env.pop(LAUNCHER_ENV)  # a node on its own: no launcher to watch
    script = str(Path(__file__).with_name("reentrant_signals.py"))
    scenario = str(resolve_scenario_path("im_short"))
    p = subprocess.Popen(
        [sys.executable, script, "torque_controller_node", "--ros-args", "--params-file",
         scenario],
        env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, start_new_session=True,
    )  # fmt: skip
    try:
        assert p.stdout.readline() == b"handlers installed\n"
        time.sleep(0.5)  # in its spin loop, waiting for peers that never come
        p.send_signal(signal.SIGINT)
        p.wait(timeout=30)
    finally:
        kill_if_running(p)
    assert p.returncode == 0


def test_a_closing_node_that_hangs_is_ended_by_sigalrm(tmp_path):
    """Without a launcher to escalate, a node whose closing hangs ends after CLOSE_TIMEOUT (set
    to 1 s here) by SIGALRM; Ctrl-C and SIGTERM during the closing do not cut it short."""
    code = (
        "import sys, time\n"
        "from predictive_drive.ros import node_base\n"
        "node_base.CLOSE_TIMEOUT = 1\n"
        "with node_base.closing():\n"
        "    print('closing', flush=True)\n"
        "    time.sleep(30)\n"
    )
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE)
    try:
        assert p.stdout.readline() == b"closing\n"
        t0 = time.monotonic()
        p.send_signal(signal.SIGINT)
        p.send_signal(signal.SIGTERM)
        p.wait(timeout=20)
        took = time.monotonic() - t0
    finally:
        kill_if_running(p)
    assert p.returncode == -signal.SIGALRM
    assert took < 20  # not the 30 s of the hang
