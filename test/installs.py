"""The package installed the two ways users install it, each in a temporary folder outside the
source tree: a wheel (``pip wheel`` + ``pip install`` into a fresh venv, its dependencies taken
from the index as a user's would be) and a ``colcon build`` workspace without
``--symlink-install``."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: what a colcon workspace's source folder gets: the package as `git clone` gives it
PACKAGE_FILES = ("package.xml", "setup.py", "setup.cfg", "README.md")
PACKAGE_DIRS = ("resource", "src", "config", "launch", "layouts")


@dataclass(frozen=True)
class Install:
    """An installed package: how to call its command line and its node executables, and the
    environment they need (what activating the venv / sourcing the workspace gives a shell)."""

    kind: str
    prefix: Path  #: the venv, or the workspace's install/predictive_drive
    bin: Path  #: where `predictive-drive` and the node executables are
    python: Path
    env: dict[str, str]

    @property
    def cli(self) -> list[str]:
        return [str(self.bin / "predictive-drive")]

    def node(self, name: str) -> list[str]:
        return [str(self.bin / f"{name}_node")]

    def share(self) -> Path:
        return self.prefix / "share" / "predictive_drive"


def clean_env() -> dict[str, str]:
    """The environment without this checkout on any path (the test's own venv and its
    editable install must not leak into the installed package's runs)."""
    # the ROS wheels' bootstrapper re-executes Python with the venv's library path and a guard
    # variable; a child of this process would inherit both, and a fresh venv must find its own
    dropped = ("PYTHONPATH", "VIRTUAL_ENV", "_ROS_WHEELS_BOOTSTRAP_COMPLETE", "AMENT_PREFIX_PATH")
    env = {k: v for k, v in os.environ.items() if k not in dropped}
    for var in ("PATH", "LD_LIBRARY_PATH"):
        env[var] = os.pathsep.join(
            p
            for p in env.get(var, "").split(os.pathsep)
            if p and not p.startswith((str(ROOT), sys.prefix))
        )
    env["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"
    return env


def copy_package(dest: Path) -> Path:
    """The package's files as a fresh clone has them (no build/, egg-info or caches of this
    checkout, which setuptools would reuse)."""
    dest.mkdir(parents=True)
    for name in PACKAGE_FILES:
        shutil.copy(ROOT / name, dest / name)
    for name in PACKAGE_DIRS:
        shutil.copytree(
            ROOT / name, dest / name, ignore=shutil.ignore_patterns("__pycache__", "*.egg-info")
        )
    return dest


def wheel_install(tmp: Path, extras: str = "ros,figures") -> Install:
    """``pip wheel`` of a clean copy of the checkout, installed with ``extras`` into a new
    venv."""
    source = copy_package(tmp / "source")
    dist = tmp / "dist"
    subprocess.run(
        [sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(source)],
        check=True, capture_output=True, timeout=300,
    )  # fmt: skip
    (wheel,) = dist.glob("predictive_drive-*.whl")
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True, timeout=120)
    python = venv / "bin" / "python"
    subprocess.run(
        [str(python), "-m", "pip", "install", "-q", f"{wheel}[{extras}]"],
        check=True, capture_output=True, timeout=600, env=clean_env(),
    )  # fmt: skip
    env = clean_env()
    env["PATH"] = os.pathsep.join([str(venv / "bin"), env["PATH"]])
    env["VIRTUAL_ENV"] = str(venv)
    return Install("wheel", venv, venv / "bin", python, env)


def colcon_install(tmp: Path) -> Install:
    """``colcon build`` (no ``--symlink-install``) of a workspace holding the package."""
    ws = tmp / "ws"
    copy_package(ws / "src" / "predictive_drive")
    colcon = Path(sys.executable).with_name("colcon")
    subprocess.run(
        [str(colcon), "build", "--base-paths", "src"],
        cwd=ws, check=True, timeout=300, capture_output=True,
    )  # fmt: skip
    prefix = ws / "install" / "predictive_drive"
    site = next(prefix.glob("lib/python3*/site-packages"))
    env = clean_env()
    # what `. install/setup.sh` gives: the package's prefix in the ament index, its
    # site-packages on the path; the interpreter is the one it was built with (here: the test
    # venv, which holds rclpy from the wheels as a ROS install would)
    env["AMENT_PREFIX_PATH"] = os.pathsep.join([str(prefix), sys.prefix])
    env["PYTHONPATH"] = str(site)
    return Install("colcon", prefix, prefix / "lib" / "predictive_drive", Path(sys.executable), env)
