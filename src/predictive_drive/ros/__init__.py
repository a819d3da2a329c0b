"""The only code that touches rclpy (but :mod:`.placement`, the launcher's contract with its nodes):
one node class and its ``main`` per file, the launcher, the composed process and ``param``."""

__all__ = [
    "composed",
    "launcher",
    "metrics_logger_node",
    "node_base",
    "params",
    "placement",
    "plant_node",
    "speed_pi_node",
    "torque_controller_node",
    "transport",
]
