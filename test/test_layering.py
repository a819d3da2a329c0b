"""The core (and everything a ROS-free user touches) never imports rclpy."""

import subprocess
import sys

import pytest

ROS_FREE = [
    "predictive_drive.core.control",
    "predictive_drive.core.inverter",
    "predictive_drive.core.metrics",
    "predictive_drive.core.motors",
    "predictive_drive.core.plant",
    "predictive_drive.core.profiles",
    "predictive_drive.core.runner",
    "predictive_drive.core.scenario",
    "predictive_drive.core.signals",
    "predictive_drive.core.speed_pi",
    "predictive_drive.core.trace",
    "predictive_drive.interface",
    "predictive_drive.bag",
    "predictive_drive.config",
    "predictive_drive.api",
    "predictive_drive.cli",
    "predictive_drive.recording",
]


@pytest.mark.parametrize("module", ROS_FREE)
def test_module_does_not_import_rclpy(module):
    code = f"import sys, {module}; assert 'rclpy' not in sys.modules, 'rclpy imported'"
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)


def test_core_imports_only_numpy_and_stdlib():
    code = (
        "import sys, importlib, pkgutil\n"
        "before = set(sys.modules)\n"
        "import predictive_drive.core as c\n"
        "for m in pkgutil.iter_modules(c.__path__):\n"
        "    importlib.import_module('predictive_drive.core.' + m.name)\n"
        "new = set(sys.modules) - before\n"
        "third = {n.split('.')[0] for n in new} - set(sys.stdlib_module_names)\n"
        "assert third <= {'numpy', 'predictive_drive'}, third\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)
