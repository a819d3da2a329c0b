"""Recordings: rosbag2 MCAP layout, round trip, independent readers, truncated files."""

import re
import shutil

import numpy as np
import pytest
import yaml

from mcapcheck import ordering_faults, rewrite_bag
from predictive_drive.api.report import report
from predictive_drive.api.run import run, run_inprocess_to_bag
from predictive_drive.bag import BagWriter
from predictive_drive.config import load_scenario
from predictive_drive.core.runner import run_inprocess
from predictive_drive.errors import BagError
from predictive_drive.interface import TOPICS, bag_topics
from predictive_drive.readback import read_bag

pytestmark = pytest.mark.core
BAG_TOPICS = bag_topics(losses=False)  #: the topics of a run without plant.losses


@pytest.fixture(scope="module")
def recorded(tmp_path_factory, im_short):
    """0.06 s of im_short with a strategy switch at 0.03 s (so every bag topic has messages)."""
    out = tmp_path_factory.mktemp("bags") / "run1"
    sc = load_scenario("im_short", duration=0.06)
    n = run_inprocess_to_bag(sc, out, switches=SWITCH)
    return out, sc, n


SWITCH = [(600, "mptc")]


def test_bag_directory_layout_and_metadata(recorded):
    out, _, n = recorded
    assert sorted(p.name for p in out.iterdir()) == ["metadata.yaml", "run1_0.mcap"]
    meta = yaml.safe_load((out / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert meta["version"] == 9 and meta["storage_identifier"] == "mcap"
    assert meta["relative_file_paths"] == ["run1_0.mcap"]
    counts = {
        t["topic_metadata"]["name"]: t["message_count"] for t in meta["topics_with_message_count"]
    }
    assert counts["/drive/state"] == n + 1 and counts["/drive/command"] == n
    assert counts["/clock"] == counts["/drive/joint_states"] == n // 20 + 1  # 1 kHz of 20 kHz
    assert meta["message_count"] == sum(counts.values())


def test_round_trip_equals_the_in_memory_run(recorded, im_short):
    out, sc, n = recorded
    trace, info = read_bag(out)
    direct = run_inprocess(sc, switches=SWITCH)
    assert info.complete and trace.steps == n == direct.steps
    np.testing.assert_array_equal(trace.state, direct.state)
    np.testing.assert_array_equal(trace.reference, direct.reference)
    np.testing.assert_array_equal(trace.command[:, :-1], direct.command[:, :-1])


def test_mcap_follows_rosbag2_conventions(recorded):
    from mcap.reader import make_reader

    out, _, _ = recorded
    with (out / "run1_0.mcap").open("rb") as f:
        reader = make_reader(f)
        header = reader.get_header()
        summary = reader.get_summary()
        meta = {m.name: m.metadata for m in reader.iter_metadata()}
    assert header.profile == "ros2"
    schemas = {s.name: s for s in summary.schemas.values()}
    for t in BAG_TOPICS.values():
        assert schemas[t.type].encoding == "ros2msg"
    assert (
        "MSG: std_msgs/MultiArrayDimension"
        in schemas["std_msgs/msg/Float64MultiArray"].data.decode()
    )
    assert ("=" * 80 + "\nMSG: builtin_interfaces/Time") in schemas[
        "rosgraph_msgs/msg/Clock"
    ].data.decode()
    for ch in summary.channels.values():
        assert ch.message_encoding == "cdr"
        assert ch.metadata["topic_type_hash"].startswith("RIHS01_")
        qos = yaml.safe_load(ch.metadata["offered_qos_profiles"])
        assert qos[0]["reliability"] in ("reliable", "best_effort")
    assert "serialized_metadata" in meta["rosbag2"]
    assert meta["predictive_drive"]["scenario"] == "im_short"
    assert "ros__parameters" in meta["predictive_drive"]["scenario_yaml"]
    # as rosbag2 writes it: one schema per type, infinite durations as RMW_DURATION_INFINITE
    assert len(summary.schemas) == len({t.type for t in BAG_TOPICS.values()})
    infinite = {"sec": 9223372036, "nsec": 854775807}
    for ch in summary.channels.values():
        (qos,) = yaml.safe_load(ch.metadata["offered_qos_profiles"])
        assert qos["deadline"] == qos["lifespan"] == qos["liveliness_lease_duration"] == infinite


def test_messages_are_written_in_log_time_order_with_sequences_per_channel(recorded):
    out, _, _ = recorded
    backwards, bad_seq, n = ordering_faults(out / "run1_0.mcap")
    assert n > 3000 and backwards == 0 and bad_seq == []


def test_independent_reader_rosbags_decodes_every_topic(recorded):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    out, _, n = recorded
    seen = {}
    with AnyReader([out], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        for conn, _t, raw in reader.messages():
            msg = reader.deserialize(raw, conn.msgtype)
            seen.setdefault(conn.topic, msg)
    assert set(seen) == {t.name for t in BAG_TOPICS.values()}
    st = seen["/drive/state"]
    assert st.layout.dim[0].label.startswith("k,t,i_alpha,i_beta")
    assert seen["/drive/joint_states"].name == ["drive_shaft"]
    assert seen["/diagnostics"].status[0].name == "predictive_drive: drive"


def test_mcap_ros2_support_decodes(recorded):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    out, _, n = recorded
    with (out / "run1_0.mcap").open("rb") as f:
        msgs = list(
            make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages(
                topics=["/drive/command"]
            )
        )
    assert len(msgs) == n
    assert list(msgs[5].decoded_message.data)[0] == 5.0


def test_foxglove_typescript_reader_reads_every_message(tmp_path, typescript_reader):
    """Foxglove's and Lichtblick's reader (@mcap/core) reads a bag of several chunks, with a
    parameter change, as the mcap library reads it (test/ts_reader.py)."""
    if typescript_reader is None:
        pytest.skip("no Node.js, or npm could not install @mcap/core (see the warning)")
    out = tmp_path / "ts"
    n = run_inprocess_to_bag(load_scenario("im_short", duration=0.4), out, switches=SWITCH)
    assert n == 8000
    typescript_reader(out / "ts_0.mcap")


def test_truncated_file_reads_up_to_the_cut(recorded, tmp_path):
    out, _, n = recorded
    cut = tmp_path / "cut"
    shutil.copytree(out, cut)
    f = cut / "run1_0.mcap"
    data = f.read_bytes()
    f.write_bytes(data[: int(len(data) * 0.6)])  # as a SIGKILL mid-write would leave it
    trace, info = read_bag(cut)
    assert not info.complete
    assert 0 < trace.steps < n


def test_existing_bag_directory_is_refused(recorded):
    out, _, _ = recorded
    with pytest.raises(BagError, match="a bag of that name exists"):
        BagWriter(out, info={})


def test_report_agrees_with_run(tmp_path):
    r = run("im_short", engine="inprocess", duration=0.1, strategy="mptc", out=tmp_path / "r")
    rep = report(tmp_path / "r")
    assert rep.metrics == r.metrics
    assert rep.strategy == "mptc" and rep.steps == 2000


def test_switch_is_visible_in_recording(tmp_path):
    run(
        "im_short",
        engine="inprocess",
        duration=0.1,
        strategy="mptc",
        switches=[(0.07, "db_mptc")],
        out=tmp_path / "s",
    )
    trace, _ = read_bag(tmp_path / "s")
    strat = trace.col("command", "strategy")
    names = trace.strategy_names
    assert names[int(strat[0])] == "mptc" and names[int(strat[-1])] == "db_mptc"
    assert np.flatnonzero(np.diff(strat))[0] + 1 == 1400  # exactly at 0.07 s


@pytest.fixture(scope="module")
def long_recording(tmp_path_factory):
    """0.25 s of im_short: three /diagnostics periods (0.1 s, 0.1 s, then the last 0.05 s),
    then the run's outcome."""
    out = tmp_path_factory.mktemp("bags") / "long"
    run_inprocess_to_bag(load_scenario("im_short", duration=0.25), out)
    trace, _ = read_bag(out)
    return out, trace


def _rosbags_messages(bag, topic):
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    with AnyReader([bag], default_typestore=get_typestore(Stores.ROS2_JAZZY)) as reader:
        conns = [c for c in reader.connections if c.topic == topic]
        return [(t, reader.deserialize(raw, c.msgtype)) for c, t, raw in reader.messages(conns)]


def test_joint_states_carry_the_traced_shaft_values(long_recording):
    """Decoded by the independent reader: every 1 ms the shaft angle, speed and torque of the
    state at that step (so a wrong field index in the plant's tool messages fails here)."""
    bag, tr = long_recording
    msgs = _rosbags_messages(bag, "/drive/joint_states")
    k = np.arange(0, tr.steps + 1, 20)
    assert len(msgs) == len(k)
    got = np.array([(m.position[0], m.velocity[0], m.effort[0]) for _, m in msgs])
    want = np.column_stack(
        [tr.col("state", "theta_m")[k], tr.col("state", "omega_m")[k], tr.col("state", "torque")[k]]
    )
    np.testing.assert_array_equal(got, want)
    stamps = [m.header.stamp.sec + m.header.stamp.nanosec * 1e-9 for _, m in msgs]
    np.testing.assert_allclose(stamps, tr.col("state", "t")[k], rtol=0, atol=1e-9)


def _figures(tr, k0, k1):
    s = slice(k0, k1)
    te = tr.col("state", "torque")[s]
    psi = np.hypot(tr.col("state", "psi_alpha")[s], tr.col("state", "psi_beta")[s])
    return {
        "t_rmse": np.sqrt(np.mean((te - tr.col("reference", "torque_ref")[s]) ** 2)),
        "psi_rmse": np.sqrt(np.mean((psi - tr.col("reference", "flux_ref")[s]) ** 2)),
        "torque_estimate_rmse": np.sqrt(np.mean((tr.col("command", "torque_est")[s] - te) ** 2)),
        "speed_rmse": np.sqrt(
            np.mean((tr.col("state", "omega_m")[s] - tr.col("reference", "speed_ref")[s]) ** 2)
        ),
        "f_ave_hz": tr.col("state", "transitions")[s].sum() / (6 * (k1 - k0) * tr.ts),
    }


def test_diagnostics_values_equal_the_trace_figures(long_recording):
    """/diagnostics, decoded by the independent reader, against figures computed here from the
    trace over the same steps (every 0.1 s of simulated time, then the rest), and the last
    message the whole run's outcome: a wrong index in the running metrics fails here. Counts
    are integers; /drive/metrics carries the same figures as numbers."""
    bag, tr = long_recording
    msgs = _rosbags_messages(bag, "/diagnostics")
    numeric = _rosbags_messages(bag, "/drive/metrics")
    assert len(msgs) == 4 and len(numeric) == 3
    bounds = [(0, 2000), (2000, 4000), (4000, tr.steps), (0, tr.steps)]
    fields = numeric[0][1].layout.dim[0].label.split(",")
    for i, ((_, msg), (k0, k1)) in enumerate(zip(msgs, bounds)):
        (status,) = msg.status
        values = {kv.key: kv.value for kv in status.values}
        for key, value in _figures(tr, k0, k1).items():
            assert float(values[key]) == pytest.approx(value, rel=1e-9, abs=1e-12), key
            if i < 3:
                assert float(values[key]) == numeric[i][1].data[fields.index(key)]
        assert values["steps"] == str(k1) and values["k"] == str(k1 - 1)
        assert values["strategy"] == "db_mptc"
        if i < 3:
            assert status.level == 0 and status.message == f"running: {k1} of 5000 steps"
    final = msgs[-1][1].status[0]
    assert final.level == 0 and final.message.startswith(
        "complete: 5000 steps; over the run T_e RMSE"
    )
    assert {kv.key: kv.value for kv in final.values}["steps_planned"] == "5000"


def test_the_outcome_of_an_interrupted_run_is_an_error(tmp_path, monkeypatch):
    """Ctrl-C in the middle: the bag closes with every step taken, and its last /diagnostics
    says ERROR with the steps missing."""
    from predictive_drive.core import runner

    real = runner.run_inprocess

    def interrupted(sc, **kw):
        def stop(k):
            if k >= 1500:
                raise KeyboardInterrupt

        return real(sc, **{**kw, "progress": stop})

    monkeypatch.setattr("predictive_drive.api.run.run_inprocess", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_inprocess_to_bag(load_scenario("im_short", duration=0.25), tmp_path / "cut")
    (_, msg), *_ = reversed(_rosbags_messages(tmp_path / "cut", "/diagnostics"))
    (status,) = msg.status
    done = re.match(r"interrupted: (\d+) of 5000 steps; over the run T_e RMSE", status.message)
    assert status.level == 2 and done and 1500 <= int(done[1]) < 5000
    meta = yaml.safe_load((tmp_path / "cut" / "metadata.yaml").read_text())
    assert meta["rosbag2_bagfile_information"]["custom_data"]["outcome"].startswith("ERROR: ")


def test_a_ctrl_c_while_a_batch_goes_into_the_bag_waits_for_the_batch(tmp_path, monkeypatch):
    """The command line's Ctrl-C comes while the recorder is between the message index and the
    chunk of a block: it is raised once the batch is in, and the bag reads whole (every message
    the index names is in its chunk), its outcome interrupted."""
    import os
    import signal

    from mcap.reader import make_reader

    from predictive_drive import interrupts
    from predictive_drive.mcapio import ChunkWriter

    real = ChunkWriter._index_block
    calls = []

    def index_then_ctrl_c(self, *a, **kw):
        real(self, *a, **kw)
        calls.append(1)
        if len(calls) == 3:
            os.kill(os.getpid(), signal.SIGINT)  # the handler runs at the next bytecode

    monkeypatch.setattr(ChunkWriter, "_index_block", index_then_ctrl_c)
    before = signal.signal(signal.SIGINT, interrupts.interrupt)
    try:
        with pytest.raises(KeyboardInterrupt):
            run_inprocess_to_bag(load_scenario("im_short", duration=0.25), tmp_path / "cut")
    finally:
        signal.signal(signal.SIGINT, before)
    with open(tmp_path / "cut" / "cut_0.mcap", "rb") as f:
        reader = make_reader(f)
        stats = reader.get_summary().statistics
        messages = sum(1 for _ in reader.iter_messages(log_time_order=False))
    assert 1000 < messages == stats.message_count < 15_000
    meta = yaml.safe_load((tmp_path / "cut" / "metadata.yaml").read_text())
    assert meta["rosbag2_bagfile_information"]["custom_data"]["outcome"].startswith(
        "ERROR: interrupted"
    )


def test_a_record_of_another_layout_is_read_by_field_name():
    """A command recorded before the field-oriented fields existed: every field it has lands in
    its place, the ones it lacks are NaN (old recordings stay readable)."""
    from predictive_drive.codec import CODECS, MultiArrayCodec

    old = tuple(f for f in TOPICS["command"].fields if f not in ("current_angle", "mtpa_gradient"))
    values = tuple(float(i) for i in range(len(old)))
    row = CODECS["command"].decode(MultiArrayCodec(old).encode(values))
    by_name = dict(zip(TOPICS["command"].fields, row))
    assert all(by_name[f] == v for f, v in zip(old, values))
    assert np.isnan(by_name["current_angle"]) and np.isnan(by_name["mtpa_gradient"])
    with pytest.raises(BagError, match="layout mismatch"):
        CODECS["command"].decode(MultiArrayCodec(("x", "y")).encode((1.0, 2.0)))


def test_the_tool_messages_are_what_cdr_writes_field_by_field():
    """/clock and /drive/joint_states are packed in one struct call each: the same bytes as the
    CDR writer's field by field (stamp, frame_id, one name, three sequences of one float64,
    each aligned to 8), for times that round up to the next second too."""
    from predictive_drive.codec import CdrWriter, encode_clock, encode_joint_state

    rng = np.random.default_rng(5)
    for t in [0.0, 0.9999999996, 1.5, *rng.uniform(0, 100, 200)]:
        p, v, e = rng.standard_normal(3) * 100
        w = CdrWriter()
        w.time(t)
        assert encode_clock(t) == w.bytes()
        w.string("")
        w.u32(1)
        w.string("drive_shaft")
        for x in (p, v, e):
            w.f64_seq((x,))
        assert encode_joint_state(t, p, v, e) == w.bytes()


def test_repair_writes_what_the_cut_file_holds_in_log_time_order(recorded, tmp_path):
    """A writer killed outright may leave messages out of log-time order across channels (the
    graph delivers command k after state k+1). Made here with the mcap library: every channel
    written one after the other (each in its own order, 16 KiB chunks), the file cut at 70 %.
    `repair` writes every complete message the cut file holds, in log-time order, each channel's
    sequence 1, 2, 3, ..., the original kept beside it."""
    from predictive_drive.bag import read_records, repair_bag

    scrambled = tmp_path / "scrambled"
    n_msgs = rewrite_bag(recorded[0], scrambled, order=lambda ch, m: ch.id)  # channel by channel
    path = scrambled / "scrambled_0.mcap"
    data = path.read_bytes()
    path.write_bytes(data[: int(len(data) * 0.7)])
    held, _, complete = read_records(path)
    assert not complete and 0 < len(held) < n_msgs
    backwards, _, n = ordering_faults(path)
    assert backwards > 0  # the cut file is out of order

    fixed = repair_bag(scrambled)
    assert fixed.messages == len(held) and fixed.original == path.with_name(path.name + ".orig")
    backwards, bad_seq, n = ordering_faults(path)
    assert (backwards, bad_seq, n) == (0, [], len(held))

    def content(pairs):  # any order
        return sorted((c.topic, m.log_time, m.sequence, m.publish_time, m.data) for c, m in pairs)

    assert content(read_records(path)[0]) == content(held)
