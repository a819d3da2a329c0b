"""End to end: the four nodes as real processes (docs/ros.md; docs/recordings.md). Each test owns
what it starts and ends it by PID in teardown; a hung peer fails the test through timeouts instead
of hanging CI."""

from __future__ import annotations

import contextlib
import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from mcapcheck import ordering_faults
from predictive_drive.api.report import report
from predictive_drive.api.run import run
from predictive_drive.config import load_scenario
from predictive_drive.errors import ConfigError
from predictive_drive.readback import read_bag
from procs import (
    assert_placed,
    bag_bytes,
    descendants,
    ended,
    kill_if_running,
    signal_tree,
    wait_until,
)

pytestmark = pytest.mark.process

CLI = [sys.executable, "-m", "predictive_drive.cli"]


def node_pids(line: str) -> dict[str, int]:
    return {n: int(p) for n, p in re.findall(r"(\w+) pid (\d+)", line)}


@pytest.fixture
def cli_run(tmp_path):
    """Start `predictive-drive run` as a child; kill it (and its nodes) by PID in teardown."""
    started: list[subprocess.Popen[str]] = []

    def start(*args: str) -> tuple[subprocess.Popen[str], str]:
        p = subprocess.Popen(
            [*CLI, "run", *args],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        started.append(p)
        line = p.stderr.readline()  # "graph on ROS_DOMAIN_ID=N: plant pid ..., ..."
        assert "ROS_DOMAIN_ID=" in line, line
        return p, line

    yield start
    for p in started:
        signal_tree(p.pid, signal.SIGKILL)
        p.wait(timeout=10)


def assert_same_run(a, b) -> None:
    """Two traces hold the same state, reference and command sequences (and losses) bit for bit
    (the measured compute_ns aside)."""
    np.testing.assert_array_equal(a.state, b.state)
    np.testing.assert_array_equal(a.losses, b.losses)
    np.testing.assert_array_equal(a.reference, b.reference)
    np.testing.assert_array_equal(a.command[:, :-1], b.command[:, :-1])


def run_against_inprocess(engine: str, duration: float, tmp_path: Path) -> tuple:
    """im_short on ``engine`` and in-process; the engine's recording complete, both the same run
    bit for bit. Returns (engine result, in-process result)."""
    g = run("im_short", duration=duration, engine=engine, out=tmp_path / engine)
    i = run("im_short", duration=duration, engine="inprocess", out=tmp_path / "inprocess")
    a, info = read_bag(g.bag)
    b, _ = read_bag(i.bag)
    assert info.complete and a.steps == b.steps
    assert_same_run(a, b)
    return g, i


def test_graph_run_equals_inprocess_bit_for_bit(tmp_path):
    before = set(descendants(os.getpid()))
    ros, inp = run_against_inprocess("ros", 0.1, tmp_path)
    assert ros.steps == 2000
    assert ros.metrics.t_rmse == inp.metrics.t_rmse
    # the recording holds every topic, decodable by the independent reader
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    with AnyReader([ros.bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as r:
        topics = {c.topic for c in r.connections}
        n_clock = sum(1 for c, _, _ in r.messages() if c.topic == "/clock")
    assert {
        "/drive/state",
        "/drive/command",
        "/drive/torque_reference",
        "/clock",
        "/drive/joint_states",
        "/diagnostics",
    } <= topics
    assert n_clock == 101
    assert set(descendants(os.getpid())) == before  # no node process left behind


def test_composed_run_equals_inprocess(tmp_path):
    """Composed: lock-step topics delivered in-process (LocalBus), same sequences bit for bit;
    the bag says which engine made it."""
    composed, _ = run_against_inprocess("composed", 0.05, tmp_path)
    assert composed.steps == 1000
    assert read_bag(composed.bag)[1].info["engine"] == "composed"


@pytest.mark.parametrize("engine", ["ros", "composed"])
def test_timed_switch_through_parameter_service(tmp_path, engine, typescript_reader):
    """A scheduled switch goes through the parameter service and lands exactly at its step: the
    plant waits there until the controller has taken it, the controller applies it there.
    Composed, the watch is the process's one outside (DDS) subscriber and the service is answered
    between local delivery batches. Foxglove's TypeScript reader reads the graph's bag."""
    r = run(
        "im_short",
        duration=0.4,
        engine=engine,
        strategy="mptc",
        switches=[(0.05, "db_mptc")],
        out=tmp_path / "sw",
    )
    tr, _ = read_bag(r.bag)
    s = tr.col("command", "strategy").astype(int)
    names = tr.strategy_names
    assert names[s[0]] == "mptc" and names[s[-1]] == "db_mptc"
    first = int(np.flatnonzero(s == names.index("db_mptc"))[0])
    assert first == 1000  # 0.05 s / 50 µs
    assert np.all(s[:first] == names.index("mptc"))
    assert np.all(s[first:] == names.index("db_mptc"))  # one clean switch at a step boundary
    # the switch leaves a trace: the controller's parameter event (set ahead of its step, which
    # the controller then waits for), the strategies' spans in the metadata and the report
    rep = report(r.bag)
    assert [(e.node, e.changed) for e in rep.details.parameter_events] == [
        ("/drive/torque_controller", {"strategy": "db_mptc"})
    ]
    assert rep.details.parameter_events[0].t <= 0.05
    spans = [(d.strategy, d.first, d.last) for d in rep.details.strategies]
    assert spans == [("mptc", 0, 999), ("db_mptc", 1000, 7999)]
    assert "strategies" in read_bag(r.bag)[1].custom  # from the metadata, not the commands
    assert rep.details.outcome.startswith("OK: complete: 8000 steps")
    # written in log-time order (the graph delivers command k after state k+1), sequence
    # numbers per channel
    backwards, bad_seq, n = ordering_faults(next(r.bag.glob("*.mcap")))
    assert (backwards, bad_seq) == (0, []) and n > 24000
    if typescript_reader is not None:  # else test_bag's test says why it is skipped
        typescript_reader(next(r.bag.glob("*.mcap")))
    # and the run is the in-process one switched at that step, bit for bit
    from predictive_drive.core.runner import run_inprocess

    sc = load_scenario("im_short", strategy="mptc", duration=0.4)
    assert_same_run(tr, run_inprocess(sc, switches=[(1000, "db_mptc")]))


def test_live_param_set_rejects_bad_value_then_ctrl_c_leaves_readable_bag(cli_run, tmp_path):
    bag = tmp_path / "live"
    p, line = cli_run("im_short", "--duration", "30", "--strategy", "mptc", "--out", str(bag))
    env = dict(os.environ, ROS_DOMAIN_ID=re.search(r"ROS_DOMAIN_ID=(\d+)", line).group(1))
    # the drive runs (a chunk of mptc is in the bag) before the switch: on a loaded machine the
    # graph's start can take longer than the parameter calls below
    wait_recorded(bag, 1, p)

    def param(*args):
        return subprocess.run(
            [*CLI, "param", *args], env=env, capture_output=True, text=True, timeout=60
        )

    bad = param("set", "torque_controller", "strategy", "dtc")
    assert bad.returncode == 2
    assert "rejected" in bad.stderr and "valid: mptc, mptc_db, db_mptc" in bad.stderr
    assert param("get", "torque_controller", "strategy").stdout.strip() == "mptc"
    ok = param("set", "torque_controller", "strategy", "db_mptc")
    assert ok.returncode == 0, ok.stderr
    assert param("get", "torque_controller", "strategy").stdout.strip() == "db_mptc"
    for node, name, value in (
        ("plant", "u_dc", "300.0"),
        ("torque_controller", "peer_timeout", "0.001"),
        ("speed_pi", "startup_timeout", "1.0"),
        ("metrics_logger", "bag", "elsewhere"),
        ("torque_controller", "family", "mptc_pmsm"),
    ):
        ro = param("set", node, name, value)
        assert ro.returncode == 2 and "read-only" in ro.stderr.lower(), (name, ro.stderr)
    sim = param("set", "plant", "use_sim_time", "false")
    assert sim.returncode == 2 and "use_sim_time must stay true" in sim.stderr
    for action in (("get", "plant", "no_such_param"), ("set", "plant", "no_such_param", "1")):
        missing = param(*action)
        assert missing.returncode == 2, action
        assert "node /drive/plant has no parameter 'no_such_param'" in missing.stderr, action
        assert "Traceback" not in missing.stderr and "u_dc" in missing.stderr  # lists them
    time.sleep(0.5)
    nodes = node_pids(line)
    assert_placed(nodes)
    os.kill(p.pid, signal.SIGINT)  # Ctrl-C
    _, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert all(ended(pid) for pid in nodes.values())
    tr, info = read_bag(bag)
    assert info.complete  # the logger closed it on SIGINT
    assert f"interrupted: the bag {bag.resolve()} was closed with {tr.steps} steps" in err
    s = tr.col("command", "strategy").astype(int)
    assert tr.strategy_names[s[0]] == "mptc" and tr.strategy_names[s[-1]] == "db_mptc"
    assert [e.changed for _, e in info.events] == [(("strategy", "db_mptc"),)]
    # the outcome says why, and counts the steps applied: those whose state k+1 came, as the
    # trace does
    stopped = re.fullmatch(
        r"ERROR: interrupted \(Ctrl-C\): (\d+) of 600000 steps; over the run .*",
        info.custom["outcome"],
    )
    assert stopped and int(stopped[1]) == tr.steps, info.custom["outcome"]  # as report counts


def wait_recorded(bag: Path, chunks: int = 1, p: subprocess.Popen | None = None) -> None:
    """Wait (up to 120 s) until the bag's file holds ``chunks`` × 260 kB (~2,000 steps each,
    whole chunks of ~1,270 steps): the drive has run that far, whatever the machine's
    speed."""
    wait_until(lambda: bag_bytes(bag) > 260_000 * chunks, "the run did not get that far", proc=p)


def started_recording(
    cli_run, bag: Path, *args: str
) -> tuple[subprocess.Popen[str], dict[str, int]]:
    """Start a long im_paper run into ``bag``; return (launcher, node PIDs) once it has
    recorded a chunk (so a fault hits a drive that is running)."""
    p, line = cli_run("im_paper", "--duration", "4", "--out", str(bag), *args)
    wait_recorded(bag, p=p)
    return p, node_pids(line)


def wait_logged(bag: Path, node: str, text: str) -> None:
    """Wait (up to 120 s) until ``node``'s log says ``text``."""
    log = bag / "logs" / f"{node}.log"
    wait_until(
        lambda: log.exists() and text in log.read_text(errors="replace"),
        f"{node} never said {text!r}",
    )


def read_until(p: subprocess.Popen, text: str, stream: str = "stderr") -> str:
    """Read the child's ``stream`` up to the line holding ``text`` (EOF fails)."""
    while line := getattr(p, stream).readline():
        if text in line:
            return line
    raise AssertionError(f"the command ended without saying {text!r}")


def node_said(bag: Path, node: str) -> tuple[str, int] | None:
    """(signal, step) from the node's 'stopped by SIG... at step k' line, if it wrote one."""
    found = re.search(r"^stopped by (SIG\w+) at step (-?\d+)$",
                      (bag / "logs" / f"{node}.log").read_text(), re.M)  # fmt: skip
    return (found[1], int(found[2])) if found else None


def test_killed_peer_ends_run_with_clear_error_and_readable_bag(cli_run, tmp_path):
    bag = tmp_path / "killed"
    p, nodes = started_recording(cli_run, bag)
    t0 = time.monotonic()
    os.kill(nodes["torque_controller"], signal.SIGKILL)
    _, err = p.communicate(timeout=60)
    took = time.monotonic() - t0
    assert p.returncode == 2
    assert "node torque_controller" in err and "killed by signal 9 (SIGKILL)" in err
    assert all(ended(pid) for pid in nodes.values())
    tr, info = read_bag(bag)
    assert info.complete and tr.steps > 0
    # the survivors were told to finish quickly (SIGTERM): they do not wait the 20 s their
    # publishers would for acknowledgements the dead node never sends
    from predictive_drive.ros.node_base import FINISH_TIMEOUT

    assert node_said(bag, "plant")[0] == "SIGTERM" and took < FINISH_TIMEOUT, took
    # and nothing the plant published is missing from the bag
    assert info.counts["/drive/state"] == node_said(bag, "plant")[1] + 1


def test_nodes_of_a_launcher_killed_outright_end_themselves(cli_run, tmp_path):
    """SIGKILL on the launcher leaves it no chance to stop its children: they notice they were
    orphaned, end the run themselves and the logger closes the bag."""
    bag = tmp_path / "orphaned"
    p, nodes = started_recording(cli_run, bag)
    os.kill(p.pid, signal.SIGKILL)
    p.wait(timeout=10)
    wait_until(
        lambda: all(ended(pid) for pid in nodes.values()),
        "orphaned node processes did not end",
        timeout=30,
    )
    tr, info = read_bag(bag)
    assert info.complete and tr.steps > 0


def test_bad_scenario_file_fails_before_starting_anything(tmp_path):
    bad = tmp_path / "bad.yaml"
    bad.write_text("/**:\n  ros__parameters: {scenario: x}\n")
    with pytest.raises(ConfigError, match="bad.yaml"):
        run(bad, engine="ros", out=tmp_path / "never")
    assert not (tmp_path / "never").exists()


SWITCHES = {
    # scenario, start, switch time s, to, steps, the strategy's own check on the commands
    "mptc_pmsm": ("ipmsm_short", "mptc", 0.02, "simplified3", 6000, "cal"),
    "foc_pmsm": ("hs_ipmsm_mtpa_short", "foc_formula", 0.1, "foc_injection", 1500, "current_angle"),
}


@pytest.mark.parametrize("engine", ["ros", "composed"])
@pytest.mark.parametrize("family", SWITCHES)
def test_pmsm_graph_switches_live_and_equals_inprocess(tmp_path, family, engine):
    """The PMSM families switch strategy through the parameter service like the IM one, in
    separate processes and composed; replaying the recorded switch step in-process gives the
    same sequences bit for bit (for field-oriented control, its diagnostics among them)."""
    from predictive_drive.core.runner import run_inprocess

    scenario, start, at, to, steps, field = SWITCHES[family]
    r = run(
        scenario,
        duration=0.3,
        engine=engine,
        strategy=start,
        switches=[(at, to)],
        out=tmp_path / "b",
    )
    tr, info = read_bag(r.bag)
    assert info.complete and tr.steps == steps
    names = tr.strategy_names
    s = tr.col("command", "strategy").astype(int)
    first = int(np.flatnonzero(s == names.index(to))[0])
    assert first == round(at / tr.ts)  # exactly at its step
    assert np.all(s[first:] == names.index(to)) and np.all(s[:first] == names.index(start))
    col = tr.col("command", field)
    if field == "cal":  # all 7 vectors before, at most 4 candidates after
        assert np.all(col[:first] == 7) and col[first:].mean() < 3
    else:  # the current angle in every command, at the MTPA angle before and after
        assert np.all(np.isfinite(col)) and abs(np.degrees(col[first - 1]) - 3.30) < 0.05
    sc = load_scenario(scenario, strategy=start, duration=0.3)
    assert_same_run(tr, run_inprocess(sc, switches=[(first, to)]))


@pytest.fixture
def composed_run(tmp_path):
    """Start the composed process by hand with extra parameters; killed by PID in teardown."""
    started: list[subprocess.Popen[str]] = []

    def start(params: dict, domain: int) -> subprocess.Popen[str]:
        import yaml

        from predictive_drive.config import resolve_scenario_path

        over = tmp_path / f"over{len(started)}.yaml"

        class NoAliases(yaml.SafeDumper):  # rcl's parser refuses YAML aliases
            def ignore_aliases(self, data):
                return True

        doc = {f"/drive/{n}": {"ros__parameters": v} for n, v in params.items()}
        over.write_text(yaml.dump(doc, Dumper=NoAliases))
        scenario = str(resolve_scenario_path("im_short"))
        p = subprocess.Popen(
            [sys.executable, "-m", "predictive_drive.ros.composed", "--ros-args"]
            + ["--params-file", scenario, "--params-file", str(over)],
            env={**os.environ, "ROS_DOMAIN_ID": str(domain)},
            stdout=subprocess.PIPE,
            stderr=subprocess.STDOUT,
            text=True,
            start_new_session=True,
        )
        started.append(p)
        return p

    yield start
    for p in started:
        if p.poll() is None:
            os.kill(p.pid, signal.SIGKILL)
        p.wait(timeout=10)


def _waiting_at_step_500(composed_run, domain: int, bag: Path):
    """A composed graph (im_short, mptc, 0.05 s, recorded to ``bag``) whose plant waits at the
    strategy switch scheduled at step 500: the process, once it says so, and its parameters."""
    common = {"duration": 0.05, "peer_timeout": 10.0, "switch_steps": [500]}
    params = {
        "plant": dict(common),
        "torque_controller": {**common, "strategy": "mptc"},
        "speed_pi": {"duration": 0.05},
        "metrics_logger": {"duration": 0.05, "bag": str(bag), "strategy": "mptc"},
    }
    p = composed_run(params, domain)
    said = read_until(p, "waits for the strategy switch", stream="stdout")
    assert "state 500 waits for the strategy switch scheduled at step 500" in said, said
    return p, params


def test_the_plant_waits_at_a_scheduled_switch_until_the_controller_takes_it(
    composed_run, tmp_path
):
    """The request comes late (3 s after the start, when the drive would long be past step 500):
    the drive waits at step 500 for it, and the switch lands there. Without a request, the wait
    ends the run after peer_timeout, saying why."""
    from predictive_drive.ros.processes import isolated_domain

    with isolated_domain() as domain:
        p, params = _waiting_at_step_500(composed_run, domain, tmp_path / "late")
        assert p.poll() is None, p.communicate()[0]  # waiting at step 500
        setter = subprocess.run(
            [*CLI, "param", "set", "torque_controller", "strategy", "db_mptc", "--timeout", "30"],
            env={**os.environ, "ROS_DOMAIN_ID": str(domain)},
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert setter.returncode == 0, setter.stderr
        out, _ = p.communicate(timeout=60)
        assert p.returncode == 0, out
    tr, _ = read_bag(tmp_path / "late")
    s = tr.col("command", "strategy").astype(int)
    assert tr.steps == 1000 and int(np.flatnonzero(np.diff(s))[0]) + 1 == 500
    with isolated_domain() as domain:
        params["metrics_logger"]["bag"] = str(tmp_path / "never")
        for n in ("plant", "torque_controller"):
            params[n]["peer_timeout"] = 2.0
        p = composed_run(params, domain)
        out, _ = p.communicate(timeout=60)
    assert p.returncode == 1
    assert (
        "the strategy switch scheduled at step 500 was not taken by /drive/torque_controller" in out
    )
    tr, info = read_bag(tmp_path / "never")
    assert info.complete and tr.steps == 499  # everything up to the wait, closed


def test_a_stalled_recorder_stops_the_run_with_every_step_recorded(cli_run, tmp_path):
    """The logger stopped (SIGSTOP) with --peer-timeout 3 while the drive runs: the plant waits
    for it (back-pressure), then ends the run, and the launcher names the stopped logger as the
    cause; when it goes on it takes what was in flight and closes the bag: every state the plant
    published, and every command, is in it."""
    bag = tmp_path / "stall"
    p, nodes = started_recording(cli_run, bag, "--peer-timeout", "3")
    os.kill(nodes["metrics_logger"], signal.SIGSTOP)
    try:  # the plant waits 3 s for it, then gives up (and waits for what it sent to be taken)
        wait_logged(bag, "plant", "the recorder is stalled")
    finally:
        os.kill(nodes["metrics_logger"], signal.SIGCONT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 2
    assert f"node metrics_logger (pid {nodes['metrics_logger']}) was stopped by a signal" in err
    assert "plant timed out waiting for it" in err
    assert "the recorder /drive/metrics_logger has written every step up to" in err
    assert "the recorder is stalled" in err and "was closed with" in err
    held = int(re.search(r"the drive waits at step (\d+)", err).group(1))
    tr, info = read_bag(bag)
    assert info.complete
    assert info.counts["/drive/state"] == held  # states 0..held-1: all it published
    assert info.counts["/drive/command"] == held  # and every command it was sent
    assert tr.steps == held - 1
    assert all(ended(pid) for pid in nodes.values())


def test_a_killed_recorder_is_said_and_repair_restores_the_bag(cli_run, tmp_path):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    bag = tmp_path / "killed_logger"
    p, nodes = started_recording(cli_run, bag)
    os.kill(nodes["metrics_logger"], signal.SIGKILL)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 2
    assert "node metrics_logger" in err and "killed by signal 9" in err
    assert "was not closed (no index)" in err and f"predictive-drive repair {bag.resolve()}" in err
    cut, info = read_bag(bag)
    assert not info.complete and cut.steps > 0
    r = subprocess.run([*CLI, "repair", str(bag)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    fixed, info = read_bag(bag)
    assert info.complete and fixed.steps == cut.steps
    assert_same_run(fixed, cut)
    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        states = sum(1 for c, _, _ in reader.messages() if c.topic == "/drive/state")
    assert states == info.counts["/drive/state"] >= fixed.steps + 1
    assert (bag / f"{bag.name}_0.mcap.orig").is_file()  # the original is kept


def test_a_full_disk_under_the_graph_is_said(tmp_path):
    """The logger's writes fail (a file-size limit the nodes inherit stands in for a full
    disk): the run stops naming it, and the bag is not presented as good."""
    import resource

    def limit() -> None:
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (400_000, 400_000))

    out = tmp_path / "full"
    r = subprocess.run(
        [*CLI, "run", "im_short", "--duration", "2", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=180,
        preexec_fn=limit,
    )
    assert r.returncode == 2, r.stderr
    assert "/drive/metrics_logger: " in r.stderr and "File too large" in r.stderr, r.stderr
    assert "(metrics_logger, pid " in r.stderr, r.stderr  # the node whose message it is
    assert "was closed with" not in r.stderr


def test_nodes_stopped_as_ros2_launch_stops_them_end_cleanly(tmp_path):
    """SIGINT to every node mid-run (what `ros2 launch` sends on Ctrl-C): each exits 0 (no
    "process has died"), says nothing on the way out (no rosout or traceback noise but the
    logger's last line), and the bag is closed, its outcome an ERROR naming the steps done."""
    from predictive_drive.ros.launcher import START_ORDER
    from predictive_drive.ros.processes import isolated_domain

    procs = {}
    with isolated_domain() as domain:
        env = dict(os.environ, ROS_DOMAIN_ID=str(domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST")
        params = Path(__file__).parents[1] / "config" / "im_short.yaml"
        try:
            for name in START_ORDER:
                procs[name] = subprocess.Popen(
                    [sys.executable, "-m", f"predictive_drive.ros.{name}_node", "--ros-args",
                     "--params-file", str(params), "-p", "duration:=30.0",
                     *(["-p", f"bag:={tmp_path / 'b'}"] if name == "metrics_logger" else [])],
                    env=env, cwd=tmp_path, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                    text=True, start_new_session=True,
                )  # fmt: skip
            wait_until(
                lambda: bag_bytes(tmp_path / "b") >= 300_000, "the run did not start", timeout=60
            )
            for p in procs.values():
                os.kill(p.pid, signal.SIGINT)
            outs = {n: p.communicate(timeout=60)[0] for n, p in procs.items()}
        finally:
            for p in procs.values():
                kill_if_running(p)
    assert {n: p.returncode for n, p in procs.items()} == dict.fromkeys(START_ORDER, 0), outs
    for name, out in outs.items():
        lines = [ln for ln in out.splitlines() if ln.strip()]
        if name == "metrics_logger":
            assert len(lines) == 2 and "bag closed" in lines[-1], out
        else:
            assert lines == [], (name, out)
    tr, info = read_bag(tmp_path / "b")
    assert info.complete and 0 < tr.steps < 600000
    assert info.custom["outcome"].startswith("ERROR: stopped: ")


def test_the_immediate_speed_loop_through_the_graph_equals_inprocess(tmp_path):
    """speed_loop: immediate on the four processes: the controller waits for the speed PI's
    answer to state k before deciding step k; the run equals the in-process one bit for bit."""
    from predictive_drive.config import scenario_with
    from predictive_drive.core.runner import run_inprocess

    path = scenario_with("im_short", {"speed_pi.speed_loop": "immediate"}, tmp_path)
    r = run(path, duration=0.05, out=tmp_path / "g")
    tr, info = read_bag(r.bag)
    ref = run_inprocess(load_scenario(path, duration=0.05))
    assert info.complete and tr.steps == ref.steps == 1000
    assert_same_run(tr, ref)
    assert tr.reference[0][2] != 0.0  # T* from state 0 applies at step 0


def test_a_terminated_logger_closes_its_bag_and_the_run_stops_at_once(cli_run, tmp_path):
    """SIGTERM to the metrics logger alone: it stops announcing /drive/recorded (the plant
    holds within 1,000 steps), takes everything in flight, closes its bag, and the launcher
    ends the run at once naming it; every state the plant published is in the bag."""
    bag = tmp_path / "term"
    p, nodes = started_recording(cli_run, bag)
    os.kill(nodes["metrics_logger"], signal.SIGTERM)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 2, err
    assert (
        f"node metrics_logger (pid {nodes['metrics_logger']}) was stopped from outside by "
        f"SIGTERM at step"
    ) in err and "the run was stopped" in err
    tr, info = read_bag(bag)
    assert info.complete and 0 < tr.steps < 80000
    assert f"was closed with {tr.steps} steps" in err
    _, published = node_said(bag, "plant")  # the launcher then stopped the plant
    assert info.counts["/drive/state"] == published + 1  # states 0..published: nothing lost
    assert all(ended(pid) for pid in nodes.values())


def test_a_stopped_controller_is_named_not_the_peer_that_timed_out(cli_run, tmp_path):
    """SIGSTOP of the torque controller past the peer timeout: its peers time out waiting for
    it, and the launcher names the stopped node as the cause."""
    bag = tmp_path / "stopped"
    p, nodes = started_recording(cli_run, bag, "--peer-timeout", "3")
    os.kill(nodes["torque_controller"], signal.SIGSTOP)
    try:  # its peers wait 3 s for it, then give up
        wait_logged(bag, "plant", "from /drive/torque_controller within 3.0 s")
    finally:
        os.kill(nodes["torque_controller"], signal.SIGCONT)
    _, err = p.communicate(timeout=120)
    assert p.returncode == 2
    # the error line: a stop that takes over 5 s on a busy machine says first whom it waits for
    first = next(line for line in err.splitlines() if "error:" in line)
    assert (
        f"node torque_controller (pid {nodes['torque_controller']}) was stopped by a signal"
        in first
    ), err
    assert "timed out waiting for it" in first and "failed first" not in first
    assert read_bag(bag)[1].complete


def ctrl_c_while_closing(
    cli_run, bag: Path, presses: int
) -> tuple[subprocess.Popen[str], dict[str, int], str]:
    """A recording run given Ctrl-C ``presses`` times (2 or 3) while its logger is held by
    SIGSTOP (so the bag is still being closed), then let go; (launcher, node PIDs, stderr)."""
    p, nodes = started_recording(cli_run, bag)
    os.kill(nodes["metrics_logger"], signal.SIGSTOP)
    try:
        os.kill(p.pid, signal.SIGINT)
        read_until(p, "interrupted: the nodes finish what is in flight")
        os.kill(p.pid, signal.SIGINT)
        read_until(p, "interrupted again")
        if presses == 3:
            os.kill(p.pid, signal.SIGINT)
            _, err = p.communicate(timeout=120)
    finally:
        with contextlib.suppress(ProcessLookupError):  # gone: the assertions say what it left
            os.kill(nodes["metrics_logger"], signal.SIGCONT)
    if presses == 2:
        _, err = p.communicate(timeout=120)
    return p, nodes, err


def test_a_repeated_ctrl_c_says_what_is_true_when_the_command_exits(cli_run, tmp_path):
    """Ctrl-C twice while the bag is still being closed (the logger held by SIGSTOP so that it
    is): the nodes are told to finish quickly and the command says the bag was closed, with
    the steps it holds. Three times: it leaves them closing and says so; they close the bag on
    their own."""
    bag = tmp_path / "twice"
    p, nodes, err = ctrl_c_while_closing(cli_run, bag, presses=2)
    assert p.returncode == 130
    tr, info = read_bag(bag)
    assert info.complete and f"the bag {bag.resolve()} was closed with {tr.steps} steps" in err
    assert all(ended(pid) for pid in nodes.values())

    bag = tmp_path / "thrice"
    p, nodes, err = ctrl_c_while_closing(cli_run, bag, presses=3)
    assert p.returncode == 130
    said = re.search(
        r"metrics_logger \(pid \d+\) is still closing the bag .* \((\d+) steps so far", err
    )
    assert said and "it is complete when that process ends" in err, err
    wait_until(  # they end on their own
        lambda: all(ended(pid) for pid in nodes.values()), "the nodes did not end", timeout=90
    )
    tr, info = read_bag(bag)
    assert info.complete and tr.steps >= int(said[1])


def test_one_ctrl_c_stops_a_run_that_shows_its_progress(tmp_path):
    """One Ctrl-C to a run on a terminal (stderr a tty: the progress bar is on, so the launcher
    follows /clock through a node of its own and the plant waits for it before step 0): the
    stop's line comes within seconds (0.00-0.06 s measured here), the command exits 130, the
    bag is closed and readable, every node has ended, and the terminal shows nothing but the
    progress and the stop's lines (no traceback)."""
    import fcntl
    import pty
    import struct
    import termios
    import threading

    bag = tmp_path / "tty"
    master, slave = pty.openpty()
    # a terminal's size (a new one has 0 columns: the bar has no room and draws nothing)
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", 24, 80, 0, 0))
    p = subprocess.Popen(
        [*CLI, "run", "im_short", "--duration", "30", "--out", str(bag)],
        stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=slave,
        start_new_session=True,
    )  # fmt: skip
    os.close(slave)
    shown: list[tuple[float, str]] = []  # (time.monotonic(), text) as the terminal got it

    def drain() -> None:  # a terminal nobody reads blocks its writer once its buffer is full
        with contextlib.suppress(OSError):  # EIO: the writer is gone
            while chunk := os.read(master, 4096):
                shown.append((time.monotonic(), chunk.decode(errors="replace")))

    def text(since: float = 0.0) -> str:
        return "".join(t for at, t in list(shown) if at >= since)

    reader = threading.Thread(target=drain, daemon=True)
    reader.start()
    nodes: dict[str, int] = {}
    try:
        wait_until(lambda: "sched batch" in text(), "no graph line", timeout=60, proc=p)
        nodes = node_pids(next(x for x in text().splitlines() if "ROS_DOMAIN_ID=" in x))
        wait_until(lambda: bag_bytes(bag) > 100_000, "the run did not get going", proc=p)
        watched = (bag / "logs" / "overrides.yaml").read_text()
        assert "await_launcher: true" in watched and "step/s" in text()  # the bar, the watch
        t0 = time.monotonic()
        p.send_signal(signal.SIGINT)
        wait_until(lambda: "interrupted: the nodes finish" in text(t0), "no stop line within "
                   f"5 s of the Ctrl-C; the terminal showed:\n{text()}", timeout=5)  # fmt: skip
        p.wait(timeout=60)
    finally:
        if p.poll() is None:
            signal_tree(p.pid, signal.SIGTERM)
            try:
                p.wait(timeout=20)
            except subprocess.TimeoutExpired:
                signal_tree(p.pid, signal.SIGKILL)
                p.wait(timeout=10)
        left = [pid for pid in nodes.values() if not ended(pid)]
        for pid in left:
            os.kill(pid, signal.SIGKILL)
        reader.join(timeout=10)
        os.close(master)
    assert not left, f"node processes left running: {left}"
    assert p.returncode == 130, text()
    tr, info = read_bag(bag)
    assert info.complete and tr.steps > 0
    assert f"interrupted: the bag {bag.resolve()} was closed with {tr.steps} steps" in text(t0)
    assert "Traceback" not in text() and "Exception in" not in text(), text()


def test_the_same_out_twice_at_once_refuses_the_second_run(tmp_path):
    """Two runs given the same --out at once: one records, the other is refused before it
    starts anything and touches nothing."""
    out = tmp_path / "same"
    cmd = [*CLI, "run", "im_short", "--duration", "0.2", "--out", str(out)]
    a = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)  # fmt: skip
    b = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         start_new_session=True)  # fmt: skip
    try:
        results = {x.pid: (x.communicate(timeout=180), x.returncode) for x in (a, b)}
    finally:
        for x in (a, b):
            signal_tree(x.pid, signal.SIGKILL)
    codes = sorted(rc for _, rc in results.values())
    assert codes == [0, 2], results
    (winner,) = [pid for pid, (_, rc) in results.items() if rc == 0]
    ((_, err), _) = next(v for v in results.values() if v[1] == 2)
    assert f"another run (pid {winner}) is writing its bag there" in err
    assert "ROS_DOMAIN_ID" not in err and "Traceback" not in err  # it started nothing
    tr, info = read_bag(out)
    assert info.complete and tr.steps == 4000
    assert (out / "logs" / "metrics_logger.log").read_text().count("recording to") == 1
    assert not (out / ".claim").exists()  # the claim ended with the run


def _fastdds_files() -> set[str]:
    return {p.name for p in Path("/dev/shm").iterdir() if "fastrtps" in p.name}


def test_a_killed_node_leaves_no_shared_memory_behind(cli_run, tmp_path):
    """Fast DDS cannot release the shared memory of a node killed outright; the launcher
    removes what its children used and nobody uses any more (8-16 files were left per killed
    node)."""
    from predictive_drive.ros.processes import _shm_files

    p, nodes = started_recording(cli_run, tmp_path / "shm")
    # the killed node's own segments; those a process outside this run also uses (another
    # test's, which may end later) are not the launcher's to remove. The ports are numbered
    # machine-wide (7000, 7001, ... as participants come), so another test's graph may open one
    # of this run's while it ends: what outside processes use is looked at until the run is over
    run_pids = {str(p.pid), *(str(c) for c in descendants(p.pid))}

    def outside_now() -> set[str]:
        return set().union(
            *(_shm_files(d.name) for d in Path("/proc").iterdir()
              if d.name.isdigit() and d.name not in run_pids)
        )  # fmt: skip

    outside = outside_now()
    mine = {f for f in _shm_files(str(nodes["plant"])) if f.startswith("fastrtps_")} - outside
    assert mine
    done = threading.Event()

    def watch() -> None:
        while not done.is_set():
            outside.update(outside_now())
            done.wait(0.05)

    watcher = threading.Thread(target=watch, daemon=True)
    watcher.start()
    try:
        os.kill(nodes["plant"], signal.SIGKILL)
        p.communicate(timeout=120)
    finally:
        done.set()
        watcher.join(timeout=10)
    assert p.returncode == 2
    in_use = set().union(*(_shm_files(d.name) for d in Path("/proc").iterdir() if d.name.isdigit()))
    left = (mine & _fastdds_files()) - in_use - outside
    assert not left, sorted(left)


def test_the_node_logs_stay_with_the_bag(tmp_path):
    """The graph's logs, rcl's own log files and the parameter overrides go into <bag>/logs,
    no temp folder elsewhere."""
    import tempfile

    before = set(Path(tempfile.gettempdir()).iterdir())
    r = run("im_short", duration=0.01, engine="ros", out=tmp_path / "b")
    logs = r.bag / "logs"
    names = {p.name for p in logs.iterdir()}
    assert names >= {"overrides.yaml", "plant.log", "metrics_logger.log"}
    assert len([n for n in names if n.startswith("python_")]) == 4  # rcl's, one per node
    made = set(Path(tempfile.gettempdir()).iterdir()) - before
    assert not [p for p in made if p.name.startswith("tmp")]


def test_a_user_without_a_writable_home_runs_the_graph(tmp_path):
    """rcl writes its logs under ~/.ros/log by default; a HOME that cannot be made (here: under
    /proc, which not even root can write) failed every node ("Failed to create log
    directory"). The logs go with the run instead; the tools' own go to a temp folder."""
    env = {k: v for k, v in os.environ.items() if k not in ("ROS_LOG_DIR", "ROS_HOME")}
    env["HOME"] = "/proc/no-home"
    r = subprocess.run([*CLI, "run", "im_short", "--duration", "0.01", "--out",
                        str(tmp_path / "b"), "--json"], env=env, capture_output=True, text=True,
                       timeout=180)  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert json.loads(r.stdout)["steps"] == 200
    p = subprocess.run([*CLI, "param", "get", "plant", "u_dc"], env={**env, "ROS_DOMAIN_ID": "230"},
                       capture_output=True, text=True, timeout=60)  # fmt: skip
    assert p.returncode == 2 and "offers no parameter services" in p.stderr, p.stderr


def test_a_real_drive_through_the_graph_equals_inprocess(tmp_path):
    """Delay with its compensation, dead time, device drops and seeded sensors through the four
    processes (run --set): the same run as in-process, bit for bit, the truth recorded beside
    the measurements."""
    settings = {
        "plant.actuation_delay_steps": 1,
        "torque_controller.delay_compensation": True,
        "plant.dead_time": 1e-6,
        "plant.device_drop": 1.0,
        "plant.current_noise": 0.05,
        "plant.current_adc_bits": 12,
        "plant.current_range": 20.0,
        "plant.encoder_lines": 1024,
        "plant.sensor_seed": 3,
    }
    g = run("im_short", duration=0.05, settings=settings, out=tmp_path / "g")
    i = run("im_short", duration=0.05, settings=settings, engine="inprocess", out=tmp_path / "i")
    a, info = read_bag(g.bag)
    b, _ = read_bag(i.bag)
    assert info.complete and a.steps == b.steps == 1000
    assert_same_run(a, b)
    assert not np.array_equal(a.col("state", "i_alpha"), a.col("state", "i_alpha_true"))
    assert "actuation_delay_steps: 1" in info.info["scenario_yaml"]


def test_losses_and_temperatures_through_the_graph_equal_inprocess(tmp_path):
    """A drive with a device file, the machine's losses and temperatures (plant.losses): the
    plant node reads the device file and books the same losses as the in-process engine, bit for
    bit; the bag stores the file it read (docs/physics.md#losses-and-temperature)."""
    settings = {
        "plant.dead_time": 1e-6,
        "plant.losses.device": "semikron_skm150gb124d",
        "plant.losses.machine": True,
        "plant.losses.iron_eddy": 0.01,
    }
    g = run("im_short", duration=0.05, settings=settings, out=tmp_path / "g")
    i = run("im_short", duration=0.05, settings=settings, engine="inprocess", out=tmp_path / "i")
    a, info = read_bag(g.bag)
    b, _ = read_bag(i.bag)
    assert info.complete and a.steps == b.steps == 1000
    assert_same_run(a, b)
    assert len(a.losses) == len(a.state) == 1001 and info.counts["/drive/losses"] == 1001
    assert np.isfinite(a.col("losses", "tj_ta_hi")).all() and a.col("losses", "p_sw_t").any()
    assert '"SKM 150 GB 124 D"' in info.info["device_json"]


def test_field_orientation_at_a_held_point_through_the_graph_equals_inprocess(tmp_path):
    """foc_im (field orientation of the induction motor) at a steady point — the shaft held by
    a load machine through a speed step, T* from a torque profile, the plant's period means on —
    through the four processes: the same run as in-process, bit for bit; its switching
    frequency the carrier's."""
    g = run("im_steady_foc", duration=0.08, out=tmp_path / "g")
    i = run("im_steady_foc", duration=0.08, engine="inprocess", out=tmp_path / "i")
    a, info = read_bag(g.bag)
    b, _ = read_bag(i.bag)
    assert info.complete and a.steps == b.steps == 800
    assert_same_run(a, b)
    assert g.metrics.f_sw_hz == pytest.approx(1e4, rel=1e-9)
    w = a.col("state", "omega_m")
    assert np.all(w[:500] == 0.0) and np.all(w[500:] == pytest.approx(2772 * np.pi / 30))
    assert np.all(a.col("reference", "torque_ref")[200:] == 3.0)  # ramped up over 10 ms
    assert np.isfinite(g.metrics.t_rmse_cont) and g.metrics.t_rmse_cont != g.metrics.t_rmse


@pytest.mark.parametrize("engine", ["ros", "composed"])
def test_a_horizon_switched_live_lands_at_its_step_and_equals_inprocess(tmp_path, engine):
    """mptc at N = 3 switched to N = 1 at 0.01 s through the parameter service: exactly at step
    200, the same run as in-process bit for bit, the spans saying N = 3 then N = 1."""
    from predictive_drive.api.report import evaluate, strategies_of

    kw = dict(duration=0.02, settings={"torque_controller.horizon": 3},
              switches=[(0.01, "horizon=1")])  # fmt: skip
    g = run("ipmsm_short", engine=engine, out=tmp_path / "g", **kw)
    i = run("ipmsm_short", engine="inprocess", out=tmp_path / "i", **kw)
    a, info = read_bag(g.bag)
    b, _ = read_bag(i.bag)
    assert info.complete and a.steps == b.steps == 400
    assert_same_run(a, b)
    spans = [(s.strategy, s.first, s.last) for s in strategies_of(evaluate(g.bag))]
    assert spans == [("mptc N=3", 0, 199), ("mptc", 200, 399)]


def test_direct_mpc_at_a_long_horizon_through_the_graph_equals_inprocess(tmp_path):
    """direct_mpc (sphere decoding) at N = 5 through the four processes: the same run as
    in-process, bit for bit, with finite metrics; replayed into the controller node, every
    command again."""
    from predictive_drive.api.replay import replay_into

    kw = dict(duration=0.01, settings={"torque_controller.horizon": 5})
    g = run("ipmsm_steady_mpc", out=tmp_path / "g", **kw)
    i = run("ipmsm_steady_mpc", engine="inprocess", out=tmp_path / "i", **kw)
    a, info = read_bag(g.bag)
    b, _ = read_bag(i.bag)
    assert info.complete and a.steps == b.steps == 200
    assert_same_run(a, b)
    assert np.all(a.col("command", "horizon") == 5.0) and a.col("command", "cal").min() >= 2
    assert np.isfinite(g.metrics.t_rmse) and np.isfinite(g.metrics.f_sw_hz)
    again = replay_into(g.bag, out=tmp_path / "again")
    assert (again.vector_agreement, again.pulse_agreement) == (1.0, 1.0)


def test_param_set_horizon_from_another_shell_lands_at_the_scheduled_step(composed_run, tmp_path):
    """`predictive-drive param set torque_controller horizon 3` while the drive waits at its
    scheduled step 500: from that step every command is mptc's at N = 3, the bag's spans say so
    and hold the parameter event; a horizon of 9 is refused naming the range."""
    from predictive_drive.api.report import evaluate, strategies_of
    from predictive_drive.ros.processes import isolated_domain

    with isolated_domain() as domain:
        env = {**os.environ, "ROS_DOMAIN_ID": str(domain)}
        p, _ = _waiting_at_step_500(composed_run, domain, tmp_path / "b")
        bad = subprocess.run([*CLI, "param", "set", "torque_controller", "horizon", "9"],
                             env=env, capture_output=True, text=True, timeout=60)  # fmt: skip
        # rclpy's own range check (the descriptor's IntegerRange) answers first
        assert bad.returncode != 0 and "horizon out of range. Min: 1, Max: 6" in bad.stderr
        setter = subprocess.run([*CLI, "param", "set", "torque_controller", "horizon", "3",
                                 "--timeout", "30"],
                                env=env, capture_output=True, text=True, timeout=60)  # fmt: skip
        assert setter.returncode == 0, setter.stderr
        out, _ = p.communicate(timeout=60)
        assert p.returncode == 0, out
    tr, info = read_bag(tmp_path / "b")
    h = tr.col("command", "horizon")
    assert tr.steps == 1000 and np.all(h[:500] == 1.0) and np.all(h[500:] == 3.0)
    spans = [(s.strategy, s.first, s.last) for s in strategies_of(evaluate(tmp_path / "b"))]
    assert spans == [("mptc", 0, 499), ("mptc N=3", 500, 999)]
    assert ("horizon", 3) in [c for _, e in info.events for c in e.changed]
