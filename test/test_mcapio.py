"""The fast MCAP path against the ``mcap`` library: the writer's bytes, the grouped records, the
chunk reader, and a recording made by the fast path against one made message by message."""

from __future__ import annotations

import io
import os
import random

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from mcapcheck import rewrite_bag
from predictive_drive.mcapio import ChunkWriter, read_file

pytestmark = pytest.mark.core


def calls(seed: int, messages: int) -> list[tuple]:
    """A writer's calls: schemas, channels, metadata, messages of random sizes whose log times
    sometimes go back, metadata again."""
    rng = random.Random(seed)
    out: list[tuple] = [
        ("schema", "std_msgs/msg/Float64MultiArray", "ros2msg", b"float64[] data"),
        ("schema", "rosgraph_msgs/msg/Clock", "ros2msg", b"builtin_interfaces/Time clock"),
    ]
    out += [("channel", f"/t{i}", "cdr", 1 + i % 2, {"q": str(i)}) for i in range(5)]
    out.append(("meta", "predictive_drive", {"a": "b"}))
    seq: dict[int, int] = {}
    t = 0
    for _ in range(messages):
        ch = rng.randint(1, 5)
        seq[ch] = seq.get(ch, 0) + 1
        t += rng.choice([0, 1000, 50000])
        data = os.urandom(rng.randint(0, 40)) + bytes(rng.randint(0, 600))
        out.append(("msg", ch, t - rng.choice([0, 0, 2000]), data, t, seq[ch]))
    out.append(("meta", "rosbag2", {"x": "y"}))
    return out


def play(w, script) -> None:
    w.start(profile="ros2", library="test")
    for c in script:
        if c[0] == "schema":
            w.register_schema(*c[1:])
        elif c[0] == "channel":
            w.register_channel(*c[1:])
        elif c[0] == "meta":
            w.add_metadata(*c[1:])
        else:
            w.add_message(*c[1:])
    w.finish()


@pytest.mark.parametrize("background", [False, True])
def test_the_writer_writes_what_the_mcap_library_writes(background):
    """Byte for byte: chunks, message indexes, statistics, summary, footer, CRCs."""
    script = calls(1, 6000)
    lib = io.BytesIO()
    play(Writer(lib, chunk_size=32 * 1024, compression=CompressionType.ZSTD), script)
    ours = io.BytesIO()
    w = ChunkWriter(ours, chunk_size=32 * 1024, background=background)
    play(w, script)
    w.close()
    assert len(lib.getvalue()) > 100_000
    assert ours.getvalue() == lib.getvalue()


def test_a_group_writes_what_its_messages_one_by_one_write():
    """MessageGroup.add3 packs state, reference and command at once: the same bytes as three
    add() calls, chunk boundaries (which fall inside groups here) included."""
    prefixes = (b"\x00\x01\x00\x00" + b"p" * 36, b"\x00\x01\x00\x00" + b"r" * 20, b"\x00" * 28)
    widths = (20, 9, 21)
    rng = np.random.default_rng(2)

    def run(grouped: bool) -> bytes:
        out = io.BytesIO()
        w = ChunkWriter(out, chunk_size=8 * 1024)
        w.start(profile="ros2", library="test")
        ids = [w.register_channel(f"/c{i}", "cdr", 0, {}) for i in range(4)]
        group = w.group([(ids[i], prefixes[i], 8 * widths[i]) for i in range(3)])
        for k in range(700):
            values = [rng.standard_normal(n).astype("<f8").tobytes() for n in widths]
            t = k * 50_000
            if k % 20 == 0:  # something else between the groups now and then
                w.add(ids[3], t, b"tool")
            if k % 37 == 0:  # a state on its own (a chunk may begin with it)
                w.add(ids[0], t, prefixes[0] + bytes(8 * widths[0]))
            if grouped:
                group.add3(t, t, t + 1, *values)
            else:
                for i in range(3):
                    w.add(ids[i], t + (i == 2), prefixes[i] + values[i])
        w.finish()
        return out.getvalue()

    rng = np.random.default_rng(2)
    one_by_one = run(False)
    rng = np.random.default_rng(2)
    assert run(True) == one_by_one


def lib_messages(path) -> list[tuple]:
    with open(path, "rb") as f:
        return [
            (ch.topic, m.log_time, m.publish_time, m.sequence, bytes(m.data))
            for _, ch, m in make_reader(f).iter_messages(log_time_order=False)
        ]


def test_the_reader_reads_what_the_mcap_library_reads(tmp_path):
    path = tmp_path / "f.mcap"
    with open(path, "wb") as f:
        play(Writer(f, chunk_size=32 * 1024, compression=CompressionType.ZSTD), calls(3, 4000))
    c = read_file(path)
    assert c.complete and c.messages == 4000
    got = [(ch.topic, lt, pt, s, d) for ch, lt, pt, s, d in c.in_file_order()]
    assert got == lib_messages(path)
    assert c.metadata == {"predictive_drive": {"a": "b"}, "rosbag2": {"x": "y"}}


def test_a_cut_file_is_read_up_to_its_last_whole_chunk(tmp_path):
    """As the library's stream reader reads it: every message of the chunks before the cut."""
    path = tmp_path / "f.mcap"
    with open(path, "wb") as f:
        play(Writer(f, chunk_size=32 * 1024, compression=CompressionType.ZSTD), calls(4, 4000))
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: int(len(data) * 0.6)])
    c = read_file(cut)
    assert not c.complete and 0 < c.messages < 4000
    stream = []
    channels = {}
    with open(cut, "rb") as f:
        try:
            for r in StreamReader(f, skip_magic=False).records:
                if type(r).__name__ == "Channel":
                    channels[r.id] = r.topic
                elif type(r).__name__ == "Message":
                    stream.append((channels[r.channel_id], r.log_time, r.sequence))
        except Exception:  # noqa: BLE001 — the cut
            pass
    assert [(ch.topic, lt, s) for ch, lt, _, s, _ in c.in_file_order()] == stream


def test_a_damaged_chunk_ends_the_reading_there(tmp_path):
    path = tmp_path / "f.mcap"
    with open(path, "wb") as f:
        play(Writer(f, chunk_size=32 * 1024, compression=CompressionType.ZSTD), calls(5, 4000))
    data = bytearray(path.read_bytes())
    whole = read_file(path).messages
    data[len(data) // 2] ^= 0xFF  # a flipped byte inside a chunk: its CRC no longer matches
    path.write_bytes(bytes(data))
    c = read_file(path)
    assert not c.complete and 0 < c.messages < whole


def test_the_fast_recording_path_writes_what_the_message_path_writes(tmp_path):
    """In-process recording takes each step's three records as one pack (and the running
    metrics a batch at a time); with a live view it goes message by message. Both bags hold
    the same messages, times and sequence numbers, in the same order, with a switch inside a
    batch and at a step that is not a tool step."""
    from predictive_drive.api.run import run_inprocess_to_bag
    from predictive_drive.bag import BagWriter
    from predictive_drive.config import load_scenario
    from predictive_drive.core.control import strategy_names
    from predictive_drive.core.runner import run_inprocess
    from predictive_drive.recording import RunRecorder, bag_info

    sc = load_scenario("im_short", strategy="mptc", duration=0.25)
    switches = [(1337, "db_mptc"), (2001, "mptc_db")]
    run_inprocess_to_bag(sc, tmp_path / "fast", switches=switches)
    with BagWriter(tmp_path / "slow", info=bag_info(sc, "inprocess")) as w:
        rec = RunRecorder(
            w,
            ts=sc.ts,
            steps=sc.run.steps,
            torque_limit=sc.speed_pi.torque_limit,
            strategy_names=strategy_names(sc.family),
            record_tools=True,
            live=lambda key, t, data: None,  # a second sink: the message-by-message path
        )
        run_inprocess(sc, switches=switches, sinks=[rec.record_step])
        rec.finish()

    def masked(messages):  # the measured compute time aside
        out = []
        for topic, lt, pt, s, d in messages:
            if topic == "/drive/command":
                d = d[:-8]
            out.append((topic, lt, pt, s, d))
        return out

    fast = masked(lib_messages(tmp_path / "fast" / "fast_0.mcap"))
    slow = masked(lib_messages(tmp_path / "slow" / "slow_0.mcap"))
    assert len(fast) > 15_000 and fast == slow
    events = [m for m in fast if m[0] == "/parameter_events"]
    assert [m[1] for m in events] == [1337 * 50_000, 2001 * 50_000]


def test_read_bag_decodes_what_the_mcap_library_decodes(tmp_path):
    """The per-step topics gathered by numpy equal each message decoded by the library's reader
    and the codec, one by one."""
    from predictive_drive.api.run import run_inprocess_to_bag
    from predictive_drive.codec import CODECS
    from predictive_drive.config import load_scenario
    from predictive_drive.interface import TOPICS
    from predictive_drive.readback import read_bag

    run_inprocess_to_bag(load_scenario("spmsm_short", duration=0.05), tmp_path / "b")
    tr, info = read_bag(tmp_path / "b")
    rows: dict[str, list] = {"state": [], "reference": [], "command": []}
    key_of = {TOPICS[key].name: key for key in rows}
    for topic, _, _, _, d in lib_messages(tmp_path / "b" / "b_0.mcap"):
        if topic in key_of:
            rows[key_of[topic]].append(CODECS[key_of[topic]].decode(d))
    np.testing.assert_array_equal(tr.state, np.array(rows["state"]))
    np.testing.assert_array_equal(tr.reference, np.array(rows["reference"]))
    np.testing.assert_array_equal(tr.command, np.array(rows["command"]))
    assert info.counts["/drive/state"] == len(rows["state"])


def test_a_bag_of_another_layout_is_read_message_by_message(tmp_path):
    """A state topic whose messages carry a label of another version (fields reordered, one
    missing) is read by field name, as before the gather."""
    from predictive_drive.api.run import run_inprocess_to_bag
    from predictive_drive.codec import CODECS, MultiArrayCodec, decode_multiarray
    from predictive_drive.config import load_scenario
    from predictive_drive.readback import read_bag

    run_inprocess_to_bag(load_scenario("im_short", duration=0.01), tmp_path / "b")
    codec = CODECS["state"]
    fields = tuple(f for f in codec.fields[::-1] if f != "i_alpha")  # reordered, one dropped
    old = MultiArrayCodec(fields)

    def in_old_layout(ch, m):
        if ch.topic != "/drive/state":
            return m.data
        labels, values = decode_multiarray(m.data)
        by = dict(zip(labels, values))
        return old.encode(tuple(by[f] for f in fields))

    other = tmp_path / "o"
    rewrite_bag(tmp_path / "b", other, data=in_old_layout)
    a, _ = read_bag(tmp_path / "b")
    b, _ = read_bag(other)
    i = codec.fields.index("i_alpha")
    assert np.isnan(b.state[:, i]).all()
    keep = [j for j in range(len(codec.fields)) if j != i]
    np.testing.assert_array_equal(a.state[:, keep], b.state[:, keep])


def test_the_writing_thread_and_the_switch_interval_end_with_the_bag(tmp_path, monkeypatch):
    """A bag closed, or one that could not even start (a full disk at its metadata.yaml),
    leaves no compressing thread behind and Python's switch interval as it was."""
    import sys
    import threading

    from predictive_drive.bag import BagWriter
    from predictive_drive.errors import BagError

    before = sys.getswitchinterval()
    with BagWriter(tmp_path / "a", info={}) as w:
        assert sys.getswitchinterval() == min(before, 0.001)
        w.write("state", 0, b"x")
    assert sys.getswitchinterval() == before

    def full(self):
        raise OSError(28, "No space left on device")

    monkeypatch.setattr(BagWriter, "_write_metadata_yaml", full)
    with pytest.raises(BagError, match="cannot write the bag .*No space left on device"):
        BagWriter(tmp_path / "b", info={})
    assert sys.getswitchinterval() == before
    assert not [t for t in threading.enumerate() if t.name.startswith("mcap-chunks")]
