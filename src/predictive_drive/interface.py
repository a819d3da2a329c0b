"""The one module that owns the ROS interface: the namespace, node and topic names, types, QoS and
every message encoding.

No rclpy here: messages are encoded to and decoded from CDR bytes by hand, so the nodes (raw publish /
raw subscriptions), the in-process engine and the MCAP recorder all produce the *same bytes*.

Per-step topics are ``std_msgs/Float64MultiArray`` with one labelled dimension: ``layout.dim[0].label``
is the comma-separated field list of :mod:`predictive_drive.core.signals` (e.g. ``k,t,i_alpha,...``),
``size = stride = len(fields)``, ``data_offset = 0``; ``data`` holds the values in that order.
"""

from __future__ import annotations

import json
import math
import os
import struct
import sys
from dataclasses import dataclass
from pathlib import Path

from .core.signals import Command, Reference, State
from .errors import BagError

__all__ = [
    "CLOCK_PERIOD",
    "BAG_TOPICS",
    "CODECS",
    "LAUNCHER_NODE",
    "LOCKSTEP_QOS",
    "NAMESPACE",
    "NODES",
    "RECORDED_EVERY",
    "RECORDING_WINDOW",
    "RECORD_TOPICS",
    "TOPICS",
    "Qos",
    "Topic",
    "decode_multiarray",
    "ParameterEvent",
    "decode_parameter_event",
    "encode_clock",
    "encode_diagnostics",
    "encode_joint_state",
    "encode_parameter_event",
    "message_definition",
    "node_name",
    "type_hash",
]

#: every node of the drive lives in this namespace
NAMESPACE = "/drive"
#: the drive's nodes (each the name of its scenario section and of its executable ``<name>_node``)
NODES = ("plant", "speed_pi", "torque_controller", "metrics_logger")
#: the launcher's own node: it follows /clock for progress and sends timed strategy switches
LAUNCHER_NODE = "launcher"


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
#: the topics a run's bag holds
BAG_TOPICS = {key: t for key, t in TOPICS.items() if t.recorded}
#: record name (core.trace.RECORDS) → topic key, for the three per-step signal topics
RECORD_TOPICS = {"state": "state", "reference": "reference", "command": "command"}
#: decimation of /clock and /drive/joint_states: one message every this many steps' worth of time
CLOCK_PERIOD = 1e-3  #: s of simulated time (1 kHz)
#: back-pressure: the plant runs at most this many steps ahead of what the recorder has written
RECORDING_WINDOW = 1000
#: the recorder says how far it has written (/drive/recorded) every this many steps
RECORDED_EVERY = 100


# --- CDR (XCDR1, little endian) ---------------------------------------------------------------

_HEADER = b"\x00\x01\x00\x00"


class _Cdr:
    """Minimal CDR writer; alignment is relative to the byte after the encapsulation header."""

    __slots__ = ("buf",)

    def __init__(self) -> None:
        self.buf = bytearray(_HEADER)

    def _align(self, n: int) -> None:
        pad = (-(len(self.buf) - 4)) % n
        if pad:
            self.buf += b"\x00" * pad

    def u8(self, v: int) -> None:
        self.buf += struct.pack("<B", v)

    def i64(self, v: int) -> None:
        self._align(8)
        self.buf += struct.pack("<q", v)

    def f64(self, v: float) -> None:
        self._align(8)
        self.buf += struct.pack("<d", v)

    def i32(self, v: int) -> None:
        self._align(4)
        self.buf += struct.pack("<i", v)

    def u32(self, v: int) -> None:
        self._align(4)
        self.buf += struct.pack("<I", v)

    def string(self, s: str) -> None:
        b = s.encode()
        self.u32(len(b) + 1)
        self.buf += b + b"\x00"

    def f64_seq(self, values: tuple[float, ...] | list[float]) -> None:
        self.u32(len(values))
        if values:
            self._align(8)
            self.buf += struct.pack(f"<{len(values)}d", *values)

    def time(self, t: float) -> None:
        sec, nsec = stamp(t)
        self.i32(sec)
        self.u32(nsec)


def stamp(t: float) -> tuple[int, int]:
    """Simulated time in s → (sec, nanosec), rounded to the nearest ns."""
    ns = round(t * 1e9)
    return ns // 1_000_000_000, ns % 1_000_000_000


def stamp_ns(t: float) -> int:
    return round(t * 1e9)


def tool_stamp_ns(data: bytes) -> int:
    """The time of a /clock or /drive/joint_states message: its first field (clock /
    header.stamp), right after the CDR header."""
    sec, nsec = struct.unpack_from("<iI", data, 4)
    return int(sec) * 1_000_000_000 + int(nsec)


class MultiArrayCodec:
    """Float64MultiArray with a fixed label: the header is built once, each message is one pack."""

    def __init__(self, fields: tuple[str, ...]) -> None:
        self.fields = fields
        w = _Cdr()
        w.u32(1)  # one dimension
        w.string(",".join(fields))
        w.u32(len(fields))  # size
        w.u32(len(fields))  # stride
        w.u32(0)  # data_offset
        w.u32(len(fields))  # data length
        w._align(8)
        self.prefix = bytes(w.buf)
        self._fmt = struct.Struct(f"<{len(fields)}d")
        self.size = len(self.prefix) + self._fmt.size

    def encode(self, values: tuple[float, ...]) -> bytes:
        return self.prefix + self._fmt.pack(*values)

    def decode(self, data: bytes) -> tuple[float, ...]:
        """Values of a message in this layout's field order. A message of exactly this layout
        takes the fast path; another labelled layout (a recording of another version) is read
        by field name, NaN for fields it lacks; BagError if it lacks the step or time."""
        if len(data) == self.size and data.startswith(self.prefix):
            return self._fmt.unpack_from(data, len(self.prefix))
        labels, values = decode_multiarray(data)
        by_name = dict(zip(labels, values))
        if len(labels) != len(values) or not {"k", "t"} <= set(by_name):
            raise BagError(
                f"Float64MultiArray layout mismatch: expected labels {','.join(self.fields)}, got "
                f"{','.join(labels)} with {len(values)} values"
            )
        return tuple(by_name.get(f, math.nan) for f in self.fields)


CODECS: dict[str, MultiArrayCodec] = {
    key: MultiArrayCodec(TOPICS[key].fields) for key in (*RECORD_TOPICS, "recorded", "metrics")
}


def decode_multiarray(data: bytes) -> tuple[tuple[str, ...], tuple[float, ...]]:
    """Any Float64MultiArray → (labels of dim[0] split at commas, data)."""
    try:
        off = 4

        def align(n: int) -> None:
            nonlocal off
            off += (-(off - 4)) % n

        def u32() -> int:
            nonlocal off
            align(4)
            (v,) = struct.unpack_from("<I", data, off)
            off += 4
            return int(v)

        labels: list[str] = []
        for _ in range(u32()):
            n = u32()
            labels.append(data[off : off + n - 1].decode())
            off += n
            u32()
            u32()
        u32()  # data_offset
        count = u32()
        if count:
            align(8)
        values = struct.unpack_from(f"<{count}d", data, off)
    except (struct.error, UnicodeDecodeError) as e:
        raise BagError(f"not a Float64MultiArray: {e}") from None
    split = tuple(labels[0].split(",")) if labels else ()
    return split, values


def encode_clock(t: float) -> bytes:
    w = _Cdr()
    w.time(t)
    return bytes(w.buf)


JOINT_NAME = "drive_shaft"


def encode_joint_state(t: float, position: float, velocity: float, effort: float) -> bytes:
    """sensor_msgs/JointState for the shaft: angle (rad), speed (rad/s), electromagnetic torque (N·m)."""
    w = _Cdr()
    w.time(t)
    w.string("")  # frame_id
    w.u32(1)
    w.string(JOINT_NAME)
    w.f64_seq((position,))
    w.f64_seq((velocity,))
    w.f64_seq((effort,))
    return bytes(w.buf)


#: diagnostic_msgs/DiagnosticStatus levels
OK, WARN, ERROR = 0, 1, 2
LEVEL_NAMES = {OK: "OK", WARN: "WARN", ERROR: "ERROR"}


def encode_diagnostics(
    t: float, statuses: list[tuple[int, str, str, list[tuple[str, str]]]]
) -> bytes:
    """DiagnosticArray of (level, name, message, [(key, value), ...]); hardware_id = 'predictive_drive'."""
    w = _Cdr()
    w.time(t)
    w.string("")
    w.u32(len(statuses))
    for level, name, message, values in statuses:
        w.u8(level)
        w.string(name)
        w.string(message)
        w.string("predictive_drive")
        w.u32(len(values))
        for key, value in values:
            w.string(key)
            w.string(value)
    return bytes(w.buf)


def fmt(v: float) -> str:
    """A diagnostics value: repr of the float (round-trips exactly), 'nan' where undefined."""
    return "nan" if math.isnan(v) else repr(float(v))


# rcl_interfaces/msg/ParameterType
_PARAMETER_TYPES = {bool: 1, int: 2, float: 3, str: 4}


def encode_parameter_event(t: float, node: str, changed: list[tuple[str, object]]) -> bytes:
    """rcl_interfaces/ParameterEvent: ``node``'s parameters ``changed`` at ``t`` (bool, int,
    float or str values), as rclpy publishes it after an accepted set."""
    w = _Cdr()
    w.time(t)
    w.string(node)
    w.u32(0)  # new_parameters
    w.u32(len(changed))
    for name, value in changed:
        kind = _PARAMETER_TYPES[type(value)]
        w.string(name)
        w.u8(kind)
        w.u8(bool(value) if kind == 1 else 0)
        w.i64(int(value) if kind == 2 else 0)  # type: ignore[call-overload]
        w.f64(float(value) if kind == 3 else 0.0)  # type: ignore[arg-type]
        w.string(str(value) if kind == 4 else "")
        for _ in range(5):  # byte, bool, integer, double and string arrays: empty
            w.u32(0)
    w.u32(0)  # deleted_parameters
    return bytes(w.buf)


@dataclass(frozen=True)
class ParameterEvent:
    stamp_ns: int
    node: str
    new: tuple[tuple[str, object], ...]  #: (name, value) of parameters declared
    changed: tuple[tuple[str, object], ...]  #: (name, value) of parameters set


def decode_parameter_event(data: bytes) -> ParameterEvent:
    """The node and the new and changed (name, value) pairs of a ParameterEvent (array values
    as tuples; deleted parameters are not read). BagError if the bytes are not one."""
    off = 4

    def align(n: int) -> None:
        nonlocal off
        off += (-(off - 4)) % n

    def unpack(code: str, size: int) -> object:
        nonlocal off
        align(size)
        (v,) = struct.unpack_from("<" + code, data, off)
        off += size
        return v

    def string() -> str:
        nonlocal off
        n = int(unpack("I", 4))  # type: ignore[call-overload]
        s = data[off : off + n - 1].decode()
        off += n
        return s

    def seq(read: object) -> tuple[object, ...]:
        n = int(unpack("I", 4))  # type: ignore[call-overload]
        return tuple(read() for _ in range(n))  # type: ignore[operator]

    def parameter() -> tuple[str, object]:
        name = string()
        kind = int(unpack("B", 1))  # type: ignore[call-overload]
        values: list[object] = [
            bool(unpack("B", 1)),
            unpack("q", 8),
            unpack("d", 8),
            string(),
            seq(lambda: unpack("B", 1)),
            seq(lambda: bool(unpack("B", 1))),
            seq(lambda: unpack("q", 8)),
            seq(lambda: unpack("d", 8)),
            seq(string),
        ]
        return name, (values[kind - 1] if 1 <= kind <= 9 else None)

    try:
        sec, nsec = int(unpack("i", 4)), int(unpack("I", 4))  # type: ignore[call-overload]
        node = string()
        new = seq(parameter)
        changed = seq(parameter)
    except (struct.error, UnicodeDecodeError) as e:
        raise BagError(f"not a ParameterEvent: {e}") from None
    return ParameterEvent(sec * 1_000_000_000 + nsec, node, new, changed)  # type: ignore[arg-type]


# --- message definitions (for MCAP schemas) ----------------------------------------------------


def _share_dirs() -> list[Path]:
    dirs = [Path(sys.prefix) / "share"]
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            dirs.append(Path(prefix) / "share")
    return dirs


def _interface_file(type_name: str, suffix: str) -> Path:
    pkg, _, name = type_name.split("/")
    for d in _share_dirs():
        p = d / pkg / "msg" / f"{name}{suffix}"
        if p.is_file():
            return p
    raise BagError(
        f"message definition {type_name} not found under share/{pkg}/msg/ in "
        f"{', '.join(str(d) for d in _share_dirs())} (are the ROS message packages installed?)"
    )


def _deps(text: str, pkg: str) -> list[str]:
    builtin = {
        "bool",
        "byte",
        "char",
        "float32",
        "float64",
        "int8",
        "uint8",
        "int16",
        "uint16",
        "int32",
        "uint32",
        "int64",
        "uint64",
        "string",
        "wstring",
    }
    out = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        if len(parts) < 2 or "=" in parts[1]:
            continue
        base = parts[0].split("[", 1)[0].split("<=", 1)[0]
        if base in builtin:
            continue
        if "/" in base:
            dep_pkg, dep = base.split("/")[0], base.split("/")[-1]
        else:
            dep_pkg, dep = ("builtin_interfaces" if base in ("Time", "Duration") else pkg), base
        full = f"{dep_pkg}/msg/{dep}"
        if full not in out:
            out.append(full)
    return out


def message_definition(type_name: str) -> str:
    """Full ros2msg text with dependencies, as rosbag2 writes it into MCAP schemas."""
    main = _interface_file(type_name, ".msg").read_text()
    parts = [main]
    seen: set[str] = set()
    queue = _deps(main, type_name.split("/")[0])
    while queue:
        dep = queue.pop(0)
        if dep in seen:
            continue
        seen.add(dep)
        text = _interface_file(dep, ".msg").read_text()
        pkg, _, name = dep.split("/")
        parts.append("=" * 80 + f"\nMSG: {pkg}/{name}\n" + text)
        queue.extend(_deps(text, pkg))
    return "\n".join(p.rstrip("\n") for p in parts) + "\n"


def type_hash(type_name: str) -> str:
    """RIHS01 type hash of a message type, from the type description the packages install."""
    data = json.loads(_interface_file(type_name, ".json").read_text())
    for h in data.get("type_hashes", []):
        if h["type_name"] == type_name:
            return str(h["hash_string"])
    raise BagError(f"no type hash for {type_name} in its type description")
