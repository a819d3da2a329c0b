"""Shared fixtures. Every test run isolates its ROS traffic (own domain id, localhost only)."""

from __future__ import annotations

import contextlib
import os
import warnings

import pytest

from predictive_drive.ros.processes import isolated_domain

# before anything imports rclpy: a domain of this test process's own while it runs, loopback
# only. Flock'ed in 101..199 (the runs' own are 1..100), so pytest-xdist's workers and other test
# sessions on the machine never share one (the workers inherited the controller's before)
_HELD = contextlib.ExitStack()  # never closed: the lock lasts as long as this process
os.environ["ROS_DOMAIN_ID"] = str(_HELD.enter_context(isolated_domain(range(101, 200))))
os.environ["ROS_AUTOMATIC_DISCOVERY_RANGE"] = "LOCALHOST"

from installs import colcon_install, wheel_install  # noqa: E402
from predictive_drive.config import load_scenario  # noqa: E402
from predictive_drive.core.runner import run_inprocess  # noqa: E402

# pytest-xdist (make test runs two workers with --dist loadfile: a file's tests stay on one
# worker, so its module fixtures are made once). The longest files go first, so that the
# workers finish together. (Not loadgroup: xdist 3.8 under pytest 9 schedules by item.nodeid,
# which no longer carries the group its hook appends to _nodeid.)
LONGEST_FIRST = ["test_external.py", "test_graph.py", "test_install.py", "test_replay.py",
                 "test_readme.py"]  # fmt: skip


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    rank = {name: i for i, name in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.path.name, len(rank)))  # stable: the rest in order


@pytest.fixture(scope="session", autouse=True)
def _temporary_files_in_the_sessions_folder(tmp_path_factory):
    """The processes the tests start make their temporary files under the session's own folder
    (TMPDIR), which pytest keeps for its last three sessions: a launcher a test kills outright
    (SIGKILL) cannot remove its scenario file's folder, and /tmp gathered one per such test."""
    os.environ["TMPDIR"] = str(tmp_path_factory.mktemp("tmp"))


@pytest.fixture(scope="session")
def im_short():
    return load_scenario("im_short")


@pytest.fixture(scope="session")
def short_traces(im_short):
    """A 0.4 s closed-loop run per IM strategy (shared: each takes about a second)."""
    return {s: run_inprocess(im_short.with_strategy(s)) for s in ("mptc", "mptc_db", "db_mptc")}


@pytest.fixture(scope="session")
def colcon_built(tmp_path_factory):
    """The package as `colcon build` installs it (built once per test session)."""
    return colcon_install(tmp_path_factory.mktemp("colcon"))


@pytest.fixture(scope="session")
def wheel_installed(tmp_path_factory):
    """The package's wheel installed into a fresh venv (once per test session)."""
    return wheel_install(tmp_path_factory.mktemp("wheel"))


@pytest.fixture(scope="session")
def typescript_reader(tmp_path_factory):
    """``check(mcap_path)``: Foxglove's TypeScript reader (see ts_reader.py) reads the file as
    the mcap library does; None where Node.js is missing or npm cannot install it (a test that
    checks more than that goes on without it)."""
    import ts_reader

    folder = ts_reader.install(tmp_path_factory.mktemp("ts_reader"))
    if isinstance(folder, str):
        warnings.warn(f"Foxglove's TypeScript reader is not checked: {folder}", stacklevel=1)
        return None
    return lambda mcap: ts_reader.assert_reads_like_the_library(folder, mcap)


@pytest.fixture
def node_in(tmp_path):
    """``node_in(cls, scenario)``: a node built in this process from a scenario file, in its own
    Context; destroyed (and the Context shut down) in teardown."""
    import rclpy
    from rclpy.context import Context

    from predictive_drive.config import resolve_scenario_path

    made = []

    def make(cls, scenario):
        ctx = Context()
        args = ["--ros-args", "--params-file", str(resolve_scenario_path(scenario))]
        args += ["-p", f"bag:={tmp_path / 'bag'}"]  # the logger's
        rclpy.init(context=ctx, args=args)
        made.append(ctx)
        node = cls(context=ctx)
        made.append(node)
        return node

    yield make
    for obj in reversed(made):
        if hasattr(obj, "destroy_node"):
            if hasattr(obj, "close"):
                obj.close()
            obj.destroy_node()
        else:
            rclpy.try_shutdown(context=obj)
