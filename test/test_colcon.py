"""`colcon build` (colcon from PyPI) turns the repository into a ROS 2 install, and the install runs:
each executable found as `ros2 run` finds it (the package's prefix from the ament index, then
`lib/predictive_drive/<exe>`), started with only `--ros-args --params-file <scenario>`; the
launch file starts the same graph."""

from __future__ import annotations

import ast
import os
import re
import subprocess
import sys
import time
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest

from procs import kill_if_running

pytestmark = pytest.mark.process

ROOT = Path(__file__).resolve().parents[1]
NODES = ("metrics_logger", "torque_controller", "speed_pi", "plant")


@pytest.fixture
def install(colcon_built):
    return colcon_built.prefix


def install_env(install: Path, domain: int) -> dict[str, str]:
    """What sourcing the install's setup script gives a shell, for this package."""
    site = next(install.glob("lib/python3*/site-packages"))
    return {
        **os.environ,
        "AMENT_PREFIX_PATH": os.pathsep.join([str(install), sys.prefix]),
        "PYTHONPATH": str(site),
        "ROS_DOMAIN_ID": str(domain),
        "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST",
    }


def ros2_run_path(env: dict[str, str], exe: str) -> Path:
    """Where `ros2 run predictive_drive <exe>` finds the executable."""
    code = (
        "from ament_index_python.packages import get_package_prefix; "
        "print(get_package_prefix('predictive_drive'))"
    )
    prefix = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True
    ).stdout.strip()
    return Path(prefix) / "lib" / "predictive_drive" / exe


def test_the_install_holds_executables_resources_and_the_ament_marker(install):
    for node in NODES:
        assert (install / "lib" / "predictive_drive" / f"{node}_node").is_file(), node
    share = install / "share" / "predictive_drive"
    assert (install / "share/ament_index/resource_index/packages/predictive_drive").is_file()
    for name in ("package.xml", "config/im_paper.yaml", "launch/drive.launch.xml"):
        assert (share / name).is_file(), name


def test_the_installed_nodes_run_as_ros2_run_starts_them(install, tmp_path):
    """No other arguments than the scenario file: the logger finds the scenario through the ament
    index (a plain colcon install: nothing of the source tree on the path) and writes its bag
    under the working directory; the recording equals the in-process run bit for bit."""
    from predictive_drive.config import load_scenario
    from predictive_drive.core.runner import run_inprocess
    from predictive_drive.readback import read_bag
    from predictive_drive.ros.processes import isolated_domain

    params = install / "share" / "predictive_drive" / "config" / "im_short.yaml"
    work = tmp_path / "run"
    work.mkdir()
    procs = []
    with isolated_domain() as domain:
        env = install_env(install, domain)
        try:
            t0 = time.perf_counter()
            for node in NODES:
                exe = ros2_run_path(env, f"{node}_node")
                assert str(exe).startswith(str(install)), exe
                procs.append(
                    subprocess.Popen(
                        [str(exe), "--ros-args", "--params-file", str(params)],
                        cwd=work,
                        env=env,
                        stdout=subprocess.PIPE,
                        stderr=subprocess.STDOUT,
                        text=True,
                        start_new_session=True,
                    )
                )
            outs = [p.communicate(timeout=180)[0] for p in procs]
            wall = time.perf_counter() - t0
        finally:
            for p in procs:
                kill_if_running(p)
    codes = [p.returncode for p in procs]
    assert codes == [0] * len(procs), list(zip(NODES, codes, outs))
    (bag,) = (work / "bags").iterdir()
    tr, info = read_bag(bag)
    assert info.complete and info.info["engine"] == "ros"
    ref = run_inprocess(load_scenario("im_short"))
    assert tr.steps == ref.steps == 8000
    np.testing.assert_array_equal(tr.state, ref.state)
    np.testing.assert_array_equal(tr.reference, ref.reference)
    np.testing.assert_array_equal(tr.command[:, :-1], ref.command[:, :-1])
    print(f"installed graph: {tr.steps} steps in {wall:.1f} s wall (start-up included)")


def test_the_launch_file_starts_the_graph_the_launcher_starts():
    """The launch package is not installable here (no `ros2 launch`), so the file is held to the
    launcher's graph: the same nodes, executables, namespace, scenario file and strategy."""
    from dataclasses import fields

    from predictive_drive.core.signals import EXTERNAL
    from predictive_drive.interface import NAMESPACE
    from predictive_drive.ros.launcher import START_ORDER
    from predictive_drive.ros.metrics_logger_node import RecordingParams

    root = ET.parse(ROOT / "launch" / "drive.launch.xml").getroot()
    args = {a.get("name"): a.get("default") for a in root.iter("arg")}
    assert args == {"scenario": "im_paper", "strategy": "", "live_port": "0"}
    nodes = root.findall("node")
    assert {n.get("name") for n in nodes} == set(START_ORDER)
    for n in nodes:
        assert n.get("pkg") == "predictive_drive"
        assert n.get("exec") == f"{n.get('name')}_node"
        assert f"/{n.get('namespace')}" == NAMESPACE
        params = n.findall("param")
        assert params[0].get("from") == "$(var params)"
        overrides = {p.get("name"): p.get("value") for p in params[1:]}
        if n.get("name") == "metrics_logger":
            assert overrides.pop("live_port") == "$(var live_port)"
        if n.get("unless") or "not in" in (n.get("if") or ""):  # when a strategy is given
            assert overrides == {"strategy": "$(var strategy)"}
            assert n.get("name") in ("torque_controller", "metrics_logger")
        else:
            assert overrides == {}
        # the logger declares what the file sets
        if n.get("name") == "metrics_logger":
            assert {"strategy", "live_port"} <= {f.name for f in fields(RecordingParams)}
    (let,) = root.findall("let")
    assert let.get("value") == "$(find-pkg-share predictive_drive)/config/$(var scenario).yaml"
    # each conditional node comes as a pair that covers both cases exactly once; the torque
    # controller's second case leaves out a controller of the user's own
    empty = "$(eval '\\'$(var strategy)\\' == \\'\\'')"
    given = "$(eval '\\'$(var strategy)\\' not in (\\'\\', \\'external:torque_controller\\')')"
    logger = [n for n in nodes if n.get("name") == "metrics_logger"]
    assert sorted(((n.get("if"), n.get("unless")) for n in logger), key=str) == sorted(
        [(empty, None), (None, empty)], key=str
    )
    controller = [n for n in nodes if n.get("name") == "torque_controller"]
    assert sorted(((n.get("if"), n.get("unless")) for n in controller), key=str) == sorted(
        [(empty, None), (given, None)], key=str
    )
    assert "not in" not in empty and EXTERNAL in given


# rosdep keys as rosdistro's rosdep/python.yaml defines them (checked against ros/rosdistro
# 8468e88, 2026-08-22: system packages on Debian/Ubuntu, or pip where no system package exists),
# each with the PyPI distribution it installs
ROSDEP_KEYS = {
    "python3-numpy": "numpy",
    "python3-yaml": "PyYAML",
    "mcap-ros2-support": "mcap",  # pip key; mcap-ros2-support requires mcap
    "python3-tqdm": "tqdm",
    "python3-matplotlib": "matplotlib",
    "python3-pytest": "pytest",
    "python3-rosbags-pip": "rosbags",
}
ROS_PACKAGES = {
    "rclpy", "std_msgs", "sensor_msgs", "diagnostic_msgs", "rosgraph_msgs", "rcl_interfaces",
    "ament_index_python",
}  # fmt: skip


def test_package_xml_names_rosdep_keys_for_every_python_requirement():
    """Every dependency in package.xml is a ROS package or a known rosdep key, and every Python
    requirement the package itself needs (setup.py's, figures included) has its key there."""
    root = ET.parse(ROOT / "package.xml").getroot()
    deps = {e.tag: set() for e in root}
    for e in root:
        deps[e.tag].add(e.text)
    keys = deps["exec_depend"] | deps.get("test_depend", set())
    assert keys - ROS_PACKAGES <= set(ROSDEP_KEYS), keys - ROS_PACKAGES - set(ROSDEP_KEYS)
    setup = {
        k.arg: ast.literal_eval(k.value)
        for node in ast.walk(ast.parse((ROOT / "setup.py").read_text()))
        if isinstance(node, ast.Call) and getattr(node.func, "id", "") == "setup"
        for k in node.keywords
        if k.arg in ("install_requires", "extras_require")
    }
    needed = {
        re.split(r"[<>=\[; ]", r)[0]
        for r in setup["install_requires"] + setup["extras_require"]["figures"]
    }
    provided = {ROSDEP_KEYS[k] for k in deps["exec_depend"] - ROS_PACKAGES}
    assert needed == provided
