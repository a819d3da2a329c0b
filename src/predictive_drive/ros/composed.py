"""All four nodes in one process on one executor (``predictive-drive run --composed``)."""

from __future__ import annotations

import sys

from .common import DriveNode, LocalBus, spin_main
from .nodes import NODE_CLASSES

__all__ = ["main"]


def main(args: list[str] | None = None) -> int:
    def make(bus: LocalBus | None) -> list[DriveNode]:
        # logger first so it is listening before the plant looks for its peers
        names = ("metrics_logger", "torque_controller", "speed_pi", "plant")
        return [NODE_CLASSES[name](bus=bus) for name in names]

    return spin_main(make, args=sys.argv if args is None else args, bus=LocalBus())


if __name__ == "__main__":
    sys.exit(main())
