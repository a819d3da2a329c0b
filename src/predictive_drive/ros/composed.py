"""All four nodes in one process on one executor (``predictive-drive run --composed``)."""

from __future__ import annotations

import sys

from .metrics_logger_node import MetricsLoggerNode
from .node_base import DriveNode, spin_main
from .plant_node import PlantNode
from .speed_pi_node import SpeedPINode
from .torque_controller_node import TorqueControllerNode
from .transport import LocalBus

__all__ = ["main"]


def main(args: list[str] | None = None) -> int:
    def make(bus: LocalBus | None) -> list[DriveNode]:
        # logger first so it is listening before the plant looks for its peers
        return [
            MetricsLoggerNode(bus=bus),
            TorqueControllerNode(bus=bus),
            SpeedPINode(bus=bus),
            PlantNode(bus=bus),
        ]

    return spin_main(make, args=sys.argv if args is None else args, bus=LocalBus())


if __name__ == "__main__":
    sys.exit(main())
