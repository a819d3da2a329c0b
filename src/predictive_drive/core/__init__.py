"""The ROS-free core: numpy and the standard library only (a test holds it to that)."""

__all__ = [
    "control",
    "inverter",
    "metrics",
    "motors",
    "plant",
    "profiles",
    "runner",
    "scenario",
    "signals",
    "speed_pi",
    "trace",
]
