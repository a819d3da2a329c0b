"""The ROS interface as data: the namespace, the node and topic names, the message types, QoS, and
the topic table — the one place a topic or node name is written. The bytes on each topic are
:mod:`predictive_drive.codec`'s, the schemas :mod:`predictive_drive.schemas`'.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from .core.signals import Command, Losses, Reference, State

__all__ = [
    "BAG_TOPICS",
    "LOSSES_TOPIC",
    "CLOCK_PERIOD",
    "LAUNCHER_NODE",
    "LOCKSTEP_QOS",
    "NAMESPACE",
    "NODES",
    "PARAM_NODE",
    "PLAYER_NODE",
    "RECORDED_EVERY",
    "RECORDING_WINDOW",
    "RECORD_TOPICS",
    "STEPPER_NODE",
    "TOOL_TOPICS",
    "TOPICS",
    "Qos",
    "Topic",
    "bag_topics",
    "node_name",
]

#: every node of the drive lives in this namespace
NAMESPACE = "/drive"
#: the drive's nodes (each the name of its scenario section and of its executable ``<name>_node``)
NODES = ("plant", "speed_pi", "torque_controller", "metrics_logger")
#: the launcher's own node: it follows /clock for progress and sends timed strategy switches
LAUNCHER_NODE = "launcher"
#: the node of ``replay BAG --into``: plays plant and speed loop for a controller, step by step
STEPPER_NODE = "stepper"
#: the node of ``replay BAG``: publishes a recording (``rate`` and ``paused`` settable)
PLAYER_NODE = "player"
#: the node of ``predictive-drive param`` (outside the namespace, as ``ros2 param``'s)
PARAM_NODE = "param_cli"


def node_name(name: str) -> str:
    """Fully qualified name of a drive node: ``plant`` → ``/drive/plant``."""
    return name if name.startswith("/") else f"{NAMESPACE}/{name}"


FLOAT64_MULTI_ARRAY = "std_msgs/msg/Float64MultiArray"
#: labels of /drive/recorded: every step up to k is recorded, k·Ts is t, messages written so far
RECORDED_FIELDS = ("k", "t", "messages")
#: labels of /drive/metrics: the running figures of /diagnostics as numbers, one message per
#: diagnostics period: last step k and its time t, steps so far, the period's RMS errors (N·m,
#: Wb, N·m, rad/s), mean switching frequency (Hz), strategy index, diagnostic level (0 OK, 1 WARN)
METRICS_FIELDS = (
    "k", "t", "steps", "t_rmse", "psi_rmse", "torque_estimate_rmse", "speed_rmse", "f_ave_hz",
    "strategy", "level",
)  # fmt: skip


@dataclass(frozen=True)
class Qos:
    """A QoS profile as plain data (the nodes turn it into rclpy's QoSProfile)."""

    reliability: str  #: "reliable" | "best_effort"
    durability: str  #: "volatile" | "transient_local"
    history: str  #: "keep_last" | "keep_all"
    depth: int

    @classmethod
    def from_rosbag2(cls, profile: dict[str, Any]) -> Qos:
        """The profile of a rosbag2 ``offered_qos_profiles`` entry (unknown or missing
        policies as ``ros2 bag play`` takes them: reliable, volatile, keep_last 10)."""
        return cls(
            "best_effort" if profile.get("reliability") == "best_effort" else "reliable",
            "transient_local" if profile.get("durability") == "transient_local" else "volatile",
            "keep_all" if profile.get("history") == "keep_all" else "keep_last",
            int(profile.get("depth", 10) or 10),
        )

    def rosbag2(self) -> dict[str, object]:
        """rosbag2 (metadata version 9) form of one offered QoS profile."""
        infinite = {"sec": 9223372036, "nsec": 854775807}  # RMW_DURATION_INFINITE, as rosbag2
        return {
            "history": self.history,
            "depth": self.depth,
            "reliability": self.reliability,
            "durability": self.durability,
            "deadline": dict(infinite),
            "lifespan": dict(infinite),
            "liveliness": "automatic",
            "liveliness_lease_duration": dict(infinite),
            "avoid_ros_namespace_conventions": False,
        }


#: lock-step edges and the recorder: nothing may be lost, so reliable and keep-all
LOCKSTEP_QOS = Qos("reliable", "volatile", "keep_all", 0)
#: decimated tool topics: reliable (so the recorder loses none; best-effort readers such as
#: rclpy's time source still match) and a deep enough history for a slow reader
TOOLS_QOS = Qos("reliable", "volatile", "keep_last", 1000)
#: rclpy's qos_profile_parameter_events (what every node's /parameter_events publisher offers)
PARAMETER_EVENTS_QOS = Qos("reliable", "volatile", "keep_last", 1000)


@dataclass(frozen=True)
class Topic:
    name: str
    type: str  #: ROS type name, pkg/msg/Type
    qos: Qos
    fields: tuple[str, ...] = ()  #: labels of a Float64MultiArray record topic
    recorded: bool = True  #: written into the run's bag


TOPICS: dict[str, Topic] = {
    "state": Topic(f"{NAMESPACE}/state", FLOAT64_MULTI_ARRAY, LOCKSTEP_QOS, State._fields),
    "reference": Topic(
        f"{NAMESPACE}/torque_reference", FLOAT64_MULTI_ARRAY, LOCKSTEP_QOS, Reference._fields
    ),
    "command": Topic(f"{NAMESPACE}/command", FLOAT64_MULTI_ARRAY, LOCKSTEP_QOS, Command._fields),
    # the plant's losses and temperatures, one message a step beside the state: published and
    # recorded only where plant.losses is on (a run without has no such topic)
    "losses": Topic(f"{NAMESPACE}/losses", FLOAT64_MULTI_ARRAY, LOCKSTEP_QOS, Losses._fields),
    "joint_states": Topic(f"{NAMESPACE}/joint_states", "sensor_msgs/msg/JointState", TOOLS_QOS),
    "clock": Topic("/clock", "rosgraph_msgs/msg/Clock", TOOLS_QOS),
    "diagnostics": Topic("/diagnostics", "diagnostic_msgs/msg/DiagnosticArray", TOOLS_QOS),
    "metrics": Topic(f"{NAMESPACE}/metrics", FLOAT64_MULTI_ARRAY, TOOLS_QOS, METRICS_FIELDS),
    # accepted parameter changes of the drive's nodes, as rclpy publishes them (the logger
    # records the changes, not the declarations at start-up)
    "parameter_events": Topic(
        "/parameter_events", "rcl_interfaces/msg/ParameterEvent", PARAMETER_EVENTS_QOS
    ),
    # the recorder's progress: every step up to k is in the bag (the plant's back-pressure)
    "recorded": Topic(
        f"{NAMESPACE}/recorded", FLOAT64_MULTI_ARRAY, TOOLS_QOS, RECORDED_FIELDS, recorded=False
    ),
}
#: the plant's decimated tool topics (besides the per-step records)
TOOL_TOPICS = ("clock", "joint_states")
#: the topics a run's bag may hold
BAG_TOPICS = {key: t for key, t in TOPICS.items() if t.recorded}
#: record name (core.trace.RECORDS) → topic key, for the three per-step signal topics
RECORD_TOPICS = {"state": "state", "reference": "reference", "command": "command"}
#: the per-step topic a run has only where the plant books its losses (``plant.losses`` on),
#: one message a step beside the state: a run without it has neither the topic nor its channel
LOSSES_TOPIC = "losses"


def bag_topics(*, losses: bool) -> dict[str, Topic]:
    """The topics the bag of a run holds: every recorded one, /drive/losses only with
    ``losses``."""
    return {k: t for k, t in BAG_TOPICS.items() if losses or k != LOSSES_TOPIC}


#: decimation of /clock and /drive/joint_states: one message every this many steps' worth of time
CLOCK_PERIOD = 1e-3  #: s of simulated time (1 kHz)
#: back-pressure: the plant runs at most this many steps ahead of what the recorder has written
RECORDING_WINDOW = 1000
#: the recorder says how far it has written (/drive/recorded) every this many steps
RECORDED_EVERY = 100
