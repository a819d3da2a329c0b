"""The launcher ↔ node contract (no ROS): CPU plan, scheduling policy, environment, and the
launcher's refusal of bad settings before anything starts."""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from predictive_drive.config import load_scenario
from predictive_drive.errors import GraphError
from predictive_drive.ros.launcher import run_graph
from predictive_drive.ros.placement import (
    CPUS_ENV,
    FASTDDS_PROFILES,
    FASTDDS_PROFILES_ENV,
    SCHED_ENV,
    cpu_plan,
    ros_env,
)

pytestmark = pytest.mark.core


def test_cpu_plan_pairs_the_lock_step_partners():
    assert cpu_plan("paired", [2, 5, 7]) == {
        "plant": "2",
        "torque_controller": "2",
        "speed_pi": "5",
        "metrics_logger": "5",
    }
    assert cpu_plan("paired", [3]) == {}  # one CPU: nothing to place
    assert cpu_plan("none", [0, 1]) == {}
    with pytest.raises(GraphError, match="--affinity: 'spread' is not one of paired, none"):
        cpu_plan("spread", [0, 1])


def test_node_process_applies_the_placement_it_is_given():
    code = "import os, threading; from predictive_drive.ros.placement import apply_placement; "
    code += "t = threading.Thread(target=threading.Event().wait, args=(5,), daemon=True); "
    code += "t.start(); apply_placement(); "
    code += "print(sorted(os.sched_getaffinity(t.native_id)), os.sched_getscheduler(t.native_id))"
    first = min(os.sched_getaffinity(0))

    def child(**env: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-c", code],
            env={**os.environ, **env},
            capture_output=True,
            text=True,
            timeout=60,
        )

    ok = child(**{CPUS_ENV: str(first), SCHED_ENV: "batch"})
    assert ok.stdout.split() == [f"[{first}]", str(os.SCHED_BATCH)], ok.stderr  # a thread it had
    other = child(**{SCHED_ENV: "other"})
    assert other.stdout.split()[-1] == str(os.SCHED_OTHER), other.stderr
    bad = child(**{CPUS_ENV: "0,x"})
    assert bad.returncode == 1
    assert f"{CPUS_ENV}='0,x': cannot keep to these CPUs" in bad.stderr
    bad = child(**{SCHED_ENV: "fifo"})
    assert bad.returncode == 1
    assert f"{SCHED_ENV}='fifo': unknown scheduling policy; expected one of batch, other" in (
        bad.stderr
    )


def test_run_graph_rejects_an_unknown_policy(tmp_path):
    sc = load_scenario("im_short")
    with pytest.raises(GraphError, match="--sched: 'fifo' is not one of batch, other"):
        run_graph(sc, tmp_path / "bag", sched="fifo")
    assert not (tmp_path / "bag").exists()


def test_launcher_hands_children_the_profile_unless_the_user_has_one(monkeypatch):
    for k in FASTDDS_PROFILES_ENV:
        monkeypatch.delenv(k, raising=False)
    env = ros_env(150)
    assert all(env[k] == str(FASTDDS_PROFILES) for k in FASTDDS_PROFILES_ENV)
    monkeypatch.setenv("FASTRTPS_DEFAULT_PROFILES_FILE", "/etc/mine.xml")
    env = ros_env(150)
    assert env["FASTRTPS_DEFAULT_PROFILES_FILE"] == "/etc/mine.xml"
    assert "FASTDDS_DEFAULT_PROFILES_FILE" not in env
