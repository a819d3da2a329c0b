"""``predictive-drive param get|set NODE NAME [VALUE]`` through the standard parameter services."""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from typing import Any

from rclpy.parameter import Parameter
from rclpy.parameter_client import AsyncParameterClient

from ..errors import ConfigError, GraphError
from ..interface import PARAM_NODE, node_name
from .transport import ros_session

__all__ = ["domain_id", "param"]


def _value(text: str) -> Any:
    import yaml

    return yaml.safe_load(text)  # as `ros2 param set` does: 1 → int, 1.0 → float, x → str


def domain_id() -> int:
    """The environment's ROS_DOMAIN_ID (0 when unset); ConfigError when it is not one."""
    text = os.environ.get("ROS_DOMAIN_ID", "0").strip() or "0"
    try:
        domain = int(text)
    except ValueError:
        domain = -1
    if not 0 <= domain <= 232:
        raise ConfigError(f"ROS_DOMAIN_ID={text!r}: expected a whole number from 0 to 232")
    return domain


#: s a request may wait for its answer before it is sent again: a request made just after the
#: services were discovered can be lost (the server's reply writer has not matched the client's
#: reader yet), so one lost answer must not cost the whole timeout
RESEND_AFTER = 2.0


def param(*, node: str, name: str, value: str | None = None, timeout: float = 10.0) -> Any:
    """Get (value None) or set a parameter on a running node; returns the value, or raises
    GraphError with the node's reason when a set is rejected or the parameter does not exist."""
    node = node_name(node)
    domain = domain_id()
    with ros_session(PARAM_NODE, domain=domain) as (me, ex):
        client = AsyncParameterClient(me, node)
        if not client.wait_for_services(timeout_sec=timeout):
            raise GraphError(f"node {node} offers no parameter services; {_where_runs_are(domain)}")
        deadline = time.monotonic() + timeout

        def answer(ask: Callable[[], Any]) -> Any:
            """``ask()``'s answer, asked again every RESEND_AFTER s until the deadline."""
            while True:
                fut = ask()
                left = deadline - time.monotonic()
                ex.spin_until_future_complete(fut, timeout_sec=max(0.0, min(RESEND_AFTER, left)))
                if fut.done():
                    return fut.result()
                if not _in_graph(me, node):
                    raise GraphError(
                        f"node {node} left the graph before its answer came (a set may have "
                        "been applied: the node ended right after it)"
                    )
                if time.monotonic() >= deadline:
                    raise GraphError(
                        f"node {node} did not answer within {timeout:g} s (its parameter "
                        "services are there: a node busy on a loaded machine may answer later; "
                        "--timeout S waits longer)"
                    )

        if value is None:
            res = answer(lambda: client.get_parameters([name]))
        else:
            res = answer(lambda: client.set_parameters([Parameter(name, value=_value(value))]))
        if value is None:
            if not res.values or res.values[0].type == 0:  # PARAMETER_NOT_SET: undeclared
                raise GraphError(f"node {node} has no parameter {name!r}; {_listing(client, ex)}")
            v = res.values[0]
            return Parameter.from_parameter_msg(type("P", (), {"name": name, "value": v})()).value
        r = res.results[0]
        if not r.successful:
            listing = _names(client, ex)
            if listing is not None and name not in listing:  # rclpy's reason names nothing
                raise GraphError(
                    f"node {node} has no parameter {name!r}; its parameters: "
                    f"{', '.join(sorted(listing))}"
                )
            raise GraphError(f"{node}: setting {name} to {value!r} was rejected: {r.reason}")
        return _value(value)


def _in_graph(me: Any, node: str) -> bool:
    """Whether ``node`` (its full name) is still among the graph's nodes as ``me`` sees them."""
    return any(
        f"{ns.rstrip('/')}/{name}" == node for name, ns in me.get_node_names_and_namespaces()
    )


def _where_runs_are(domain: int) -> str:
    """Which domains the runs going on here hold: a graph answers on its own domain only."""
    from .processes import domains_in_use

    held = domains_in_use()
    runs = (
        f"runs in progress here hold ROS_DOMAIN_ID {', '.join(map(str, held))}"
        if held
        else "no predictive-drive run is in progress here"
    )
    return (
        f"this looked on ROS_DOMAIN_ID={domain}, and {runs} (`run` prints its graph's as "
        "'graph on ROS_DOMAIN_ID=N': give it as ROS_DOMAIN_ID=N predictive-drive param ...)"
    )


def _names(client: AsyncParameterClient, ex: Any) -> list[str] | None:
    """The node's parameter names (None when the list does not come)."""
    fut = client.list_parameters()
    ex.spin_until_future_complete(fut, timeout_sec=RESEND_AFTER)
    return list(fut.result().result.names) if fut.done() else None


def _listing(client: AsyncParameterClient, ex: Any) -> str:
    names = _names(client, ex)
    if names is None:
        return "its parameter list did not come"
    return "its parameters: " + ", ".join(sorted(names))
