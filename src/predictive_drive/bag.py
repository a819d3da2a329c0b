"""Recordings in rosbag2's MCAP layout, written and read without ROS.

A bag is a directory ``<run>/`` holding ``<run>_0.mcap`` and ``metadata.yaml`` (rosbag2 version 9).
The MCAP file uses profile ``ros2``, ``ros2msg`` schemas with full definitions, ``cdr`` messages,
channel metadata ``offered_qos_profiles`` and ``topic_type_hash``, a ``rosbag2`` metadata record, and a
``predictive_drive`` metadata record with the scenario file, strategy names, engine and version.
Chunks are small and flushed as they fill, so a file cut short by a crash still yields every complete
chunk; :func:`read_bag` falls back to a streaming read for such files.
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import yaml
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from . import __version__
from .core.signals import STATE_INDEX
from .core.trace import RECORDS, Trace, TraceBuilder
from .errors import BagError
from .interface import CODECS, RECORD_TOPICS, TOPICS, message_definition, type_hash

__all__ = ["BagInfo", "BagWriter", "read_bag"]

CHUNK_SIZE = 256 * 1024
META_NAME = "predictive_drive"
K = STATE_INDEX.k  #: the step index: the first field of every per-step record


def _qos_yaml(topic_key: str) -> str:
    return yaml.safe_dump([TOPICS[topic_key].qos.rosbag2()], sort_keys=False).strip()


class BagWriter:
    """Write one run. Use as a context manager: the bag is closed (index, footer, metadata.yaml)
    however the block ends, so Ctrl-C or an error leaves a complete, readable bag."""

    def __init__(self, directory: str | Path, *, info: dict[str, Any]) -> None:
        self.directory = Path(directory)
        if self.directory.exists():
            raise BagError(f"bag directory {self.directory} already exists; choose another --out")
        self.directory.mkdir(parents=True)
        self.path = self.directory / f"{self.directory.name}_0.mcap"
        self._file = self.path.open("wb")
        self._writer = Writer(self._file, chunk_size=CHUNK_SIZE, compression=CompressionType.ZSTD)
        self._writer.start(profile="ros2", library=f"predictive_drive {__version__}")
        self._channels: dict[str, int] = {}
        self._counts: dict[str, int] = {}
        self._first = None
        self._last = 0
        self._closed = False
        for key, topic in TOPICS.items():
            schema = self._writer.register_schema(
                topic.type, "ros2msg", message_definition(topic.type).encode()
            )
            self._channels[key] = self._writer.register_channel(
                topic.name,
                "cdr",
                schema,
                {"offered_qos_profiles": _qos_yaml(key), "topic_type_hash": type_hash(topic.type)},
            )
            self._counts[key] = 0
        info = {**info, "package_version": __version__, "created_unix_s": f"{time.time():.3f}"}
        self._writer.add_metadata(
            META_NAME, {k: v if isinstance(v, str) else json.dumps(v) for k, v in info.items()}
        )
        self._file.flush()  # a file cut short still says what it is
        self._write_metadata_yaml()  # provisional, rewritten on close
        self._seq = 0

    def write(self, topic_key: str, t_ns: int, data: bytes) -> None:
        """One serialized message; ``t_ns`` (simulated time) is both log and publish time."""
        self._writer.add_message(self._channels[topic_key], t_ns, data, t_ns, self._seq)
        self._seq += 1
        self._counts[topic_key] += 1
        if self._first is None:
            self._first = t_ns
        if t_ns > self._last:
            self._last = t_ns

    def close(self) -> None:
        if self._closed:
            return
        self._closed = True
        self._writer.add_metadata(
            "rosbag2",
            {
                "serialized_metadata": yaml.safe_dump(
                    self._metadata()["rosbag2_bagfile_information"], sort_keys=False
                ),
                "ROS_DISTRO": "jazzy",
            },
        )
        self._writer.finish()
        self._file.close()
        self._write_metadata_yaml()

    @property
    def message_count(self) -> int:
        return sum(self._counts.values())

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _metadata(self) -> dict[str, Any]:
        start = self._first or 0
        duration = max(0, self._last - start)
        count = self.message_count
        return {
            "rosbag2_bagfile_information": {
                "version": 9,
                "storage_identifier": "mcap",
                "duration": {"nanoseconds": duration},
                "starting_time": {"nanoseconds_since_epoch": start},
                "message_count": count,
                "topics_with_message_count": [
                    {
                        "topic_metadata": {
                            "name": t.name,
                            "type": t.type,
                            "serialization_format": "cdr",
                            "offered_qos_profiles": [t.qos.rosbag2()],
                            "type_description_hash": type_hash(t.type),
                        },
                        "message_count": self._counts[key],
                    }
                    for key, t in TOPICS.items()
                ],
                "compression_format": "",
                "compression_mode": "",
                "relative_file_paths": [self.path.name],
                "files": [
                    {
                        "path": self.path.name,
                        "starting_time": {"nanoseconds_since_epoch": start},
                        "duration": {"nanoseconds": duration},
                        "message_count": count,
                    }
                ],
                "custom_data": None,
                "ros_distro": "jazzy",
            }
        }

    def _write_metadata_yaml(self) -> None:
        tmp = self.directory / "metadata.yaml.tmp"
        tmp.write_text(yaml.safe_dump(self._metadata(), sort_keys=False))
        tmp.replace(self.directory / "metadata.yaml")


@dataclass
class BagInfo:
    path: Path
    info: dict[str, str]
    counts: dict[str, int]
    complete: bool  #: False if the file had to be read as a truncated stream


def mcap_file(bag: str | Path) -> Path:
    p = Path(bag)
    if p.is_dir():
        files = sorted(p.glob("*.mcap"))
        if not files:
            raise BagError(f"{p}: no .mcap file in this bag directory")
        return files[0]
    if not p.is_file():
        raise BagError(f"{p}: no such bag directory or .mcap file")
    return p


def _iter_records(
    path: Path,
) -> tuple[list[tuple[Channel, Message]], dict[str, dict[str, str]], bool]:
    """(channel, message) pairs and metadata records; tolerant of a file cut short."""
    msgs: list[tuple[Channel, Message]] = []
    meta: dict[str, dict[str, str]] = {}
    try:
        with path.open("rb") as f:
            reader = make_reader(f)
            for m in reader.iter_metadata():
                meta[m.name] = dict(m.metadata)
            for _schema, channel, message in reader.iter_messages(log_time_order=False):
                msgs.append((channel, message))
        return msgs, meta, True
    except (McapError, EOFError, ValueError, KeyError, AssertionError, OSError):
        pass
    msgs, meta = [], {}
    channels: dict[int, Channel] = {}
    with path.open("rb") as f:
        try:
            for rec in StreamReader(f, skip_magic=False).records:
                if isinstance(rec, Channel):
                    channels[rec.id] = rec
                elif isinstance(rec, Message) and rec.channel_id in channels:
                    msgs.append((channels[rec.channel_id], rec))
                elif isinstance(rec, Metadata):
                    meta[rec.name] = dict(rec.metadata)
                elif isinstance(rec, Schema):
                    pass
        except Exception:  # noqa: BLE001 — a truncated tail ends the stream; keep what came before
            pass
    return msgs, meta, False


def read_bag(bag: str | Path) -> tuple[Trace, BagInfo]:
    """Decode the per-step topics of a recording into a :class:`Trace` (complete steps only)."""
    path = mcap_file(bag)
    msgs, meta, complete = _iter_records(path)
    if META_NAME not in meta:
        raise BagError(f"{path}: not a predictive_drive recording (no '{META_NAME}' metadata)")
    info = meta[META_NAME]
    by_name = {TOPICS[key].name: rec for rec, key in RECORD_TOPICS.items()}
    rows: dict[str, dict[int, tuple[float, ...]]] = {rec: {} for rec in RECORDS}
    counts: dict[str, int] = {}
    for channel, message in msgs:
        counts[channel.topic] = counts.get(channel.topic, 0) + 1
        rec = by_name.get(channel.topic)
        if rec is None:
            continue
        values = CODECS[RECORD_TOPICS[rec]].decode(message.data)
        rows[rec][int(values[K])] = values
    ts = float(info["ts"])
    builder = TraceBuilder(ts, tuple(json.loads(info["strategy_names"])))
    # keep the longest prefix of whole steps: states and references 0..n, commands 0..n-1
    n = 0
    while (
        n in rows["command"]
        and n + 1 in rows["state"]
        and n + 1 in rows["reference"]
        and n in rows["state"]
        and n in rows["reference"]
    ):
        n += 1
    if n == 0:
        raise BagError(f"{path}: the recording holds no complete step")
    for k in range(n + 1):
        builder.add("state", rows["state"][k])
        builder.add("reference", rows["reference"][k])
    for k in range(n):
        builder.add("command", rows["command"][k])
    return builder.build(), BagInfo(path, info, counts, complete)
