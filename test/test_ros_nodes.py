"""The nodes in this process, each with its own rclpy Context: parameters as declared (meaning,
unit, range, read-only), the strategy switch through rclpy's own parameter path, Fast DDS's
reading of the project's profile."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import pytest

from predictive_drive.ros.placement import ros_env

pytestmark = pytest.mark.ros


def test_fastdds_accepts_the_profile():
    """Fast DDS reports a profile it cannot parse on stderr and carries on; this one it takes."""
    code = "import rclpy; rclpy.init(); n = rclpy.create_node('profile_check'); "
    code += "from std_msgs.msg import Float64MultiArray as M; n.create_publisher(M, 'x', 10); "
    code += "n.destroy_node(); rclpy.shutdown(); print('ok')"
    r = subprocess.run(
        [sys.executable, "-c", code],
        env=ros_env(int(os.environ["ROS_DOMAIN_ID"])),
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.stdout.strip() == "ok" and "XMLPARSER" not in r.stderr, r.stderr


def test_controller_node_rejects_a_strategy_of_another_family():
    """In-process node with its own context, through rclpy's own parameter path (what the
    parameter services call): db_mptc is an IM strategy, so a PMSM controller refuses it with the
    valid names and keeps running what it runs; a valid name is applied by the post-set callback;
    a read-only parameter is refused."""
    import rclpy
    from rclpy.context import Context
    from rclpy.parameter import Parameter

    from predictive_drive.config import resolve_scenario_path
    from predictive_drive.ros.torque_controller_node import TorqueControllerNode

    ctx = Context()
    path = resolve_scenario_path("ipmsm_short")
    rclpy.init(context=ctx, args=["--ros-args", "--params-file", str(path)])
    try:
        node = TorqueControllerNode(context=ctx)
        try:
            (res,) = node.set_parameters([Parameter("strategy", Parameter.Type.STRING, "db_mptc")])
            assert not res.successful
            assert "controller family 'mptc_pmsm'" in res.reason
            assert "valid: mptc, simplified1, simplified2, simplified3" in res.reason
            assert node.ctrl.strategy.name == "mptc"
            assert node.get_parameter("strategy").value == "mptc"
            (ok,) = node.set_parameters(
                [Parameter("strategy", Parameter.Type.STRING, "simplified2")]
            )
            assert ok.successful and node.ctrl.strategy.name == "simplified2"
            (ro,) = node.set_parameters([Parameter("t_floor", Parameter.Type.DOUBLE, 1.0)])
            assert not ro.successful and "read-only" in ro.reason
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


def _descriptors(node):
    names = sorted(node._parameters)
    return dict(zip(names, node.describe_parameters(names)))


@pytest.mark.parametrize("scenario", ["im_short", "ipmsm_short"])
def test_every_parameter_is_described_with_unit_and_range_and_read_only(node_in, scenario):
    from predictive_drive.ros.metrics_logger_node import MetricsLoggerNode
    from predictive_drive.ros.plant_node import PlantNode
    from predictive_drive.ros.speed_pi_node import SpeedPINode
    from predictive_drive.ros.torque_controller_node import TorqueControllerNode

    for cls in (PlantNode, SpeedPINode, TorqueControllerNode, MetricsLoggerNode):
        node = node_in(cls, scenario)
        for name, d in _descriptors(node).items():
            if name == "use_sim_time":  # rclpy's own
                continue
            assert d.description, (cls.__name__, name)
            # the switchable ones (strategy, horizon) are the controller's only writable ones
            assert d.read_only == (name not in cls.writable), (cls.__name__, name)
    plant = _descriptors(node_in(PlantNode, scenario))
    r_s = plant["motor.r_s"]
    assert "stator resistance" in r_s.description and "Ω" in r_s.description
    (rng,) = r_s.floating_point_range
    assert (rng.from_value, rng.to_value) == (0.0, math.inf)
    (p,) = plant["motor.p"].integer_range
    assert p.from_value == 1
    assert "unit V" in plant["u_dc"].description
    assert "unit s" in plant["peer_timeout"].description
    ctrl = _descriptors(node_in(TorqueControllerNode, scenario))
    assert "one of mptc_im, mptc_pmsm" in ctrl["family"].description
    assert not ctrl["strategy"].read_only and "horizon" in TorqueControllerNode.writable


def test_a_parameter_outside_its_range_is_refused_when_declared(tmp_path):
    """The range in the descriptor is enforced by rclpy as the parameter file is applied."""
    import rclpy
    from rclpy.context import Context
    from rclpy.exceptions import InvalidParameterValueException

    from predictive_drive.config import resolve_scenario_path
    from predictive_drive.ros.plant_node import PlantNode

    ctx = Context()
    bad = tmp_path / "override.yaml"  # node-specific, so it beats the scenario file's value
    bad.write_text("/drive/plant:\n  ros__parameters:\n    u_dc: -5.0\n")
    args = ["--ros-args", "--params-file", str(resolve_scenario_path("im_short"))]
    rclpy.init(context=ctx, args=[*args, "--params-file", str(bad)])
    try:
        with pytest.raises(InvalidParameterValueException, match="u_dc"):
            PlantNode(context=ctx)
    finally:
        rclpy.try_shutdown(context=ctx)


def test_a_stop_ends_the_wait_for_subscribers_at_once(node_in):
    """SIGINT / SIGTERM (STOP) while a node waits for the readers of its first message: the wait
    ends at once (was: the whole start-up timeout, 60 s, polled without looking at a stop)."""
    import threading
    import time

    from predictive_drive.ros.node_base import STOP
    from predictive_drive.ros.speed_pi_node import SpeedPINode

    node = node_in(SpeedPINode, "im_short")
    assert node.startup_timeout == 60.0
    stopper = threading.Timer(0.5, STOP.set)
    stopper.start()
    try:
        t0 = time.monotonic()
        node.wait_matched(node.pub_ref, 5, "five readers that never come")
        assert time.monotonic() - t0 < 30.0  # a bound on a hang, not a measurement
    finally:
        stopper.cancel()
        STOP.clear()
