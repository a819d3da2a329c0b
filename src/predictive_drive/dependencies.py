"""The Python packages the command line needs beyond the standard library, and how to install
each: where one is missing, the command says so in one line (the package, and how to get it with
pip, rosdep or a ROS install), never a traceback. Standard library only: it speaks when the
rest cannot be imported."""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass

from .errors import MissingDependency

__all__ = ["GRAPH_MODULES", "REQUIREMENTS", "ROS_PACKAGES", "Requirement", "how_to_install", "missing",
           "require_ros"]  # fmt: skip


@dataclass(frozen=True)
class Requirement:
    """A package as pip installs it, its rosdep key (None: rosdep has none, pip is the way in a
    ROS workspace too) and the ``setup.py`` extra that brings it (None: always needed)."""

    distribution: str
    rosdep: str | None
    extra: str | None = None


#: by the name Python imports (package.xml's keys and setup.py's requirements, held to each
#: other by test_colcon.py)
REQUIREMENTS: dict[str, Requirement] = {
    "numpy": Requirement("numpy", "python3-numpy"),
    "yaml": Requirement("PyYAML", "python3-yaml"),
    "mcap": Requirement("mcap", "mcap-ros2-support"),  # pip key: it requires mcap
    "tqdm": Requirement("tqdm", "python3-tqdm"),
    "matplotlib": Requirement("matplotlib", "python3-matplotlib", "figures"),
    "foxglove": Requirement("foxglove-sdk", None, "live"),
    "pyarrow": Requirement("pyarrow", None, "sweep"),
    "dask": Requirement("dask[distributed]", None, "sweep"),
    "distributed": Requirement("dask[distributed]", None, "sweep"),
}

#: what a ROS 2 Jazzy install provides (here: the PyPI wheels of the [ros] extra)
ROS_PACKAGES = frozenset(
    {
        "rclpy", "rcl_interfaces", "std_msgs", "sensor_msgs", "diagnostic_msgs", "rosgraph_msgs",
        "builtin_interfaces", "ament_index_python", "rpyutils", "rosidl_runtime_py",
    }
)  # fmt: skip


def _package_and_how(module: str) -> tuple[str, str]:
    """(what provides ``module``, how to install it)."""
    top = module.split(".")[0]
    if top in ROS_PACKAGES:
        return (
            f"the ROS 2 package {top}",
            "source a ROS 2 Jazzy install (. /opt/ros/jazzy/setup.sh) or pip install "
            "'predictive_drive[ros]'",
        )
    r = REQUIREMENTS.get(top)
    if r is None:
        return f"the Python module {top}", f"pip install {top}"
    pip = f"pip install '{r.distribution}'"
    if r.extra is not None:
        pip += f" (or the package's [{r.extra}] extra)"
    if r.rosdep is None:
        return f"the Python package {r.distribution}", (
            f"{pip}; it has no rosdep key, so in a ROS workspace too pip is the way"
        )
    return f"the Python package {r.distribution}", (
        f"{pip}; in a ROS workspace, rosdep install --from-paths src --ignore-src -y (its key: "
        f"{r.rosdep})"
    )


def how_to_install(module: str) -> str:
    """What is missing and how to install it, for the module Python could not import."""
    package, how = _package_and_how(module)
    return f"{package} is not installed: {how}"


def missing(module: str, needed_for: str) -> MissingDependency:
    """The error of an optional feature (``needed_for``: the option) whose package is missing."""
    package, how = _package_and_how(module)
    return MissingDependency(f"{needed_for} needs {package}, which is not installed: {how}")


#: what the nodes of a graph import: looked for (not imported) before any node process starts
GRAPH_MODULES = ("rclpy", "rcl_interfaces", "std_msgs", "sensor_msgs", "rosgraph_msgs")


def require_ros(needed_for: str) -> None:
    """MissingDependency naming the first ROS 2 package a graph's nodes would fail to import
    (``needed_for``: the option that asks for the graph), before anything starts: a node
    process that cannot import rclpy otherwise fails after the launch, with a traceback."""
    for module in GRAPH_MODULES:
        try:
            found = importlib.util.find_spec(module) is not None
        except (ImportError, ValueError):
            found = False
        if not found:
            raise MissingDependency(
                f"{missing(module, needed_for)}; or run in-process (--engine inprocess), which "
                "needs no ROS"
            )
