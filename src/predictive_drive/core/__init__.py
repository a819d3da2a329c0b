"""The ROS-free core: numpy and the standard library only (a test holds it to that)."""

__all__ = [
    "analysis",
    "control",
    "fields",
    "inverter",
    "machines",
    "metrics",
    "plant",
    "runner",
    "scenario",
    "signals",
    "timebase",
    "trace",
]
