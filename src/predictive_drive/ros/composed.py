"""All four nodes in one process on one executor (``predictive-drive run --composed``)."""

from __future__ import annotations

import sys

import rclpy
from rclpy.executors import ExternalShutdownException

from ..errors import ConfigError, GraphError
from .common import LocalBus, hold_signals, spin_nodes
from .nodes import NODE_CLASSES

__all__ = ["main"]


def main(args: list[str] | None = None) -> int:
    rclpy.init(args=sys.argv if args is None else args)
    nodes = []
    code = 0
    try:
        # logger first so it is listening before the plant looks for its peers
        bus = LocalBus()
        for name in ("metrics_logger", "torque_controller", "speed_pi", "plant"):
            nodes.append(NODE_CLASSES[name](bus=bus))
        code = spin_nodes(nodes, bus)
    except (KeyboardInterrupt, ExternalShutdownException):
        code = 130
    except (ConfigError, GraphError) as e:
        print(e, file=sys.stderr)
        code = 2
    finally:
        hold_signals()
        for n in nodes:
            if n.failure:
                print(n.failure, file=sys.stderr)
            close = getattr(n, "close", None)
            if close is not None:
                close()
            n.destroy_node()
        rclpy.try_shutdown()
    return code


if __name__ == "__main__":
    sys.exit(main())
