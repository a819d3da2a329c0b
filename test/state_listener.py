"""An independent subscriber of the drive's state, as a user's tool would run it: rclpy and
std_msgs only, its own process (test_replay.py). ``state_listener.py N`` subscribes to
/drive/state (reliable, keep-all), says ``ready`` once its subscription exists, and counts what
comes until N states have, or 10 s pass without one (a minute before the first); then prints
one JSON line: how many came, their steps' first and last, and whether they came in order."""

from __future__ import annotations

import json
import sys
import time

import rclpy
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64MultiArray

LOCKSTEP = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
    history=HistoryPolicy.KEEP_ALL,
)


def main() -> int:
    expected = int(sys.argv[1])
    rclpy.init()
    node = rclpy.create_node("state_listener")
    steps: list[int] = []
    node.create_subscription(
        Float64MultiArray, "/drive/state", lambda m: steps.append(int(m.data[0])), LOCKSTEP
    )
    print("ready", flush=True)
    last = time.monotonic() + 50.0  # the first may take a minute; then 10 s each at most
    try:
        while len(steps) < expected and time.monotonic() - last < 10.0:
            n = len(steps)
            rclpy.spin_once(node, timeout_sec=0.1)
            if len(steps) != n:
                last = time.monotonic()
    finally:
        print(json.dumps({
            "count": len(steps),
            "first": steps[0] if steps else None,
            "last": steps[-1] if steps else None,
            "in_order": steps == sorted(steps),
        }), flush=True)  # fmt: skip
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())
