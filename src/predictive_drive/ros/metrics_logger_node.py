"""`ros2 run predictive_drive metrics_logger_node --ros-args --params-file config/<scenario>.yaml`."""

from __future__ import annotations

import sys

from .common import run_main
from .nodes import MetricsLoggerNode

__all__ = ["main"]


def main(args: list[str] | None = None) -> int:
    return run_main(MetricsLoggerNode, args)


if __name__ == "__main__":
    sys.exit(main())
