"""`colcon build` (colcon from PyPI) turns the repository into a ROS 2 install: what `ros2 run` uses."""

import shutil
import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.process

ROOT = Path(__file__).resolve().parents[1]
NODES = ["plant_node", "speed_pi_node", "torque_controller_node", "metrics_logger_node"]


def test_colcon_build_installs_node_executables_and_ament_marker(tmp_path):
    pkg = tmp_path / "src" / "predictive_drive"
    pkg.mkdir(parents=True)
    for name in ("package.xml", "setup.py", "setup.cfg", "README.md"):
        shutil.copy(ROOT / name, pkg / name)
    for name in ("resource", "src", "config"):
        shutil.copytree(ROOT / name, pkg / name, ignore=shutil.ignore_patterns("__pycache__"))
    colcon = Path(sys.executable).with_name("colcon")
    subprocess.run(
        [str(colcon), "build", "--base-paths", "src"],
        cwd=tmp_path,
        check=True,
        timeout=300,
        capture_output=True,
    )
    install = tmp_path / "install" / "predictive_drive"
    for node in NODES:
        assert (install / "lib" / "predictive_drive" / node).is_file(), node
    assert (install / "share/ament_index/resource_index/packages/predictive_drive").is_file()
    assert (install / "share/predictive_drive/package.xml").is_file()
    assert (install / "share/predictive_drive/config/im_paper.yaml").is_file()
