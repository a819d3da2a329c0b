"""``predictive-drive param get|set NODE NAME [VALUE]``: a parameter of a running node."""

from __future__ import annotations

import argparse

from ..errors import ConfigError
from .common import dumps

HELP = (
    "get or set a parameter of a running node (uses ROS_DOMAIN_ID; `run` prints the domain of "
    "its graph)"
)


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("action", choices=["get", "set"])
    p.add_argument("node", help="node name, e.g. torque_controller or /drive/torque_controller")
    p.add_argument("name", help="parameter name, e.g. strategy")
    p.add_argument("value", nargs="?", help="set: the new value (read as YAML: 1, 1.0, mptc)")
    p.add_argument(
        "--timeout",
        type=float,
        default=10.0,
        metavar="S",
        help="s to wait for the node's parameter services and then for its answer (default 10; "
        "a node busy on a loaded machine may need longer)",
    )


def main(a: argparse.Namespace) -> int:
    from ..interface import node_name
    from ..ros.params import param

    if not a.timeout > 0.0:
        raise ConfigError(f"--timeout {a.timeout:g}: a number of seconds above 0")

    if a.action == "get":
        if a.value is not None:
            raise ConfigError("param get takes NODE NAME only")
        value = param(node=a.node, name=a.name, timeout=a.timeout)
    else:
        if a.value is None:
            raise ConfigError("param set needs NODE NAME VALUE")
        value = param(node=a.node, name=a.name, value=a.value, timeout=a.timeout)
    if a.json:
        print(
            dumps({"action": a.action, "node": node_name(a.node), "name": a.name, "value": value})
        )
    elif a.action == "get":
        print(value)
    else:
        print(f"set {a.name} = {a.value} on {a.node}")
    return 0
