"""rosbag2's MCAP bags, written and read without ROS: the file layer (what a recording *means* is
:mod:`predictive_drive.recording`'s and :mod:`predictive_drive.readback`'s).

A bag is a directory ``<run>/`` holding ``<run>_0.mcap`` and ``metadata.yaml`` (rosbag2 version 9).
The MCAP file uses profile ``ros2``, ``ros2msg`` schemas with full definitions, ``cdr`` messages,
channel metadata ``offered_qos_profiles`` and ``topic_type_hash``, a ``rosbag2`` metadata record, and a
``predictive_drive`` metadata record with the scenario file, strategy names, engine and version.
Chunks are small and flushed as they fill, so a file cut short by a crash still yields every complete
chunk; :func:`read_records` falls back to a streaming read for such files. The file is written by
:class:`~predictive_drive.mcapio.ChunkWriter` (byte for byte what the ``mcap`` library writes,
several times faster); the library reads it back where speed does not matter (repair, replay).
"""

from __future__ import annotations

import fcntl
import functools
import json
import os
import shutil
import time
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np
import yaml
from mcap.exceptions import McapError
from mcap.reader import make_reader
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader

from . import __version__, interrupts
from .errors import BagError
from .interface import BAG_TOPICS, TOPICS, bag_topics
from .mcapio import MAGIC, ChunkWriter, MessageGroup
from .outputs import unwritable
from .schemas import message_definition, type_hash

__all__ = [
    "CLAIM",
    "LOGS_DIR",
    "META_NAME",
    "BagWriter",
    "Held",
    "RecordedTopic",
    "RepairResult",
    "check_new_bag",
    "first_log_time",
    "claim_bag_dir",
    "iter_messages",
    "load_yaml",
    "mcap_file",
    "not_a_recording",
    "read_records",
    "recorded_topics",
    "repair_bag",
]

#: a chunk is sealed when it holds this many bytes, then compressed with zstd at ZSTD_LEVEL and
#: written (and flushed to the OS) by the writer's own thread while the next one fills: the mcap
#: C++ writer's defaults, which rosbag2's MCAP plugin records with (768 KiB, its "default" zstd
#: level, 1). A run killed outright loses what had not reached the file: the chunk it was
#: filling, the one in flight and the steps not yet handed to the recorder (in-process
#: core.runner.SINK_BATCH, in a node the logger's TAKE_BATCH); ~3,000 steps of a 20 kHz run at
#: most (0.15 s simulated; ~620 bytes a step)
CHUNK_SIZE = 768 * 1024
ZSTD_LEVEL = 1
META_NAME = "predictive_drive"
#: a bag directory may hold this folder besides the recording: the node logs of the run
LOGS_DIR = "logs"
#: the file by which a run claims its bag directory for as long as it runs (flock'ed: the kernel
#: releases the claim of a run that was killed); removed when the run ends
CLAIM = ".claim"


class _FlushingFile:
    """A file the MCAP writer writes through, flushed after every write: the writer only writes
    when it finishes a chunk (and at the start and end), so this costs one system call per chunk
    and leaves nothing in a userspace buffer for a kill to lose. (An unbuffered file would not
    do: the writer wraps a raw file in a buffer of its own and never flushes it.)"""

    def __init__(self, path: Path) -> None:
        self._f = path.open("wb")

    def write(self, data: bytes | bytearray | memoryview) -> int:
        n = self._f.write(data)
        self._f.flush()
        return n

    def tell(self) -> int:
        return self._f.tell()

    def flush(self) -> None:
        self._f.flush()

    def close(self) -> None:
        self._f.close()


def check_new_bag(directory: str | Path, *, claimed: bool = False) -> Path:
    """The directory a new bag goes to, checked before anything runs: it must not exist, or be an
    empty folder (but for :data:`LOGS_DIR`), no other run may have claimed it (see
    :func:`claim_bag_dir`; ``claimed``: this run holds the claim), and its parent must be a
    writable folder. BagError names the path and what is wrong."""
    d = Path(directory)
    if d.exists():
        if not d.is_dir():
            raise BagError(f"--out {d}: a file of that name exists; choose another --out")
        if not claimed and (owner := _claimant(d)) is not None:
            raise BagError(
                f"--out {d}: another run (pid {owner}) is writing its bag there; choose another "
                f"--out"
            )
        others = sorted(p.name for p in d.iterdir() if p.name not in (LOGS_DIR, CLAIM))
        if others:
            what = (
                "a bag"
                if any(n.endswith(".mcap") or n == "metadata.yaml" for n in others)
                else "a folder"
            )
            raise BagError(
                f"--out {d}: {what} of that name exists ({', '.join(others[:3])}"
                f"{', ...' if len(others) > 3 else ''}); choose another --out"
            )
    why = unwritable(d)
    if why is not None:
        raise BagError(f"--out {d}: cannot create it: {why}")
    return d


def _claimant(d: Path) -> int | None:
    """The PID of the run holding ``d``'s claim, or None when nobody holds it."""
    try:
        fd = os.open(d / CLAIM, os.O_RDONLY)
    except OSError:
        return None
    try:
        fcntl.flock(fd, fcntl.LOCK_SH | fcntl.LOCK_NB)
    except OSError:
        # held: the holder writes its PID right after it takes the lock
        for _ in range(100):
            text = os.pread(fd, 32, 0).decode(errors="replace").strip()
            if text.isdigit():
                return int(text)
            time.sleep(0.01)
        return -1
    finally:
        os.close(fd)  # closing releases a shared lock taken just to look
    return None


@contextmanager
def claim_bag_dir(directory: str | Path) -> Iterator[Path]:
    """Claim ``directory`` for a new bag, atomically, for the whole run: checked as
    :func:`check_new_bag` does, made, and locked (``<dir>/.claim``, with this process's PID). A
    second run given the same directory is refused before it starts anything, and touches
    nothing. The claim ends with the block (or with the process)."""
    d = check_new_bag(directory)
    try:
        d.mkdir(parents=True, exist_ok=True)
        fd = os.open(d / CLAIM, os.O_RDWR | os.O_CREAT, 0o644)
    except OSError as e:
        raise BagError(f"--out {d}: cannot create it: {e.strerror}") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        os.close(fd)
        owner = _claimant(d)
        who = f"another run (pid {owner})" if owner and owner > 0 else "another run"
        raise BagError(f"--out {d}: {who} is writing its bag there; choose another --out") from None
    try:
        check_new_bag(d, claimed=True)  # a run that ended meanwhile left its bag there
        os.ftruncate(fd, 0)
        os.pwrite(fd, f"{os.getpid()}\n".encode(), 0)
        yield d
    finally:
        try:
            (d / CLAIM).unlink()
        except OSError:
            pass
        os.close(fd)


#: libyaml's safe loader where PyYAML has it (ten times faster than the pure-Python one)
_YAML_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def load_yaml(text: str) -> Any:
    """``yaml.safe_load``, with libyaml when there is one."""
    return yaml.load(text, Loader=_YAML_LOADER)  # noqa: S506 — a safe loader


_YAML_DUMPER = getattr(yaml, "CSafeDumper", yaml.SafeDumper)


def dump_yaml(doc: Any) -> str:
    """``yaml.safe_dump`` in document order, with libyaml when there is one, long strings on
    one line (how the two emitters fold them differs)."""
    return str(yaml.dump(doc, Dumper=_YAML_DUMPER, sort_keys=False, width=1 << 16))


@functools.cache
def _qos_yaml(topic_key: str) -> str:
    return yaml.safe_dump([TOPICS[topic_key].qos.rosbag2()], sort_keys=False).strip()


class Held(NamedTuple):
    """Messages held for log-time order (:meth:`BagWriter.hold_block`, :meth:`BagWriter.ready`):
    their log times (int64 ns), MCAP channel ids and serialized data, one entry each."""

    times: np.ndarray
    channels: np.ndarray
    data: list[bytes]


_NOTHING_HELD = Held(np.empty(0, dtype=np.int64), np.empty(0, dtype=np.int64), [])


class BagWriter:
    """Write one run. Use as a context manager: the bag is closed (index, footer, metadata.yaml)
    however the block ends, so Ctrl-C or an error leaves a complete, readable bag."""

    def __init__(
        self,
        directory: str | Path,
        *,
        info: dict[str, Any],
        stamp: bool = True,
        claimed: bool = False,
        losses: bool = False,
    ) -> None:
        """``info``: the ``predictive_drive`` metadata record; ``stamp`` adds the package version
        and the creation time (a repaired bag keeps the original's instead); ``claimed``: the
        run this bag is written for holds the directory's claim (:func:`claim_bag_dir`);
        ``losses``: the run books its losses, and the bag has /drive/losses (else no such
        channel)."""
        self._topics = bag_topics(losses=losses)
        self.directory = check_new_bag(directory, claimed=claimed)
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            self.path = self.directory / f"{self.directory.name}_0.mcap"
            # each record reaches the OS as it is written, so a killed writer loses at most the
            # chunk it was filling (see CHUNK_SIZE)
            self._file = _FlushingFile(self.path)
        except OSError as e:
            raise BagError(f"cannot write the bag {self.directory}: {e.strerror}") from None
        self._writer = ChunkWriter(
            self._file, chunk_size=CHUNK_SIZE, level=ZSTD_LEVEL, background=True
        )
        try:
            self._start(info, stamp)
        except BaseException as e:
            self._writer.close()  # its thread, and Python's switch interval
            self._file.close()
            if isinstance(e, OSError):
                raise BagError(
                    f"cannot write the bag {self.directory}: {e.strerror or e}"
                ) from None
            raise

    def _start(self, info: dict[str, Any], stamp: bool) -> None:
        """The header, schemas, channels, this package's metadata and a provisional
        metadata.yaml."""
        self._writer.start(profile="ros2", library=f"predictive_drive {__version__}")
        self._channels: dict[str, int] = {}
        #: messages held for log-time order (see hold), in the order they came: blocks of
        #: (log times, channels, data), then the ones held one at a time since the last block
        self._held: list[Held] = []
        self._loose: tuple[list[int], list[int], list[bytes]] = ([], [], [])
        self._closed = False
        self._failed = ""
        #: rosbag2's custom_data: written into metadata.yaml and the rosbag2 record on close
        self.custom_data: dict[str, str] = {}
        schemas: dict[str, int] = {}  # one schema per type, as rosbag2 writes it
        for key, topic in self._topics.items():
            if topic.type not in schemas:
                schemas[topic.type] = self._writer.register_schema(
                    topic.type, "ros2msg", message_definition(topic.type).encode()
                )
            self._channels[key] = self._writer.register_channel(
                topic.name,
                "cdr",
                schemas[topic.type],
                {"offered_qos_profiles": _qos_yaml(key), "topic_type_hash": type_hash(topic.type)},
            )
        if stamp:
            info = {**info, "package_version": __version__, "created_unix_s": f"{time.time():.3f}"}
        self._writer.add_metadata(
            META_NAME, {k: v if isinstance(v, str) else json.dumps(v) for k, v in info.items()}
        )
        self._file.flush()  # a file cut short still says what it is
        self._write_metadata_yaml()  # provisional, rewritten on close

    def write(self, topic_key: str, t_ns: int, data: bytes) -> None:
        """One serialized message, written now; ``t_ns`` (simulated time) is both log and
        publish time. BagError when the file cannot take it (a full disk): the bag is then
        incomplete. Messages written in log-time order make a file readers need not sort; a
        writer that receives them out of order uses :meth:`hold` and :meth:`release`."""
        self.write_on(self._channels[topic_key], t_ns, data)

    def write_on(self, channel: int, t_ns: int, data: bytes) -> None:
        """:meth:`write` by MCAP channel id (see :meth:`channel`)."""
        try:
            self._writer.add(channel, t_ns, data)
        except OSError as e:
            raise self.write_failed(e) from None

    def group(self, parts: Sequence[tuple[str, bytes, int]], extras_after: int = 0) -> MessageGroup:
        """Messages written together (:class:`~.mcapio.MessageGroup`): (topic key, payload
        prefix, bytes after it) each, other messages after part ``extras_after``. Its
        ``add_steps`` raises OSError: pass it to :meth:`write_failed`."""
        return self._writer.group(
            [(self._channels[key], p, n) for key, p, n in parts], extras_after
        )

    def channel(self, topic_key: str) -> int:
        """The MCAP channel id of a topic (for :meth:`~.mcapio.MessageGroup.add_steps`' extra
        messages)."""
        return self._channels[topic_key]

    def write_failed(self, e: OSError) -> BagError:
        """The error to raise for a write that failed (the bag takes nothing more)."""
        self._failed = f"{e.strerror or e}"
        return BagError(
            f"writing the bag {self.directory} failed ({self._failed}); it holds what was "
            f"written before, up to its last complete chunk"
        )

    def hold(self, topic_key: str, t_ns: int, data: bytes) -> None:
        """One message to be written in log-time order once :meth:`release` passes its time
        (messages of equal time keep their arrival order); :meth:`close` writes what is held."""
        times, channels, held = self._loose
        times.append(t_ns)
        channels.append(self._channels[topic_key])
        held.append(data)

    def hold_block(self, block: Held) -> None:
        """Messages to hold (see :meth:`hold`), in the order they came: their log times,
        channel ids and data."""
        self._gather()
        if len(block.times):
            self._held.append(block)

    def _gather(self) -> None:
        """The messages held one at a time since the last block, as a block."""
        times, channels, data = self._loose
        if times:
            self._held.append(
                Held(np.array(times, dtype=np.int64), np.array(channels, dtype=np.int64), data)
            )
            self._loose = ([], [], [])

    def release(self, through_ns: int) -> None:
        """Write the held messages logged at or before ``through_ns``, in (log time, arrival)
        order: the caller knows that no message of an earlier time is still to come."""
        ready = self.ready(through_ns)
        write = self.write_on
        for t_ns, channel, data in zip(ready.times.tolist(), ready.channels.tolist(), ready.data):
            write(channel, t_ns, data)

    def ready(self, through_ns: int) -> Held:
        """Take the held messages logged at or before ``through_ns`` out, in (log time,
        arrival) order: the caller writes them, in that order (what :meth:`release` does)."""
        self._gather()
        if not self._held:
            return _NOTHING_HELD
        if len(self._held) == 1:
            times, channels, data = self._held[0]
        else:
            times = np.concatenate([b.times for b in self._held])
            channels = np.concatenate([b.channels for b in self._held])
            data = [d for b in self._held for d in b.data]
        if len(times) > 1 and not bool((times[1:] >= times[:-1]).all()):
            order = np.argsort(times, kind="stable")  # equal times keep their arrival order
            times, channels = times[order], channels[order]
            data = [data[i] for i in order.tolist()]
        n = int(np.searchsorted(times, through_ns, side="right"))
        rest = Held(times[n:], channels[n:], data[n:])
        self._held = [rest] if len(rest.times) else []
        return Held(times[:n], channels[:n], data[:n])

    @property
    def last_ns(self) -> int:
        """The latest log time written so far (0 before the first message)."""
        return self._writer.last_time

    @property
    def held(self) -> int:
        """Messages held for :meth:`release`."""
        return sum(len(b.times) for b in self._held) + len(self._loose[0])

    def close(self) -> None:
        """Index, footer and metadata.yaml; BagError if they cannot be written (the file then
        reads as a cut recording, which ``predictive-drive repair`` rebuilds). A Ctrl-C of the
        command line meanwhile is raised once the bag is closed (see :mod:`.interrupts`)."""
        with interrupts.held():
            self._close()

    def _close(self) -> None:
        if self._closed:
            return
        self._closed = True
        try:
            if not self._failed:
                self.release(2**63)  # what is held: nothing more will come
            self._finish()
        except OSError as e:
            self._writer.close()
            try:
                self._file.close()
            except OSError:
                pass  # what could not be written stays unwritten
            if self._failed:  # the first failure is the one to tell
                raise BagError(
                    f"writing the bag {self.directory} failed ({self._failed}) after "
                    f"{self.message_count} messages; it has no index and holds what was written "
                    f"up to its last complete chunk: `predictive-drive repair {self.directory}` "
                    f"rebuilds one from that"
                ) from None
            self._failed = f"{e.strerror or e}"  # what `failure` tells
            raise BagError(
                f"closing the bag {self.directory} failed ({self._failed}): it has no index; "
                f"`predictive-drive repair {self.directory}` rebuilds one from what it holds"
            ) from None

    @property
    def failed(self) -> bool:
        """A write failed (a full disk): nothing more can be written."""
        return bool(self._failed)

    @property
    def failure(self) -> str:
        """Why the write failed ('' if none did)."""
        return self._failed

    def _finish(self) -> None:
        self._writer.add_metadata(
            "rosbag2",
            {
                "serialized_metadata": dump_yaml(self._metadata()["rosbag2_bagfile_information"]),
                "ROS_DISTRO": "jazzy",
            },
        )
        self._writer.finish()
        self._writer.close()
        self._file.close()
        self._write_metadata_yaml()

    @property
    def message_count(self) -> int:
        return self._writer.message_count

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def _metadata(self) -> dict[str, Any]:
        start = self._writer.first_time or 0
        duration = max(0, self._writer.last_time - start)
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
                        "message_count": self._writer.counts[self._channels[key]],
                    }
                    for key, t in self._topics.items()
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
                "custom_data": dict(self.custom_data) or None,
                "ros_distro": "jazzy",
            }
        }

    def _write_metadata_yaml(self) -> None:
        tmp = self.directory / "metadata.yaml.tmp"
        tmp.write_text(dump_yaml(self._metadata()))
        tmp.replace(self.directory / "metadata.yaml")


def mcap_file(bag: str | Path) -> Path:
    """The recording of a bag directory (one ``.mcap`` file, and a ``metadata.yaml`` that is
    rosbag2's if there is one) or the ``.mcap`` file given; BagError says what is wrong."""
    p = Path(bag)
    if p.is_dir():
        files = sorted(p.glob("*.mcap"))
        if not files:
            raise BagError(f"{p}: no .mcap file in this bag directory")
        if len(files) > 1:
            raise BagError(
                f"{p}: {len(files)} .mcap files ({', '.join(f.name for f in files)}); a bag of "
                f"this package has one: give the file itself"
            )
        _check_metadata_yaml(p / "metadata.yaml")
        _check_magic(files[0])
        return files[0]
    if not p.is_file():
        raise BagError(f"{p}: no such bag directory or .mcap file")
    _check_magic(p)
    return p


def _check_magic(path: Path) -> None:
    """BagError unless ``path`` begins as an MCAP file does (an empty file is said to be)."""
    try:
        with path.open("rb") as f:
            head = f.read(len(MAGIC))
    except OSError as e:
        raise BagError(f"{path}: cannot read it: {e.strerror}") from None
    if not head:
        raise BagError(
            f"{path}: the file is empty (0 bytes): its writer was killed before it wrote anything"
        )
    if head != MAGIC[: len(head)] or len(head) < len(MAGIC):
        raise BagError(f"{path}: not an MCAP file (it does not begin with MCAP's magic bytes)")


def not_a_recording(path: Path, meta: dict[str, dict[str, str]], messages: int) -> BagError:
    """The error for an MCAP file without this package's metadata record: cut short before its
    writer wrote any (no record past the header), or another program's recording."""
    if not meta and messages == 0:
        return BagError(
            f"{path}: the recording was cut short before anything was recorded "
            f"({path.stat().st_size} bytes: the file's header only)"
        )
    return BagError(f"{path}: not a predictive_drive recording (no '{META_NAME}' metadata)")


def _check_metadata_yaml(path: Path) -> None:
    if not path.exists():
        return
    try:
        doc = load_yaml(path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as e:
        raise BagError(f"{path}: not rosbag2 metadata ({type(e).__name__})") from None
    if not (isinstance(doc, dict) and isinstance(doc.get("rosbag2_bagfile_information"), dict)):
        raise BagError(f"{path}: not rosbag2 metadata (no rosbag2_bagfile_information mapping)")


def read_records(
    path: Path,
) -> tuple[list[tuple[Channel, Message]], dict[str, dict[str, str]], bool]:
    """Every (channel, message) pair in file order, the metadata records by name, and whether
    the file is whole (indexed): a file cut short is read as a stream up to its cut."""
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


@dataclass(frozen=True)
class RepairResult:
    """What :func:`repair_bag` did: the repaired bag, where the original file is kept, and the
    messages the repaired bag holds."""

    bag: Path
    original: Path | None  #: None when the bag was intact and left alone
    messages: int


def repair_bag(bag: str | Path) -> RepairResult:
    """Rewrite a bag whose writer was killed (no index, footer or summary; metadata.yaml claiming
    0 messages) into a valid one with every complete message it holds, in log-time order, as
    ``ros2 bag reindex`` / ``mcap recover`` do. The original file is kept beside it as
    ``<name>.mcap.orig``; an intact bag is left as it is."""
    path = mcap_file(bag)
    msgs, meta, complete = read_records(path)
    if META_NAME not in meta:
        raise not_a_recording(path, meta, len(msgs))
    if complete:
        return RepairResult(path.parent, None, len(msgs))
    original = path.with_name(path.name + ".orig")
    if original.exists():
        raise BagError(f"{path}: {original} exists already; move it away to repair again")
    keys = {t.name: key for key, t in BAG_TOPICS.items()}
    order = sorted(range(len(msgs)), key=lambda i: msgs[i][1].log_time)  # stable: file order
    tmp = path.parent.parent / f".{path.parent.name}.repair-{os.getpid()}"
    try:
        w: BagWriter | None = None
        try:
            losses = any(channel.topic == TOPICS["losses"].name for channel, _ in msgs)
            with BagWriter(tmp, info=meta[META_NAME], stamp=False, losses=losses) as w:
                for i in order:
                    channel, message = msgs[i]
                    if channel.topic in keys:
                        w.write(keys[channel.topic], message.log_time, message.data)
        except (BagError, OSError) as e:
            failure = w.failure if w is not None else ""
            why = failure or getattr(e, "strerror", None) or str(e)
            raise BagError(
                f"{path}: repairing it writes a second copy beside it (up to "
                f"{path.stat().st_size} bytes), which failed ({why}); the original is intact: "
                f"copy the bag to a disk with room and repair the copy"
            ) from None
        os.replace(path, original)
        os.replace(w.path, path)
        os.replace(tmp / "metadata.yaml", path.parent / "metadata.yaml")
        # metadata.yaml names the file: the repaired one has the original's name
        meta_yaml = path.parent / "metadata.yaml"
        meta_yaml.write_text(meta_yaml.read_text().replace(w.path.name, path.name))
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return RepairResult(path.parent, original, w.message_count)


@dataclass(frozen=True)
class RecordedTopic:
    """A topic as a bag holds it: name, ROS type, the QoS it was offered with (rosbag2's
    ``offered_qos_profiles``, a list of dicts), and its message count."""

    name: str
    type: str
    qos: list[dict[str, Any]]
    count: int


def _indexed_reader(bag: str | Path, f: Any) -> Any:
    reader = make_reader(f)
    try:
        reader.get_summary()
    except (McapError, EOFError, ValueError, AssertionError, OSError) as e:
        path = mcap_file(bag)
        msgs, meta, _ = read_records(path)
        if META_NAME not in meta:
            raise not_a_recording(path, meta, len(msgs)) from None
        raise BagError(
            f"{bag}: the recording has no index (its writer was killed: {type(e).__name__}); "
            f"`predictive-drive repair {bag}` rebuilds it"
        ) from None
    return reader


def recorded_topics(bag: str | Path) -> dict[str, RecordedTopic]:
    """Every topic of an indexed recording, by name."""
    path = mcap_file(bag)
    with path.open("rb") as f:
        summary = _indexed_reader(bag, f).get_summary()
    counts = summary.statistics.channel_message_counts if summary.statistics else {}
    out = {}
    for cid, ch in summary.channels.items():
        schema = summary.schemas.get(ch.schema_id)
        qos = load_yaml(ch.metadata.get("offered_qos_profiles", "[]")) or []
        out[ch.topic] = RecordedTopic(
            ch.topic, schema.name if schema else "", qos, counts.get(cid, 0)
        )
    return out


def first_log_time(bag: str | Path) -> int | None:
    """The log time of an indexed recording's first message (ns; None when it holds none),
    from its summary: no chunk is read."""
    path = mcap_file(bag)
    with path.open("rb") as f:
        stats = _indexed_reader(bag, f).get_summary().statistics
    if stats is None or not stats.message_count:
        return next((t for _, t, _ in iter_messages(bag)), None)  # a writer without statistics
    return int(stats.message_start_time)


def iter_messages(
    bag: str | Path,
    *,
    topics: Sequence[str] | None = None,
    start_ns: int | None = None,
    end_ns: int | None = None,
) -> Iterator[tuple[str, int, bytes]]:
    """(topic, log time in ns, serialized message) of an indexed recording in log-time order
    (in file order among equal times), from ``start_ns`` to before ``end_ns``; ``topics``:
    only these. Read as it goes, not into memory."""
    path = mcap_file(bag)
    with path.open("rb") as f:
        reader = _indexed_reader(bag, f)
        for _schema, channel, message in reader.iter_messages(
            topics=list(topics) if topics is not None else None,
            start_time=start_ns,
            end_time=end_ns,
            log_time_order=True,
        ):
            yield channel.topic, message.log_time, bytes(message.data)
