"""`ros2 run predictive_drive speed_pi_node --ros-args --params-file config/<scenario>.yaml`."""

from __future__ import annotations

import sys

from .common import run_main
from .nodes import SpeedPINode

__all__ = ["main"]


def main(args: list[str] | None = None) -> int:
    return run_main(SpeedPINode, args)


if __name__ == "__main__":
    sys.exit(main())
