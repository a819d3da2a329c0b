"""``predictive-drive param get|set NODE NAME [VALUE]`` through the standard parameter services."""

from __future__ import annotations

import os
from typing import Any

import rclpy
from rclpy.context import Context
from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

from ..errors import GraphError
from ..interface import node_name
from .transport import executor

__all__ = ["param"]


def _value(text: str) -> Any:
    import yaml

    return yaml.safe_load(text)  # as `ros2 param set` does: 1 → int, 1.0 → float, x → str


def param(*, node: str, name: str, value: str | None = None, timeout: float = 10.0) -> Any:
    """Get (value None) or set a parameter on a running node; returns the value, or raises
    GraphError with the node's reason when a set is rejected."""
    node = node_name(node)
    ctx = Context()
    rclpy.init(context=ctx, domain_id=int(os.environ.get("ROS_DOMAIN_ID", "0")))
    me = rclpy.create_node("param_cli", context=ctx)
    try:
        ex = executor(ctx)
        ex.add_node(me)
        client = AsyncParameterClient(me, node)
        if not client.wait_for_services(timeout_sec=timeout):
            raise GraphError(
                f"node {node} offers no parameter services (is it running, "
                f"and is ROS_DOMAIN_ID={os.environ.get('ROS_DOMAIN_ID', '0')} its domain?)"
            )
        if value is None:
            fut = client.get_parameters([name])
        else:
            fut = client.set_parameters([Parameter(name, value=_value(value))])
        ex.spin_until_future_complete(fut, timeout_sec=timeout)
        if not fut.done():
            raise GraphError(f"node {node} did not answer within {timeout} s")
        res = fut.result()
        if value is None:
            v = res.values[0]
            return Parameter.from_parameter_msg(type("P", (), {"name": name, "value": v})()).value
        r = res.results[0]
        if not r.successful:
            raise GraphError(f"{node}: setting {name} to {value!r} was rejected: {r.reason}")
        return _value(value)
    finally:
        ex.shutdown(timeout_sec=1.0)
        me.destroy_node()
        rclpy.try_shutdown(context=ctx)
