"""The fast MCAP path against the ``mcap`` library: the writer's bytes, the grouped records, the
chunk reader, and a recording made by the fast path against one made message by message."""

from __future__ import annotations

import io
import os
import random

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.records import Chunk, Message
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, IndexType, Writer

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


@pytest.mark.parametrize(("prefixed", "after"), [(True, 0), (False, 1), (True, 2)])
def test_a_group_writes_what_its_messages_one_by_one_write(prefixed, after):
    """MessageGroup.add_steps writes the records of many steps as one block: the same bytes as
    add() of each message in turn, with other messages after some steps' first records, blocks
    of one step and of hundreds, and chunk boundaries (which fall inside blocks here, on each
    of the parts and on the extra messages) included. ``prefixed``: payloads after a constant
    prefix (in-process), or whole (a node's recorder); ``after``: the part the extra messages
    follow (in-process the state, the first; in a node the state, the second)."""
    prefixes = (b"\x00\x01\x00\x00" + b"p" * 36, b"\x00\x01\x00\x00" + b"r" * 20, b"\x00" * 28)
    if not prefixed:
        prefixes = (b"", b"", b"")
    widths = (20, 9, 21)

    def run(grouped: bool, seed: int) -> bytes:
        rng = np.random.default_rng(seed)
        out = io.BytesIO()
        w = ChunkWriter(out, chunk_size=8 * 1024)
        w.start(profile="ros2", library="test")
        ids = [w.register_channel(f"/c{i}", "cdr", 0, {}) for i in range(5)]
        group = w.group([(ids[i], prefixes[i], 8 * widths[i]) for i in range(3)], after)
        k = 0
        while k < 1500:
            n = int(rng.choice([1, 2, 7, 128, 300]))
            values = [rng.standard_normal((n, m)).astype("<f8") for m in widths]
            times = [np.arange(k, k + n, dtype=np.int64) * 50_000 + (i == 2) for i in range(3)]
            extras = []
            for j in range(n):
                if (k + j) % 20 == 0:  # tool messages after the state, now and then
                    extra = [(ids[3], int(times[0][j]), b"tool" * int(rng.integers(1, 40)))]
                    if (k + j) % 40 == 0:
                        extra.append((ids[4], int(times[0][j]), b"joint"))
                    extras.append((j, extra))
            if grouped:
                group.add_steps(times, [v.tobytes() for v in values], extras)
            else:
                more = dict(extras)
                for j in range(n):
                    for i in range(3):
                        w.add(ids[i], int(times[i][j]), prefixes[i] + values[i][j].tobytes())
                        if i == after:
                            for ch, t, data in more.get(j, []):
                                w.add(ch, t, data)
            k += n
            if k % 37 < 3:  # a state on its own between blocks (a chunk may begin with it)
                w.add(ids[0], k * 50_000, prefixes[0] + bytes(8 * widths[0]))
        w.finish()
        return out.getvalue()

    for seed in (2, 3):
        one_by_one = run(False, seed)
        assert len(one_by_one) > 50_000
        assert run(True, seed) == one_by_one


def test_a_block_that_fills_the_chunk_exactly_leaves_it_open():
    """A chunk is full once a record takes it *past* its size (the library's rule): a block
    whose record ends exactly at the size leaves the chunk open, as add() does."""
    prefix = b"\x00\x01\x00\x00" + b"p" * 4

    def run(grouped: bool, chunk_size: int) -> tuple[bytes, int]:
        out = io.BytesIO()
        w = ChunkWriter(out, chunk_size=chunk_size)
        w.start(profile="ros2", library="test")
        ids = [w.register_channel(f"/c{i}", "cdr", 0, {}) for i in range(3)]
        opened = len(w._chunk)  # the channel records
        group = w.group([(ch, prefix, 16) for ch in ids])
        values = np.arange(60, dtype="<f8").reshape(10, 3, 2)
        times = [np.arange(10, dtype=np.int64) * 1000 for _ in ids]
        if grouped:
            group.add_steps(times, [values[:, i].tobytes() for i in range(3)])
        else:
            for j in range(10):
                for i, ch in enumerate(ids):
                    w.add(ch, int(times[i][j]), prefix + values[j, i].tobytes())
        w.finish()
        return out.getvalue(), opened

    _, opened = run(False, 1 << 20)
    record = 31 + len(prefix) + 16
    for size in (opened + 9 * record, opened + 9 * record - 1, opened + 9 * record + 1):
        one_by_one, _ = run(False, size)
        assert run(True, size)[0] == one_by_one


def lib_messages(path) -> list[tuple]:
    with open(path, "rb") as f:
        return [
            (ch.topic, m.log_time, m.publish_time, m.sequence, bytes(m.data))
            for _, ch, m in make_reader(f).iter_messages(log_time_order=False)
        ]


@pytest.mark.parametrize(
    "layout",
    [
        {},  # chunks with their message indexes: the message heads gathered with numpy
        {"index_types": IndexType.NONE},  # chunks without: record by record
        {"use_chunking": False},  # no chunks
    ],
    ids=["indexed", "no-index", "unchunked"],
)
def test_the_reader_reads_what_the_mcap_library_reads(tmp_path, layout):
    path = tmp_path / "f.mcap"
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=32 * 1024, compression=CompressionType.ZSTD, **layout)
        play(w, calls(3, 4000))
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


def damage_the_third_chunk(path, damage) -> list[tuple]:
    """``damage(data, at)`` the file's third chunk record (``at``: where it begins in the
    bytearray ``data``); returns (channel id, log time, sequence) of the messages of the two
    chunks before it, as the library reads them: what a reader should still read."""
    with open(path, "rb") as f:
        records = StreamReader(f, skip_magic=False, emit_chunks=True).records
        two = [r for r in records if isinstance(r, Chunk)][:2]
    data = bytearray(path.read_bytes())
    chunks, pos = [], len(b"\x89MCAP0\r\n")
    while data[pos] != 0x0F:  # the top-level records up to the data end
        if data[pos] == 0x06:
            chunks.append(pos)
        pos += 9 + int.from_bytes(data[pos + 1 : pos + 9], "little")
    damage(data, chunks[2])
    path.write_bytes(bytes(data))
    return [(m.channel_id, m.log_time, m.sequence) for c in two for m in breakup_chunk(c)
            if isinstance(m, Message)]  # fmt: skip


def test_a_chunk_that_claims_more_bytes_than_memory_holds_ends_the_reading_there(tmp_path):
    """A damaged chunk head (its uncompressed size 2**62 bytes) is a damaged chunk, not a
    MemoryError: the messages of the chunks before it are read, as the library reads them."""
    path = tmp_path / "f.mcap"
    with open(path, "wb") as f:
        play(Writer(f, chunk_size=32 * 1024, compression=CompressionType.ZSTD), calls(5, 4000))

    def claim(data, at):  # the uncompressed size, after the chunk's start and end times
        data[at + 9 + 16 : at + 9 + 24] = (2**62).to_bytes(8, "little")

    expected = damage_the_third_chunk(path, claim)
    c = read_file(path)
    assert not c.complete
    assert [(ch.id, lt, s) for ch, lt, _, s, _ in c.in_file_order()] == expected


@pytest.mark.parametrize("length", [2**40, 3], ids=["past-the-chunk", "shorter-than-a-head"])
def test_a_chunk_whose_record_length_is_wrong_ends_the_reading_there(tmp_path, length):
    """Uncompressed chunks without CRCs or message indexes (nothing else catches it): a message
    record whose length runs past its chunk, or is shorter than a message's head, damages its
    chunk; the chunks before it are read, as the library reads them."""
    path = tmp_path / "f.mcap"
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=32 * 1024, compression=CompressionType.NONE,
                   index_types=IndexType.NONE, enable_crcs=False)  # fmt: skip
        play(w, calls(5, 4000))

    def cut(data, at):
        # the chunk's records begin after its start, end, size, crc, an empty compression
        # string and the records' length
        pos = at + 9 + 8 + 8 + 8 + 4 + 4 + 8
        while data[pos] != 0x05:  # its first message
            pos += 9 + int.from_bytes(data[pos + 1 : pos + 9], "little")
        data[pos + 1 : pos + 9] = length.to_bytes(8, "little")

    expected = damage_the_third_chunk(path, cut)
    c = read_file(path)
    assert not c.complete
    assert [(ch.id, lt, s) for ch, lt, _, s, _ in c.in_file_order()] == expected


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
        run_inprocess(sc, switches=switches, sinks=[rec.record_rows])
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


def test_a_node_recorder_takes_a_batch_at_once_as_it_takes_it_message_by_message(tmp_path):
    """A node's recorder decodes a batch's records at once and sums their steps' running
    metrics at once; the bag is the one it writes taking every message in turn (its path with
    a live view): messages, times, sequence numbers, the order (reference k before state k,
    tool messages after the state), the diagnostics after the message that completed their
    period, across batches of odd sizes, with a parameter change, a command of another
    version's layout and a command that never came in between."""
    from predictive_drive.bag import BagWriter
    from predictive_drive.codec import (
        CODECS,
        MultiArrayCodec,
        encode_parameter_event,
        tool_stamp_ns,
    )
    from predictive_drive.config import load_scenario
    from predictive_drive.core.control import strategy_names
    from predictive_drive.core.runner import run_inprocess
    from predictive_drive.interface import TOPICS
    from predictive_drive.recording import RunRecorder, bag_info, tool_every, tool_messages

    sc = load_scenario("im_short", strategy="mptc", duration=0.25)
    tr = run_inprocess(sc, switches=[(1337, "db_mptc")])
    n = tr.steps
    every = tool_every(sc.ts)
    old = tuple(f for f in TOPICS["command"].fields if f != "mtpa_gradient")
    messages: list[tuple[str, bytes]] = [("reference", CODECS["reference"].encode(tr.reference[0]))]
    for k in range(n + 1):
        state = tuple(tr.state[k])
        messages.append(("state", CODECS["state"].encode(state)))
        messages += [(key, data) for key, _, data in tool_messages(state, every)]
        if k < n:
            command = tuple(tr.command[k])
            if k == 3001:  # a command of another version's layout
                data = MultiArrayCodec(old).encode(command[: len(old)])
            else:
                data = CODECS["command"].encode(command)
            # reference k+1 comes before command k now and then (the speed PI is quicker)
            ref = ("reference", CODECS["reference"].encode(tr.reference[k + 1]))
            if k == 3999:  # a command that never came: step 3999 is never complete
                messages.append(ref)
            else:
                messages += [ref, ("command", data)] if k % 7 == 0 else [("command", data), ref]
        if k == 1337:
            event = encode_parameter_event(k * sc.ts, "/drive/torque_controller", [("x", 1)])
            messages.append(("parameter_events", event))

    def record(name: str, live) -> list[tuple]:
        with BagWriter(tmp_path / name, info=bag_info(sc, "ros")) as w:
            rec = RunRecorder(
                w,
                ts=sc.ts,
                steps=n,
                torque_limit=sc.speed_pi.torque_limit,
                strategy_names=strategy_names(sc.family),
                record_tools=False,
                live=live,
            )
            i = 0
            for size in [1, 2, 384, 97, 1000, 5] * 400:
                if i >= len(messages):
                    break
                rec.take(messages[i : i + size])
                rec.flush()
                i += size
            rec.finish()
        return lib_messages(tmp_path / name / f"{name}_0.mcap")

    each = record("each", live=lambda key, t, data: None)  # message by message
    once = record("once", live=None)
    assert len(each) > 15_000 and once == each
    # the steps' messages in (log time, arrival) order, from the codec, not the recorder
    stamp = {key: TOPICS[key].name for key in ("state", "reference", "command", "clock")}
    stamp["joint_states"] = TOPICS["joint_states"].name
    expected = sorted(
        (
            (round(CODECS[key].decode(data)[1] * 1e9) if key in CODECS else tool_stamp_ns(data)),
            i,
            stamp[key],
            data,
        )
        for i, (key, data) in enumerate(messages)
        if key in stamp
    )
    steps = [(topic, lt, data) for topic, lt, _, _, data in once if topic in stamp.values()]
    assert steps == [(topic, lt, data) for lt, _, topic, data in expected]
    assert sum(m[0] == "/diagnostics" for m in once) >= 3
    assert sum(m[0] == "/parameter_events" for m in once) == 1


def test_a_malformed_command_stream_never_crashes_the_recorder_or_costs_a_valid_step(tmp_path):
    """A controller of one's own at step 100: a command of the wrong size, one with no layout,
    the commands of the next 1,000 steps at once, then command 100 (the plant refuses the first
    and stops). The recorder takes every valid step before it, leaves the rest out (counted,
    the first said), and the bag closes readable with steps 0-99 whole (was: a layout error
    that stopped the recording, or an IndexError pairing the steps, an unreadable bag)."""
    from predictive_drive.bag import BagWriter
    from predictive_drive.codec import CODECS, CdrWriter, MultiArrayCodec
    from predictive_drive.config import load_scenario
    from predictive_drive.core.control import strategy_names
    from predictive_drive.core.runner import run_inprocess
    from predictive_drive.core.signals import EXTERNAL
    from predictive_drive.readback import read_bag
    from predictive_drive.recording import RunRecorder, bag_info, tool_every, tool_messages

    sc = load_scenario("im_short", strategy="mptc", duration=0.02)
    tr = run_inprocess(sc)
    every, own = tool_every(sc.ts), MultiArrayCodec(("k", "t", "s_a", "s_b", "s_c"))

    def array(labels: str | None, values: tuple[float, ...]) -> bytes:
        """A Float64MultiArray as rclpy sends it, with one labelled dimension or none."""
        w = CdrWriter()
        w.u32(0 if labels is None else 1)
        if labels is not None:
            w.string(labels)
            w.u32(len(values))
            w.u32(len(values))
        w.u32(0)  # data_offset
        w.f64_seq(values)
        return w.bytes()

    wrong_size = array("k,t,s_a,s_b,s_c", (100.0, 0.005, 1.0, 0.0))  # five labels, four values
    no_layout = array(None, (100.0, 0.005, 1.0, 0.0, 0.0))
    messages: list[tuple[str, bytes]] = [("reference", CODECS["reference"].encode(tr.reference[0]))]
    for k in range(101):
        state = tuple(tr.state[k])
        messages.append(("state", CODECS["state"].encode(state)))
        messages += [(key, data) for key, _, data in tool_messages(state, every)]
        messages.append(("reference", CODECS["reference"].encode(tr.reference[k + 1])))
        if k < 100:
            messages.append(("command", CODECS["command"].encode(tuple(tr.command[k]))))
    future = [own.encode((j, j * sc.ts, 1.0, 0.0, 0.0)) for j in range(101, 1101)]
    for data in [wrong_size, no_layout, *future, own.encode((100.0, 0.005, 1.0, 0.0, 0.0))]:
        messages.append(("command", data))
    with BagWriter(tmp_path / "bag", info=bag_info(sc.with_strategy(EXTERNAL), "ros")) as w:
        rec = RunRecorder(w, ts=sc.ts, steps=tr.steps, torque_limit=sc.speed_pi.torque_limit,
                          strategy_names=strategy_names(sc.family), record_tools=False)  # fmt: skip
        for i in range(0, len(messages), 384):
            rec.take(messages[i : i + 384])
            rec.flush()
        rec.finish("stopped by the test")
    assert rec.left_out == {"command": 3}  # the two malformed ones and the late command 100
    assert rec.left_out_first.startswith("a /drive/command message: Float64MultiArray layout")
    trace, info = read_bag(tmp_path / "bag")
    assert trace.steps == 100 and list(trace.state[:, 0]) == list(range(101))
    np.testing.assert_array_equal(trace.command[:, :-1], tr.command[:100, :-1])
    assert info.custom["outcome"].startswith("ERROR: stopped by the test: 100 of 400 steps")


def test_the_outcome_counts_the_steps_as_report_does(tmp_path):
    """A run stopped between state k+1 and reference k+1 (a Ctrl-C can land there): step k is
    not whole, and the outcome's count is the trace's (was: one more, counted by states alone:
    45874 against 45873 in a graph test)."""
    from predictive_drive.bag import BagWriter
    from predictive_drive.codec import CODECS
    from predictive_drive.config import load_scenario
    from predictive_drive.core.control import strategy_names
    from predictive_drive.core.runner import run_inprocess
    from predictive_drive.readback import read_bag
    from predictive_drive.recording import RunRecorder, bag_info

    sc = load_scenario("im_short", strategy="mptc", duration=0.01)
    tr = run_inprocess(sc)
    messages: list[tuple[str, bytes]] = []
    for k in range(50):  # state k, reference k, command k
        messages.append(("state", CODECS["state"].encode(tuple(tr.state[k]))))
        messages.append(("reference", CODECS["reference"].encode(tr.reference[k])))
        messages.append(("command", CODECS["command"].encode(tuple(tr.command[k]))))
    messages.append(("state", CODECS["state"].encode(tuple(tr.state[50]))))  # no reference 50
    with BagWriter(tmp_path / "bag", info=bag_info(sc, "ros")) as w:
        rec = RunRecorder(w, ts=sc.ts, steps=tr.steps, torque_limit=sc.speed_pi.torque_limit,
                          strategy_names=strategy_names(sc.family), record_tools=False)  # fmt: skip
        rec.take(messages)
        rec.flush()
        rec.finish("interrupted")
    trace, info = read_bag(tmp_path / "bag")
    assert trace.steps == 49
    assert info.custom["outcome"].startswith(f"ERROR: interrupted: 49 of {tr.steps} steps")


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
