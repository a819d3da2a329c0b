"""The only code that touches rclpy: four thin nodes over the core, and the graph launcher."""

__all__ = ["common", "graph"]
