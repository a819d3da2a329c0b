"""Every message the package sends or records, encoded to and decoded from CDR bytes by hand.

No rclpy here: the nodes publish and subscribe raw (serialized) messages, and the in-process
engine and the MCAP recorder use the same encoders, so every engine produces the *same bytes*.
One writer (:class:`CdrWriter`) and one reader (:class:`CdrReader`) of XCDR1 little endian, the
encoding Fast DDS and rosbag2 use.

Per-step topics are ``std_msgs/Float64MultiArray`` with one labelled dimension: ``layout.dim[0].
label`` is the comma-separated field list of :mod:`predictive_drive.core.signals` (e.g.
``k,t,i_alpha,...``), ``size = stride = len(fields)``, ``data_offset = 0``; ``data`` holds the
values in that order (:class:`MultiArrayCodec`: a constant prefix and one ``struct.pack``).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import numpy as np

from .core.commands import FORMS, PULSE_SLACK, CommandError, command_from
from .core.signals import COMMAND_INDEX, Command
from .errors import BagError
from .interface import LOSSES_TOPIC, RECORD_TOPICS, TOPICS

__all__ = [
    "CODECS",
    "ERROR",
    "LEVEL_NAMES",
    "OK",
    "WARN",
    "CdrReader",
    "CdrWriter",
    "MultiArrayCodec",
    "ParameterEvent",
    "command_for_step",
    "decode_command",
    "decode_multiarray",
    "decode_parameter_event",
    "diagnostics_value",
    "encode_clock",
    "encode_diagnostics",
    "encode_joint_state",
    "encode_parameter_event",
    "labelled",
    "stamp",
    "stamp_ns",
    "tool_stamp_ns",
]

#: the fields of the command forms the plant resolves to pulses
RESOLVED = frozenset(FORMS["switching state"] + FORMS["voltage reference"])
#: a command row's pulse delays and duties (phases a, b, c)
_DELAYS = slice(COMMAND_INDEX.delay_a, COMMAND_INDEX.delay_c + 1)
_DUTIES = slice(COMMAND_INDEX.duty_a, COMMAND_INDEX.duty_c + 1)
#: the encapsulation header: XCDR1, little endian
HEADER = b"\x00\x01\x00\x00"
T = TypeVar("T")


class CdrWriter:
    """CDR writer; alignment is relative to the byte after the encapsulation header."""

    __slots__ = ("buf",)

    def __init__(self) -> None:
        self.buf = bytearray(HEADER)

    def align(self, n: int) -> None:
        pad = (-(len(self.buf) - 4)) % n
        if pad:
            self.buf += b"\x00" * pad

    def u8(self, v: int) -> None:
        self.buf += struct.pack("<B", v)

    def i32(self, v: int) -> None:
        self.align(4)
        self.buf += struct.pack("<i", v)

    def u32(self, v: int) -> None:
        self.align(4)
        self.buf += struct.pack("<I", v)

    def i64(self, v: int) -> None:
        self.align(8)
        self.buf += struct.pack("<q", v)

    def f64(self, v: float) -> None:
        self.align(8)
        self.buf += struct.pack("<d", v)

    def string(self, s: str) -> None:
        b = s.encode()
        self.u32(len(b) + 1)
        self.buf += b + b"\x00"

    def f64_seq(self, values: tuple[float, ...] | list[float]) -> None:
        self.u32(len(values))
        if values:
            self.align(8)
            self.buf += struct.pack(f"<{len(values)}d", *values)

    def time(self, t: float) -> None:
        """builtin_interfaces/Time of ``t`` s."""
        sec, nsec = stamp(t)
        self.i32(sec)
        self.u32(nsec)

    def bytes(self) -> bytes:
        return bytes(self.buf)


class CdrReader:
    """CDR reader of one message; ``struct.error`` or ``UnicodeDecodeError`` when the bytes end
    early or are not what is read (the decoders turn them into :class:`BagError`)."""

    __slots__ = ("data", "off")

    def __init__(self, data: bytes | memoryview) -> None:
        self.data = data
        self.off = len(HEADER)

    def align(self, n: int) -> None:
        self.off += (-(self.off - 4)) % n

    def _unpack(self, code: str, size: int) -> int | float:
        self.align(size)
        values: tuple[int | float, ...] = struct.unpack_from("<" + code, self.data, self.off)
        self.off += size
        return values[0]

    def u8(self) -> int:
        return int(self._unpack("B", 1))

    def i32(self) -> int:
        return int(self._unpack("i", 4))

    def u32(self) -> int:
        return int(self._unpack("I", 4))

    def i64(self) -> int:
        return int(self._unpack("q", 8))

    def f64(self) -> float:
        return float(self._unpack("d", 8))

    def string(self) -> str:
        n = self.u32()
        s = bytes(self.data[self.off : self.off + n - 1]).decode()
        self.off += n
        return s

    def f64_array(self, count: int) -> tuple[float, ...]:
        if not count:
            return ()
        self.align(8)
        values: tuple[float, ...] = struct.unpack_from(f"<{count}d", self.data, self.off)
        self.off += 8 * count
        return values

    def seq(self, read: Callable[[], T]) -> tuple[T, ...]:
        return tuple(read() for _ in range(self.u32()))

    def time_ns(self) -> int:
        sec = self.i32()
        return sec * 1_000_000_000 + self.u32()


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


# --- std_msgs/Float64MultiArray ---------------------------------------------------------------


class MultiArrayCodec:
    """Float64MultiArray with a fixed label: the header is built once, each message is one pack."""

    def __init__(self, fields: tuple[str, ...]) -> None:
        self.fields = fields
        w = CdrWriter()
        w.u32(1)  # one dimension
        w.string(",".join(fields))
        w.u32(len(fields))  # size
        w.u32(len(fields))  # stride
        w.u32(0)  # data_offset
        w.u32(len(fields))  # data length
        w.align(8)
        self.prefix = w.bytes()
        self._fmt = struct.Struct(f"<{len(fields)}d")
        self.size = len(self.prefix) + self._fmt.size
        self._prefix_u8 = np.frombuffer(self.prefix, dtype=np.uint8)
        #: the last message decoded and its values: composed, every local subscriber of a topic
        #: is handed the same bytes object, and decodes it once
        self._last: tuple[bytes, tuple[float, ...]] = (b"", ())

    def encode(self, values: tuple[float, ...]) -> bytes:
        return self.prefix + self._fmt.pack(*values)

    def exact(self, data: bytes) -> tuple[float, ...] | None:
        """Values of a message of exactly this layout (the fast path), else None."""
        last = self._last
        if data is last[0]:
            return last[1]
        if len(data) == self.size and data.startswith(self.prefix):
            values: tuple[float, ...] = self._fmt.unpack_from(data, len(self.prefix))
            self._last = (data, values)
            return values
        return None

    def exact_rows(self, raw: np.ndarray) -> np.ndarray | None:
        """Values of messages given as the rows of an (n, :attr:`size`) uint8 array, in one
        numpy view, when every one has exactly this layout (else None)."""
        head = len(self.prefix)
        if raw.shape[1:] != (self.size,) or not (raw[:, :head] == self._prefix_u8).all():
            return None
        return raw[:, head:].copy().view("<f8")

    def decode_rows(self, payloads: list[bytes]) -> np.ndarray:
        """Values of messages as (n, fields) rows: in one numpy call when every one has
        exactly this layout, else message by message (:meth:`decode`)."""
        if not payloads:
            return np.empty((0, len(self.fields)))
        joined = b"".join(payloads)
        if len(joined) == self.size * len(payloads):
            raw = np.frombuffer(joined, dtype=np.uint8).reshape(len(payloads), self.size)
            rows = self.exact_rows(raw)
            if rows is not None:
                return rows
        return np.array([self.decode(data) for data in payloads], dtype=np.float64)

    def decode(self, data: bytes) -> tuple[float, ...]:
        """Values of a message in this layout's field order. A message of exactly this layout
        takes the fast path; another labelled layout (a recording of another version) is read
        by field name, NaN for fields it lacks; BagError if it lacks the step or time."""
        fast = self.exact(data)
        if fast is not None:
            return fast
        labels, values = decode_multiarray(data)
        by_name = dict(zip(labels, values))
        if len(labels) != len(values) or not {"k", "t"} <= set(by_name):
            raise BagError(
                f"Float64MultiArray layout mismatch: expected labels {','.join(self.fields)}, got "
                f"{','.join(labels)} with {len(values)} values"
            )
        return tuple(by_name.get(f, math.nan) for f in self.fields)


#: the codec of every labelled record topic, by topic key
CODECS: dict[str, MultiArrayCodec] = {
    key: MultiArrayCodec(TOPICS[key].fields)
    for key in (*RECORD_TOPICS, LOSSES_TOPIC, "recorded", "metrics")
}


def decode_command(data: bytes, u_dc: Callable[[], float]) -> tuple[float, ...]:
    """A /drive/command message as a :class:`~.core.signals.Command` row, its switching as the
    plant applies it: the built-in layout as it is; a controller's own (a switching state or a
    voltage reference, modulated from ``u_dc()`` V) resolved to pulses
    (:func:`~.core.commands.command_from`); one the plant would refuse (or of an older layout)
    by field name, NaN for what it lacks."""
    codec = CODECS["command"]
    fast = codec.exact(data)
    if fast is not None:
        return fast
    try:
        fields = labelled(data)
        if not set(fields).isdisjoint(RESOLVED):
            voltage = "u_alpha" in fields or "u_beta" in fields
            return tuple(command_from(fields, u_dc=u_dc() if voltage else math.nan))
    except (CommandError, BagError):
        pass
    return codec.decode(data)


def command_for_step(data: bytes, *, k: int, t: float, u_dc: Callable[[], float]) -> Command:
    """A /drive/command message as the plant applies it at step ``k`` (its state at ``t`` s):
    the built-in layout as it is, a controller's own form resolved to pulses (a voltage
    reference modulated from ``u_dc()`` V). CommandError, naming the field and the step, for
    what the plant refuses (docs/ros.md#writing-your-own-controller): a message that is no
    labelled array, an unknown or missing field, a pulse outside the period, a switching state
    other than 0/1, a voltage that is not finite, the command of another step or of another
    time than its state's."""
    values = CODECS["command"].exact(data)
    if values is not None and _pulses_fit(values):
        cmd = Command(*values)
    else:
        try:
            fields = labelled(data)
        except BagError as e:
            raise CommandError(f"step {k}: {e}", k=k) from None
        voltage = "u_alpha" in fields or "u_beta" in fields
        cmd = command_from(fields, u_dc=u_dc() if voltage else math.nan)
    for name, wrong, shown, why in (
        ("k", cmd.k != k, f"{cmd.k:g}",
         f"the command for another step (the plant waits for step {k})"),
        ("t", cmd.t != t, repr(float(cmd.t)),  # a number as a number, not np.float64(...)
         f"a command carries the time of the state it answers (state {k}: t = {float(t)!r} s)"),
    ):  # fmt: skip
        if wrong:
            raise CommandError(f"step {k}: field {name!r} = {shown}: {why}", field=name, k=cmd.k)
    return cmd


def _pulses_fit(values: tuple[float, ...]) -> bool:
    """The pulses of a command in the built-in layout lie in the period (the fast path's check;
    :func:`~.core.commands.command_from` says what is wrong with one that does not)."""
    delay, duty = values[_DELAYS], values[_DUTIES]
    return (
        math.isfinite(sum(delay) + sum(duty))
        and min(delay) >= 0.0
        and min(duty) >= 0.0
        and max(d + w for d, w in zip(delay, duty)) <= 1.0 + PULSE_SLACK
    )


def labelled(data: bytes) -> dict[str, float]:
    """A labelled Float64MultiArray (one label per value) → its values by label; BagError names
    what does not fit."""
    labels, values = decode_multiarray(data)
    if len(labels) != len(values) or len(set(labels)) != len(labels):
        raise BagError(
            f"Float64MultiArray layout: {len(values)} values under the labels "
            f"{','.join(labels)!r} (expected one distinct label per value)"
        )
    return dict(zip(labels, values))


def decode_multiarray(data: bytes) -> tuple[tuple[str, ...], tuple[float, ...]]:
    """Any Float64MultiArray → (labels of dim[0] split at commas, data)."""
    r = CdrReader(data)
    try:
        labels: list[str] = []
        for _ in range(r.u32()):
            labels.append(r.string())
            r.u32()  # size
            r.u32()  # stride
        r.u32()  # data_offset
        values = r.f64_array(r.u32())
    except (struct.error, UnicodeDecodeError) as e:
        raise BagError(f"not a Float64MultiArray: {e}") from None
    split = tuple(labels[0].split(",")) if labels else ()
    return split, values


# --- the tool topics ---------------------------------------------------------------------------


#: rosgraph_msgs/Clock: the encapsulation header, then builtin_interfaces/Time
_CLOCK = struct.Struct("<4siI")


def encode_clock(t: float) -> bytes:
    """rosgraph_msgs/Clock at ``t`` s."""
    return _CLOCK.pack(HEADER, *stamp(t))


JOINT_NAME = "drive_shaft"
#: sensor_msgs/JointState of one joint, laid out once (CDR: the header's stamp, frame_id "",
#: one name, then position, velocity and effort each a sequence of one float64 aligned to 8):
#: a message is one pack. test_codec holds it to what CdrWriter writes field by field.
_JOINT = struct.Struct("<4siI" + "I1s3x" + "II12s" + "Id" + "I4xd" + "I4xd")
_JOINT_NAME = JOINT_NAME.encode() + b"\x00"


def encode_joint_state(t: float, position: float, velocity: float, effort: float) -> bytes:
    """sensor_msgs/JointState for the shaft: angle (rad), speed (rad/s), electromagnetic torque (N·m)."""
    sec, nsec = stamp(t)
    return _JOINT.pack(
        HEADER,
        sec,
        nsec,
        1,
        b"",
        1,
        len(_JOINT_NAME),
        _JOINT_NAME,
        1,
        position,
        1,
        velocity,
        1,
        effort,
    )


#: diagnostic_msgs/DiagnosticStatus levels
OK, WARN, ERROR = 0, 1, 2
LEVEL_NAMES = {OK: "OK", WARN: "WARN", ERROR: "ERROR"}


def encode_diagnostics(
    t: float, statuses: list[tuple[int, str, str, list[tuple[str, str]]]]
) -> bytes:
    """DiagnosticArray of (level, name, message, [(key, value), ...]); hardware_id = 'predictive_drive'."""
    w = CdrWriter()
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
    return w.bytes()


def diagnostics_value(v: float) -> str:
    """A diagnostics value: repr of the float (round-trips exactly), 'nan' where undefined."""
    return "nan" if math.isnan(v) else repr(float(v))


# --- rcl_interfaces/ParameterEvent --------------------------------------------------------------

#: rcl_interfaces/msg/ParameterType of the scalar values this package sets
_PARAMETER_TYPES = {bool: 1, int: 2, float: 3, str: 4}


def encode_parameter_event(t: float, node: str, changed: list[tuple[str, object]]) -> bytes:
    """rcl_interfaces/ParameterEvent: ``node``'s parameters ``changed`` at ``t`` (bool, int,
    float or str values), as rclpy publishes it after an accepted set."""
    w = CdrWriter()
    w.time(t)
    w.string(node)
    w.u32(0)  # new_parameters
    w.u32(len(changed))
    for name, value in changed:
        kind = _PARAMETER_TYPES[type(value)]
        w.string(name)
        w.u8(kind)
        w.u8(bool(value) if kind == 1 else 0)
        w.i64(value if kind == 2 and isinstance(value, int) else 0)
        w.f64(value if kind == 3 and isinstance(value, float) else 0.0)
        w.string(str(value) if kind == 4 else "")
        for _ in range(5):  # byte, bool, integer, double and string arrays: empty
            w.u32(0)
    w.u32(0)  # deleted_parameters
    return w.bytes()


@dataclass(frozen=True)
class ParameterEvent:
    stamp_ns: int
    node: str
    new: tuple[tuple[str, object], ...]  #: (name, value) of parameters declared
    changed: tuple[tuple[str, object], ...]  #: (name, value) of parameters set


def _parameter(r: CdrReader) -> tuple[str, object]:
    """One rcl_interfaces/Parameter: its name and the value of its type (arrays as tuples)."""
    name = r.string()
    kind = r.u8()
    values: list[object] = [
        bool(r.u8()),
        r.i64(),
        r.f64(),
        r.string(),
        r.seq(r.u8),
        r.seq(lambda: bool(r.u8())),
        r.seq(r.i64),
        r.seq(r.f64),
        r.seq(r.string),
    ]
    return name, (values[kind - 1] if 1 <= kind <= 9 else None)


def decode_parameter_event(data: bytes) -> ParameterEvent:
    """The node and the new and changed (name, value) pairs of a ParameterEvent (deleted
    parameters are not read). BagError if the bytes are not one."""
    r = CdrReader(data)
    try:
        stamp_ = r.time_ns()
        node = r.string()
        new = r.seq(lambda: _parameter(r))
        changed = r.seq(lambda: _parameter(r))
    except (struct.error, UnicodeDecodeError) as e:
        raise BagError(f"not a ParameterEvent: {e}") from None
    return ParameterEvent(stamp_, node, new, changed)
