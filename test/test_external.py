"""A torque controller of one's own in the loop (docs/ros.md#writing-your-own-controller): the
example package's switching-table DTC run as the torque controller through separate processes,
started by the launcher or by hand; compared with DB-MPTC; and a controller that misbehaves ends
the run naming the field and the step, the bag closed with every step before it. Each test owns
what it starts and ends it by PID."""

from __future__ import annotations

import ast
import json
import math
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from predictive_drive.api.compare import compare
from predictive_drive.api.run import run, run_inprocess_to_bag
from predictive_drive.codec import labelled
from predictive_drive.config import load_scenario
from predictive_drive.core.signals import EXTERNAL
from predictive_drive.errors import ConfigError
from predictive_drive.readback import read_bag
from procs import (
    assert_placed,
    bag_bytes,
    end_all,
    ended,
    kill_if_running,
    readline_within,
    wait_until,
)

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "dtc_im"
DTC = f"{shlex.quote(sys.executable)} {shlex.quote(str(EXAMPLE / 'dtc_im' / 'dtc_node.py'))}"
BAD = f"{shlex.quote(sys.executable)} {shlex.quote(str(ROOT / 'test' / 'bad_controller.py'))}"
CLI = [sys.executable, "-m", "predictive_drive.cli"]


@pytest.mark.core
def test_the_example_imports_only_rclpy_the_messages_and_the_standard_library():
    """The contract is all a user needs: the example never imports predictive_drive."""
    allowed = {"rclpy", "std_msgs", *sys.stdlib_module_names, "dtc_im"}
    files = sorted(EXAMPLE.rglob("*.py"))
    assert len(files) >= 3  # the node, the package, setup.py
    for path in files:
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            else:
                continue
            for name in names:
                assert name.split(".")[0] in allowed | {"setuptools"}, (path, name)


@pytest.mark.core
def test_the_example_keeps_the_pace_habits_the_docs_give():
    """docs/ros.md ("Your node's pace") names three habits; the example holds to them: the
    events executor spun until a future with a finite timeout (never rclpy.spin_once, which
    builds a wait set per message), the layouts' labels read once, one command message whose
    data is an array of doubles. And bench keeps its row (ros_example_dtc_steps_per_s)."""
    from predictive_drive.api.bench import GRAPH_RUNS

    tree = ast.parse((EXAMPLE / "dtc_im" / "dtc_node.py").read_text())
    calls = {
        (ast.unparse(n.func), tuple(k.arg for k in n.keywords))
        for n in ast.walk(tree)
        if isinstance(n, ast.Call)
    }
    assert ("EventsExecutor", ()) in calls
    assert ("executor.spin_until_future_complete", ("timeout_sec",)) in calls
    assert not any(name.endswith(("spin_once", ".spin")) for name, _ in calls)
    assert ("array", ()) in calls and ("Float64MultiArray", ()) in calls
    assert [g.key for g in GRAPH_RUNS if g.example_dtc] == ["ros_example_dtc_steps_per_s"]


@pytest.fixture(scope="module")
def dtc_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("external") / "dtc"
    r = run("im_short", engine="ros", out=out, external={"torque_controller": DTC})
    return r


@pytest.mark.process
def test_the_example_dtc_runs_as_the_torque_controller(dtc_run):
    r = dtc_run
    assert r.strategy == EXTERNAL and r.steps == load_scenario("im_short").run.steps
    assert [(s.strategy, s.first, s.last) for s in r.details.strategies] == [
        (EXTERNAL, 0, r.steps - 1)
    ]
    m = r.metrics
    assert math.isfinite(m.t_rmse) and math.isfinite(m.psi_rmse) and m.f_sw_hz > 0
    assert m.t_rmse < 1.0 and m.psi_rmse < 0.05  # it controls the drive: torque and flux follow
    # figures the controller did not publish: not applicable, "-"
    assert math.isnan(m.cal_ave) and math.isnan(m.deadbeat_share)
    assert math.isnan(m.compute_ns_median) and all(math.isnan(u) for u in m.utilization)
    trace, info = read_bag(r.bag)
    assert info.info["strategy"] == EXTERNAL and info.info["command_contract"] == "1"
    assert trace.command.shape[0] == r.steps
    # recorded as the node published it (its diagnostics; no compute time), read back with its
    # switching state as the pulses the plant applied: each phase high or low all period
    assert math.isfinite(trace.col("command", "torque_est")[-1])
    assert math.isnan(trace.col("command", "compute_ns")[0])
    pulses = trace.command[:, 2:8]
    assert (pulses[:, :3] == 0).all() and set(np.unique(pulses[:, 3:])) == {0.0, 1.0}


@pytest.mark.process
def test_your_controllers_parameters_and_name_are_yours_and_recorded(tmp_path):
    """--set torque_controller.KEY=VALUE reaches your node (a key no built-in family has
    included, unchecked) and goes into the bag's metadata with the command line; --label names
    the controller external:NAME in the bag, its spans, report and compare, so two of yours
    compare by name."""
    runs = {}
    for label, band in (("dtc_a", 0.05), ("dtc_b", 0.2)):
        runs[label] = run(
            "im_short", engine="ros", duration=0.05, out=tmp_path / label, label=label,
            external={"torque_controller": DTC},
            settings={"torque_controller.torque_band": band, "torque_controller.gain": 3},
        )  # fmt: skip
    r = runs["dtc_b"]
    assert r.strategy == "external:dtc_b"
    assert [(s.strategy, s.first, s.last) for s in r.details.strategies] == [
        ("external:dtc_b", 0, r.steps - 1)
    ]
    (node,) = r.details.own_nodes
    assert (node.name, node.command) == ("torque_controller", DTC)
    assert node.parameters["torque_band"] == 0.2 and node.parameters["gain"] == 3
    assert node.parameters["motor.r_s"] == load_scenario("im_short").controller.motor.r_s
    # none of the built-in family's keys (was: family, strategy=db_mptc, lambda_psi, ...)
    assert {k.split(".")[0] for k in node.parameters} == {"motor", "torque_band", "gain"}
    said = (r.bag / "logs" / "torque_controller.log").read_text()
    assert "torque band 0.2 N·m" in said, said  # the node got it as a parameter
    trace, info = read_bag(r.bag)
    assert info.info["strategy"] == "external:dtc_b" and trace.external == "external:dtc_b"
    rep = subprocess.run([*CLI, "report", str(r.bag)], capture_output=True, text=True, timeout=60)
    assert f"your node  torque_controller: started as `{DTC}`; parameters: " in rep.stdout
    assert "torque_band=0.2" in rep.stdout and "gain=3" in rep.stdout, rep.stdout
    d = compare([str(runs["dtc_a"].bag), str(r.bag)])
    assert [c.label for c in d.runs] == ["im_short external:dtc_a", "im_short external:dtc_b"]
    assert d.runs[0].metrics.t_rmse != d.runs[1].metrics.t_rmse  # the bands differ


@pytest.mark.core
def test_a_label_a_folder_cannot_hold_is_refused_and_default_folders_hold_no_colon(tmp_path):
    from predictive_drive.recording import default_bag_dir

    for bad in ("a:b", "my ctrl", "x/y", ""):
        with pytest.raises(ConfigError, match=r"--label .*letters, digits and _ \. \+ -"):
            run("im_short", label=bad, external={"torque_controller": "true"}, out=tmp_path / "x")
    with pytest.raises(ConfigError, match="--label dtc: names a node of your own"):
        run("im_short", label="dtc", out=tmp_path / "x")
    assert not (tmp_path / "x").exists()
    sc = load_scenario("im_short", strategy="external:dtc")
    folder = default_bag_dir(sc).name
    assert folder.startswith("im_short_external-dtc_") and ":" not in folder


@pytest.mark.core
def test_your_section_takes_any_key_and_ours_are_checked():
    """The section of a node of your own is yours: --set adds any key and the scenario loads
    without checking it; the same key on one of ours is refused, naming the keys it has."""
    from predictive_drive.config import apply_settings, load_scenario_text, resolve_scenario_path

    path = resolve_scenario_path("im_short")
    text = path.read_text()
    mine = apply_settings(text, {"torque_controller.gain": 3, "torque_controller.pid.kp": 0.5},
                          path, own=["torque_controller"])  # fmt: skip
    sc = load_scenario_text(mine, path, own=["torque_controller"])
    assert sc.external and sc.controller is None and sc.family == "mptc_im"
    with pytest.raises(ConfigError, match="has no key 'gain' here"):
        apply_settings(text, {"torque_controller.gain": 3}, path)
    with pytest.raises(ConfigError, match="unknown key 'gain'"):
        load_scenario_text(mine, path)
    speed = apply_settings(text, {"speed_pi.my_gain": 1.5}, path, own=["speed_pi"])
    assert load_scenario_text(speed, path, own=["speed_pi"]).speed_pi is None


@pytest.mark.core
def test_your_controller_gets_the_model_and_what_you_set_not_our_familys_keys(tmp_path):
    """A built-in scenario's torque controller section is a family's (family, strategy, its
    weights): your node gets of it only the controller's model of the machine (motor.*), with
    what you set; a section that names no built-in family is yours and stays whole."""
    from predictive_drive.config import scenario_with, section_parameters

    made = scenario_with("im_short", {"torque_controller.gain": 3}, tmp_path,
                         own=["torque_controller"])  # fmt: skip
    given = section_parameters(made.read_text(), "torque_controller")
    assert {k.split(".")[0] for k in given} == {"motor", "gain"}
    assert given["motor.l_m"] == 0.2751 and given["gain"] == 3
    assert section_parameters(made.read_text(), "speed_pi")["kp"] == 0.06  # the rest as it was
    yours = made.read_text().replace("    gain: 3", "    gain: 3\n    band: 0.1")
    (tmp_path / "yours.yaml").write_text(yours)
    (tmp_path / "x").mkdir()
    again = scenario_with(tmp_path / "yours.yaml", {}, tmp_path / "x", own=["torque_controller"])
    assert section_parameters(again.read_text(), "torque_controller")["band"] == 0.1


@pytest.mark.process
def test_compare_puts_the_example_beside_db_mptc(dtc_run, tmp_path):
    sc = load_scenario("im_short", strategy="db_mptc")
    db = tmp_path / "db_mptc"
    run_inprocess_to_bag(sc, db)
    d = compare([str(dtc_run.bag), str(db)], figures=tmp_path / "figures")
    rows = {r.label: r for r in d.runs}
    assert set(rows) == {f"im_short {EXTERNAL}", "im_short db_mptc"}
    ours, theirs = rows["im_short db_mptc"].metrics, rows[f"im_short {EXTERNAL}"].metrics
    assert ours.t_rmse < theirs.t_rmse  # MPTC's advantage over the switching table
    assert d.figures and all(Path(f).stat().st_size > 10_000 for f in d.figures)


@pytest.mark.process
def test_a_node_started_by_hand_joins_the_run(tmp_path):
    """Without =COMMAND the run says how to start the node and waits; started from here as a
    user would from another shell, it joins and the run completes."""
    out = tmp_path / "by_hand"
    cmd = [*CLI, "run", "im_short", "--duration", "0.05", "--external", "torque_controller",
           "--out", str(out), "--json"]  # fmt: skip
    started = []
    try:
        launcher = subprocess.Popen(
            cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True
        )
        started.append(launcher)
        said = ""
        while "waiting for your /drive/torque_controller" not in said:
            line = launcher.stderr.readline()
            assert line, said
            said += line
        domain = re.search(r"ROS_DOMAIN_ID=(\d+) ROS_AUTOMATIC", said).group(1)
        args = shlex.split(launcher.stderr.readline())  # the arguments, on a line of their own
        assert args[0] == "--ros-args" and "__node:=torque_controller" in args
        env = {**os.environ, "ROS_DOMAIN_ID": domain, "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
        node = subprocess.Popen([*shlex.split(DTC), *args], env=env, start_new_session=True,
                                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)  # fmt: skip
        started.append(node)
        stdout, _ = launcher.communicate(timeout=120)
        assert launcher.returncode == 0
        assert node.wait(timeout=30) == 0  # it ends itself after the last step
        d = json.loads(stdout)
        assert d["strategy"] == EXTERNAL and d["steps"] == 1000
        assert math.isfinite(d["metrics"]["t_rmse"])
        (node,) = d["own_nodes"]  # in the bag's metadata: started by hand, its parameters
        assert node["name"] == "torque_controller" and node["command"] is None
        assert node["parameters"]["motor.p"] == 1
    finally:
        end_all(started)


BAD_CASES = [
    ("switching_state_2", "field 's_b' = 2.0: a switching state is 0 (low) or 1 (high)"),
    ("wrong_step", "field 'k' = 101: the command for another step (the plant waits for step 100)"),
    ("unknown_field", "unknown field 'gain'; a command carries k, t, one of pulses"),
    ("missing_field", "the switching state lacks s_c (it is s_a, s_b, s_c)"),
    ("nan_duty", "field 'duty_a' = nan: a fraction of Ts must lie in [0, 1]"),
    ("pulse_past_period", "field 'duty_a' = 0.5: delay_a + duty_a = 1.1 exceeds the period (1)"),
    ("voltage_inf", "field 'u_alpha' = inf: a voltage reference must be a finite number of volts"),
    (
        "wrong_time",
        "field 't' = 0.00505: a command carries the time of the state it answers "
        "(state 100: t = 0.005 s)",
    ),  # fmt: skip
    # malformed (the recorder leaves them out and keeps every valid step)
    (
        "wrong_size",
        "Float64MultiArray layout: 4 values under the labels 'k,t,s_a,s_b,s_c' "
        "(expected one distinct label per value)",
    ),  # fmt: skip
    (
        "no_layout",
        "Float64MultiArray layout: 5 values under the labels '' (expected one distinct label per "
        "value)",
    ),  # fmt: skip
    (
        "future_commands",
        "field 'k' = 101: the command for another step (the plant waits for step 100)",
    ),  # fmt: skip
]


@pytest.mark.process
@pytest.mark.parametrize("mode,message", BAD_CASES, ids=[m for m, _ in BAD_CASES])
def test_a_bad_command_ends_the_run_naming_field_and_step(mode, message, tmp_path):
    """The headline is the plant's refusal (was: "node plant failed first: exit 1"); the bag's
    outcome says it too; the bag keeps every step before the bad one, and the outcome, the
    strategy spans and report count the same steps (was: 101 and a span of step 100, which
    the plant never applied)."""
    out = tmp_path / mode
    r = subprocess.run(
        [*CLI, "run", "im_short", "--duration", "0.02", "--out", str(out),
         "--external", f"torque_controller={BAD} {mode} 100"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr  # GraphError
    said = (
        "/drive/plant: refused /drive/command from /drive/torque_controller: step 100: " + message
    )
    headline = next(line for line in r.stderr.splitlines() if "error:" in line)
    assert headline.startswith(f"predictive-drive: error: {said}"), r.stderr
    assert re.search(r"; the run was stopped \(plant, pid \d+, exited with status 1\)$", headline)
    trace, info = read_bag(out)  # closed, readable: every step before the bad one
    assert trace.command.shape[0] == 100
    assert list(trace.state[:, 0]) == list(range(101))
    outcome = info.custom["outcome"]
    assert outcome.startswith(f"ERROR: {said}") and ": 100 of 400 steps" in outcome, outcome
    assert json.loads(info.custom["strategies"]) == [{"strategy": EXTERNAL, "first": 0, "last": 99}]
    rep = subprocess.run([*CLI, "report", str(out)], capture_output=True, text=True, timeout=120)
    assert "the run stopped early: 100 of 400 planned steps recorded" in rep.stdout, rep.stdout


COMMANDS = [
    ("nosuch-controller-xyz --fast", "'nosuch-controller-xyz' is not found on PATH"),
    ("/nonexistent/ctrl", "'/nonexistent/ctrl' does not exist"),
    ("python3 'examples/dtc_im", "does not parse as a command line (no closing quotation)"),
    (str(ROOT / "README.md"), "is not executable (chmod +x it, or start it with its interpreter)"),
]


@pytest.mark.core
@pytest.mark.parametrize("command,why", COMMANDS, ids=["missing", "no-file", "quote", "not-exec"])
def test_a_command_that_cannot_start_is_refused_before_anything_starts(command, why, tmp_path):
    """A typo in COMMAND: exit 2 naming the command and why, no traceback, nothing started and
    --out untouched (was: the node's start failed as a process, blamed after the graph came up,
    or a traceback for the quote), for run and for replay --into alike."""
    out = tmp_path / "out"
    r = subprocess.run(
        [*CLI, "run", "im_short", "--out", str(out), "--external", f"torque_controller={command}"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert f"--external torque_controller={command}: " in r.stderr and why in r.stderr, r.stderr
    assert "graph on ROS_DOMAIN_ID" not in r.stderr and not out.exists()
    bag = tmp_path / "bag"
    run_inprocess_to_bag(load_scenario("im_short", duration=0.01), bag)
    r = subprocess.run(
        [*CLI, "replay", str(bag), "--into", f"torque_controller={command}", "--out", str(out)],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert f"--into torque_controller={command}: " in r.stderr and why in r.stderr, r.stderr
    assert not out.exists()


NEVER = [
    ("true", [], r"error: your torque_controller \(pid \d+\) exited with status 0 at step 0, "
     r"before its last command \(step 399\); the run was stopped"),
    (f"{BAD} exit0 100", [], r"error: your torque_controller \(pid \d+\) exited with status 0 at "
     r"step 100, before its last command \(step 399\); the run was stopped"),
    # (long enough for the node to start and subscribe on a loaded machine: it then never answers)
    (f"{BAD} silent 0", ["--startup-timeout", "15"], r"error: /drive/plant: no /drive/command for "
     r"step 0 from /drive/torque_controller within 15.0 s; the run was stopped \(plant, pid \d+"),
    (None, ["--startup-timeout", "3"], r"error: /drive/plant: step 0 still waits for "
     r"/drive/torque_controller \(no /drive/state subscription, no /drive/command publisher\) "
     r"within 3.0 s; the run was stopped"),
]  # fmt: skip


@pytest.mark.process
@pytest.mark.parametrize(
    "command,options,said", NEVER, ids=["exits-at-once", "exits-at-100", "hangs", "by-hand-never"]
)
def test_a_controller_that_does_not_answer_is_named_at_once(command, options, said, tmp_path):
    """A controller that exits 0 before its last command, never sends command 0, or (started by
    hand) never starts: the error names torque_controller and /drive/command, at once or at the
    start-up limit — never speed_pi or the recorder, which waited on the plant (was: the speed PI
    or the recorder blamed after 60 s; an exit 0 went unnoticed until the peer timeout)."""
    out = tmp_path / "out"
    external = "torque_controller" if command is None else f"torque_controller={command}"
    r = subprocess.run(
        [*CLI, "run", "im_short", "--duration", "0.02", "--out", str(out), *options,
         "--external", external],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    headline = next(line for line in r.stderr.splitlines() if "error:" in line)
    assert re.search(said, headline), r.stderr
    assert "speed_pi" not in headline and "metrics_logger" not in headline
    if command is None:  # the wait says its limit and the option that changes it
        assert "waiting for your /drive/torque_controller (up to 3 s; --startup-timeout S " \
            "changes it)" in r.stderr  # fmt: skip


@pytest.mark.core
def test_a_users_node_that_ignores_sigterm_is_killed_by_end_own_nodes(monkeypatch, capsys):
    """end_own_nodes itself escalates: a node that ignores SIGTERM is SIGKILLed and said to be
    (the graph test below passes without it: the launcher's own stop kills the node after)."""
    from predictive_drive.ros import processes

    monkeypatch.setattr(processes, "OWN_NODE_GRACE", 0.3)
    code = (
        "import signal, time; signal.signal(signal.SIGTERM, signal.SIG_IGN); "
        "print(1, flush=True); time.sleep(60)"
    )
    p = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        assert p.stdout.readline().strip() == "1"  # its handler is in
        processes.end_own_nodes({"torque_controller": p}, after="the run's last step")
        assert p.wait(timeout=10) == -signal.SIGKILL
        said = capsys.readouterr().err
        assert f"your torque_controller (pid {p.pid}) has not exited 0.3 s after the run's last " \
            "step; it ignored SIGTERM: killing it (SIGKILL)" in said  # fmt: skip
    finally:
        kill_if_running(p)


@pytest.mark.process
@pytest.mark.parametrize("mode", ["no_exit", "stubborn"])
def test_a_controller_that_does_not_exit_after_its_last_command_is_ended(mode, tmp_path):
    """The run completes and prints its metrics; the node that stays is ended, and the run says
    so: SIGTERM 5 s after the last step, SIGKILL 5 s later for one that ignores it (was: the
    launcher waited for it for ever)."""
    r = subprocess.run(
        [*CLI, "run", "im_short", "--duration", "0.02", "--out", str(tmp_path / "out"),
         "--external", f"torque_controller={BAD} {mode} 0"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert "steps 400" in r.stdout and "outcome    OK: complete: 400 steps" in r.stdout, r.stdout
    pid = re.search(r"torque_controller pid (\d+)", r.stderr).group(1)
    term = f"your torque_controller (pid {pid}) has not exited 5 s after the run's last step: " \
        "ending it (SIGTERM)"  # fmt: skip
    assert term in r.stderr, r.stderr
    assert ("it ignored SIGTERM: killing it (SIGKILL)" in r.stderr) == (mode == "stubborn")
    assert ended(int(pid))


REPLAYED = [
    ("switching_state_nan", "error: /drive/stepper: refused /drive/command from "
     "/drive/torque_controller: step 100: field 's_b' = nan: a switching state is 0 (low) or 1 "
     "(high) (as the plant would); the new bag"),
    ("silent", "error: no /drive/command for step 100 from /drive/torque_controller within 10 s: "
     "it runs (pid"),
]  # fmt: skip


@pytest.mark.process
@pytest.mark.parametrize("mode,said", REPLAYED, ids=[m for m, _ in REPLAYED])
def test_replay_into_a_controller_refuses_what_the_plant_refuses(mode, said, tmp_path):
    """replay --into a node that sends what the plant would refuse, or never answers: exit 2
    with the field and the step, or the silent step (was: a NaN switching state recorded with
    exit 0; "replay into the torque controller: step 0 within 10.0 s"); the new bag keeps the
    steps before it."""
    bag = tmp_path / "bag"
    run_inprocess_to_bag(load_scenario("im_short", duration=0.02), bag)
    out = tmp_path / "again"
    r = subprocess.run(
        [*CLI, "replay", str(bag), "--into", f"torque_controller={BAD} {mode} 100", "--out",
         str(out)],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 2 and "Traceback" not in r.stderr, r.stderr
    assert said in r.stderr, r.stderr
    assert read_bag(out)[0].steps == 100


@pytest.mark.process
def test_replay_into_ends_a_node_that_does_not_exit_after_its_last_command(tmp_path):
    """replay --into, as the launcher: the replay completes and the node that stays is ended,
    and it says so."""
    bag = tmp_path / "bag"
    run_inprocess_to_bag(load_scenario("im_short", duration=0.02), bag)
    r = subprocess.run(
        [*CLI, "replay", str(bag), "--into", f"torque_controller={BAD} no_exit 0", "--out",
         str(tmp_path / "again")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    assert re.search(r"your torque_controller \(pid \d+\) has not exited 5 s after its last "
                     r"command: ending it \(SIGTERM\)", r.stderr), r.stderr  # fmt: skip
    assert read_bag(tmp_path / "again")[0].steps == 400


def _run_bad(mode: str, out: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [*CLI, "run", "im_short", "--duration", "0.02", "--out", str(out), "--peer-timeout", "2",
         "--external", f"torque_controller={BAD} {mode} 100"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip


@pytest.mark.process
def test_a_controller_that_stops_answering_is_named_by_the_plant(tmp_path):
    r = _run_bad("silent", tmp_path / "silent")
    assert r.returncode == 2, r.stderr
    assert "predictive-drive: error: /drive/plant: no /drive/command for step 100 from " \
        "/drive/torque_controller within 2.0 s; the run was stopped (plant, pid" in r.stderr  # fmt: skip
    assert "busy" not in r.stderr
    trace, _ = read_bag(tmp_path / "silent")
    assert list(trace.state[:, 0]) == list(range(101)) and trace.command.shape[0] == 100


@pytest.mark.process
def test_a_busy_controller_is_called_busy_not_hung(tmp_path):
    """A controller that computes past the peer timeout (a search that exploded) is said to be
    busy, with the CPU time it used, and where to give it longer (was: the same line as for a
    hung one); an idle silent one is not (above)."""
    r = _run_bad("busy", tmp_path / "busy")
    assert r.returncode == 2, r.stderr
    assert re.search(
        r"/drive/plant: no /drive/command for step 100 from /drive/torque_controller within "
        r"2\.0 s; torque_controller \(pid \d+\) was busy, not hung: computing at \d+ % of the "
        r"launcher's looks over the last [\d.]+ s, [\d.]+ s of CPU \(a step that long: "
        r"--peer-timeout S waits longer\)", r.stderr
    ), r.stderr  # fmt: skip


@pytest.mark.process
def test_command_0_may_take_longer_than_the_peer_timeout(tmp_path):
    """The graph starts until command 0 is applied: a controller that answers state 0 after 4 s
    (still loading, still discovering) with a peer timeout of 2 s does not fail the run — no
    node blames its neighbour for the wait (the speed PI once blamed the plant)."""
    r = _run_bad("slow_start", tmp_path / "slow")
    assert r.returncode == 0, r.stderr
    trace, _ = read_bag(tmp_path / "slow")
    assert trace.steps == 400


@pytest.mark.process
def test_a_controller_that_dies_is_named_and_the_bag_closes(tmp_path):
    """The node exits (status 3) at step 100: the launcher names it, the recorder closes the
    bag with every state and reference up to step 100. The commands the recorder had not taken
    when the node died went with it (its DDS writer is gone): the bag holds those it took.
    Its peers are told to finish quickly (SIGTERM): it left without closing its participant, so
    their waits for its acknowledgements would have held the stop until Fast DDS's lease ran
    out (SIGINT: the command took 22 s here, against 3 s)."""
    from mcap.reader import make_reader

    out = tmp_path / "dies"
    r = _run_bad("dies", out)
    assert r.returncode == 2, r.stderr
    assert re.search(r"error: node torque_controller \(pid \d+\) exited with status 3; the run "
                     r"was stopped", r.stderr), r.stderr  # fmt: skip
    for peer in ("plant", "speed_pi"):
        assert (out / "logs" / f"{peer}.log").read_text().startswith("stopped by SIGTERM"), peer
    with open(next(out.glob("*.mcap")), "rb") as f:  # closed: summary and footer are there
        reader = make_reader(f)
        assert reader.get_summary() is not None
        steps: dict[str, list[int]] = {}
        for _, channel, message in reader.iter_messages():
            if channel.topic in ("/drive/state", "/drive/torque_reference", "/drive/command"):
                k = int(labelled(message.data)["k"])
                steps.setdefault(channel.topic, []).append(k)
    assert steps["/drive/state"] == list(range(101))
    assert steps["/drive/torque_reference"][:101] == list(range(101))
    commands = steps.get("/drive/command", [])
    assert commands == list(range(len(commands))) and len(commands) <= 100


@pytest.mark.process
def test_replaying_the_example_into_itself_gives_its_commands_bit_for_bit(dtc_run, tmp_path):
    """replay BAG --into torque_controller=COMMAND: the recorded states and references step by
    step into the example; it answers every step as in the run, and the new bag says so."""
    from predictive_drive.api.replay import replay_into

    d = replay_into(dtc_run.bag, command=DTC, out=tmp_path / "again")
    assert d.strategy == EXTERNAL and d.steps == dtc_run.steps
    assert d.pulse_agreement == 1.0  # the vector: none recorded, none to agree on ("-")
    assert math.isnan(d.vector_agreement) and math.isnan(d.compute_us_per_step)
    old, _ = read_bag(dtc_run.bag)
    new, info = read_bag(d.bag)
    assert info.info["engine"] == "replay" and info.info["strategy"] == EXTERNAL
    assert np.array_equal(new.command, old.command, equal_nan=True)  # diagnostics too
    assert np.array_equal(new.state, old.state, equal_nan=True)  # the period means: NaN, off


@pytest.mark.process
def test_replay_into_your_node_takes_its_parameters_and_says_whose_figures(tmp_path):
    """replay --into with --set: your node gets the key (and of our section the controller's
    model alone); the new bag records them; a node that publishes no vector agrees on none
    ('-', was 0.00 %); report says its plant's figures are the recording's (was: f_sw under
    your label, unexplained)."""
    from predictive_drive.api.replay import replay_into

    source = tmp_path / "db_mptc"
    run_inprocess_to_bag(load_scenario("im_short", duration=0.02), source)
    d = replay_into(source, command=DTC, out=tmp_path / "into", label="band",
                    settings={"torque_controller.torque_band": 0.2})  # fmt: skip
    assert math.isnan(d.vector_agreement) and d.strategy == "external:band"
    _, info = read_bag(d.bag)
    (node,) = info.own_nodes
    assert {k.split(".")[0] for k in node.parameters} == {"motor", "torque_band"}
    assert node.parameters["torque_band"] == 0.2
    said = (d.bag / "logs" / "torque_controller.log").read_text()
    assert "torque band 0.2 N·m" in said, said
    rep = subprocess.run([*CLI, "report", str(d.bag)], capture_output=True, text=True, timeout=60)
    assert f"replay   of {source.resolve()}: its states were fed to this controller" in rep.stdout
    with pytest.raises(ConfigError, match="--set plant.u_dc: replay --into runs the "):
        replay_into(source, command=DTC, out=tmp_path / "x", settings={"plant.u_dc": 10.0})


@pytest.mark.process
def test_the_example_builds_with_colcon_and_its_executable_is_the_controller(tmp_path):
    """The example is an ament_python package as a user's would be: `colcon build` of a
    workspace holding it alone installs `lib/dtc_im/dtc_node`; that executable, with the
    environment `. install/setup.sh` gives, is the external torque controller of a run."""
    import shutil

    ws = tmp_path / "ws"
    shutil.copytree(EXAMPLE, ws / "src" / "dtc_im")
    colcon = Path(sys.executable).with_name("colcon")
    subprocess.run([str(colcon), "build", "--base-paths", "src"], cwd=ws, check=True,
                   timeout=300, capture_output=True)  # fmt: skip
    prefix = ws / "install" / "dtc_im"
    exe = prefix / "lib" / "dtc_im" / "dtc_node"
    assert exe.is_file() and (prefix / "share" / "dtc_im" / "package.xml").is_file()
    site = next(prefix.glob("lib/python3*/site-packages"))
    env = {**os.environ, "PYTHONPATH": str(site)}
    r = subprocess.run(
        [*CLI, "run", "im_short", "--duration", "0.05", "--out", str(tmp_path / "bag"), "--json",
         "--external", f"torque_controller={shlex.quote(str(exe))}"],
        capture_output=True, text=True, timeout=180, env=env, cwd=tmp_path,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["strategy"] == EXTERNAL and d["steps"] == 1000


@pytest.mark.process
def test_the_speed_loop_started_as_an_external_command_gives_the_same_run(tmp_path):
    """--external speed_pi=COMMAND, the command being this package's own speed PI node started
    as any executable would be: the launcher's naming, namespace and parameters reach it, and
    the run equals the one the launcher makes itself, message for message. --label names the
    run beside our strategy, so compare tells the two apart (was: refused)."""
    own = f"{shlex.quote(sys.executable)} -m predictive_drive.ros.speed_pi_node"
    a = run("im_short", engine="ros", duration=0.05, out=tmp_path / "ext",
            external={"speed_pi": own}, label="my_loop")  # fmt: skip
    b = run("im_short", engine="ros", duration=0.05, out=tmp_path / "own")
    ta, info = read_bag(a.bag)
    tb, _ = read_bag(b.bag)
    assert a.strategy == b.strategy == "db_mptc"
    assert [(n.name, n.command) for n in info.own_nodes] == [("speed_pi", own)]  # recorded too
    assert [c.label for c in compare([a.bag, b.bag]).runs] == [
        "im_short db_mptc [speed_pi:my_loop]", "im_short db_mptc"
    ]  # fmt: skip
    for rec in ("state", "reference"):
        assert np.array_equal(getattr(ta, rec), getattr(tb, rec), equal_nan=True), rec
    # the decisions alike (the command's last field, compute_ns, is measured; NaN where a
    # diagnostic does not apply)
    assert np.array_equal(ta.command[:, :-1], tb.command[:, :-1], equal_nan=True)


@pytest.mark.process
@pytest.mark.parametrize("command", [DTC, f"{BAD} stubborn 9999999"], ids=["dtc", "stubborn"])
def test_a_users_node_ends_when_the_launcher_is_killed_outright(command, tmp_path):
    """Our nodes watch their launcher; a user's node cannot, so the launcher starts it to end
    with it (SIGTERM when the launcher dies, even by SIGKILL, and SIGKILL 5 s later for one that
    ignores SIGTERM: was left running): none is left running."""
    p = subprocess.Popen(
        [*CLI, "run", "im_short", "--duration", "30", "--out", str(tmp_path / "bag"),
         "--external", f"torque_controller={command}"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    pid = 0
    program = shlex.split(command)[1]
    try:
        line = p.stderr.readline()
        pid = int(re.search(r"torque_controller pid (\d+)", line).group(1))
        wait_until(lambda: program in Path(f"/proc/{pid}/cmdline").read_text(),
                   "the node did not start", timeout=30)  # fmt: skip
        wait_until(lambda: bag_bytes(tmp_path / "bag") > 100_000, "the run did not start",
                   timeout=60)  # fmt: skip
        # placed as ours: on the plant's CPU, every thread SCHED_BATCH (was: left to the kernel)
        assert_placed({"torque_controller": pid})
        p.kill()  # the launcher, SIGKILL: no chance to stop anything
        p.wait(timeout=10)
        wait_until(lambda: ended(pid),
                   "the user's node outlived its launcher", timeout=30)  # fmt: skip
    finally:
        end_all([p])
        if pid and not ended(pid):  # the node this test started, if it did outlive
            os.kill(pid, signal.SIGKILL)


@pytest.mark.core
def test_a_label_too_long_for_a_folder_name_is_refused(tmp_path):
    """(was: a 300-letter --label with the default folder: OSError, File name too long); the
    longest allowed names a folder that can be made."""
    from predictive_drive.core.signals import external_name
    from predictive_drive.recording import default_bag_dir

    with pytest.raises(ConfigError, match=r"\(300 characters\): a controller's name is at most 64"):
        run("im_short", label="a" * 300, external={"torque_controller": "true"})
    longest = load_scenario("im_short", strategy=external_name("x" * 64))
    (tmp_path / default_bag_dir(longest).name).mkdir()


@pytest.mark.core
@pytest.mark.parametrize(
    "value", [[1, "x"], [], None, [[1.0]]], ids=["mixed", "empty", "null", "nested-list"]
)
def test_a_value_no_ros_parameter_can_hold_is_refused_before_anything_starts(value, tmp_path):
    """Your section is unchecked against our families, but what rcl cannot parse is refused
    first, naming the key and what a parameter holds (was: the graph started, then rcl's
    'Failed to parse global arguments' for a mixed list, the node's PARAMETER_NOT_SET for an
    empty one)."""
    with pytest.raises(ConfigError, match=r"torque_controller\.my_key: .* cannot be a ROS "
                       r"parameter; one holds true/false, an integer, a number, a string"):  # fmt: skip
        run("im_short", external={"torque_controller": "true"}, out=tmp_path / "b",
            settings={"torque_controller.my_key": value})  # fmt: skip
    assert not (tmp_path / "b").exists()


@pytest.mark.process
def test_a_stop_says_which_node_it_waits_for_and_how_long(tmp_path):
    """Your controller ignores the stop: after a Ctrl-C the command says, within seconds, that
    it waits for the torque controller (its pid), for how long, and what comes then (was: one
    line, 'the nodes finish what is in flight', and a minute of silence)."""
    p = subprocess.Popen(
        [*CLI, "run", "im_short", "--duration", "30", "--out", str(tmp_path / "bag"),
         "--external", f"torque_controller={BAD} deaf 9999999"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    pid = 0
    try:
        line = readline_within(p.stderr, 60)
        pid = int(re.search(r"torque_controller pid (\d+)", line).group(1))
        wait_until(lambda: bag_bytes(tmp_path / "bag") > 100_000, "the run did not start",
                   timeout=60)  # fmt: skip
        p.send_signal(signal.SIGINT)
        t0 = time.monotonic()
        said = ""
        while "still waiting" not in said:
            said += readline_within(p.stderr, 30)
        assert re.search(
            rf"still waiting for torque_controller \(pid {pid}\) to end after SIGINT: up to "
            r"\d+ s more, then SIGTERM \(Ctrl-C again: SIGTERM now\)", said
        ), said  # fmt: skip
        assert time.monotonic() - t0 < 15
        p.kill()  # enough: the node ends with its launcher (SIGKILL 5 s after the ignored SIGTERM)
        wait_until(lambda: ended(pid), "the node outlived its launcher", timeout=30)
    finally:
        end_all([p])
        if pid and not ended(pid):
            os.kill(pid, signal.SIGKILL)


@pytest.mark.process
def test_bench_times_your_controller_beside_ours(capsys):
    """bench --external torque_controller=COMMAND --label NAME: the graph with your node timed in
    the same call as the graph with ours (was: only the example, by its key); a command that
    cannot start is refused first."""
    r = subprocess.run(
        [*CLI, "bench", "--quick", "--no-horizons", "--no-losses", "--json", "--label", "dtc",
         "--external", f"torque_controller={DTC}"],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert r.returncode == 0, r.stderr
    d = json.loads(r.stdout)
    assert d["ros_steps_per_s"] > 0 and d["ros_external_dtc_steps_per_s"] > 0
    assert "composed_steps_per_s" not in d  # only ours beside it
    r = subprocess.run([*CLI, "bench", "--quick", "--external", "torque_controller=/no/such"],
                       capture_output=True, text=True, timeout=60)  # fmt: skip
    assert r.returncode == 2 and "'/no/such' does not exist" in r.stderr, r.stderr
