"""Replays (docs/recordings.md): a recording onto ROS topics as ros2 bag play does, received by an independent
subscriber in order and byte for byte; and a recording fed step by step into a controller node."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from predictive_drive.api.run import run_inprocess_to_bag
from predictive_drive.bag import iter_messages
from predictive_drive.config import load_scenario
from predictive_drive.interface import TOPICS

pytestmark = pytest.mark.process

CLI = [sys.executable, "-m", "predictive_drive.cli"]
PLAYED = ("/drive/state", "/drive/command", "/clock")


@pytest.fixture(scope="module")
def recording(tmp_path_factory):
    out = tmp_path_factory.mktemp("bags") / "played"
    run_inprocess_to_bag(load_scenario("im_short", duration=0.05), out)
    return out


class Listener:
    """An rclpy subscriber of its own (own Context, spun in a thread): every message of the
    played topics as received, with its arrival time."""

    def __init__(self, domain: int) -> None:
        import rclpy
        from rclpy.context import Context

        from predictive_drive.ros.transport import executor, msg_class, qos

        self.ctx = Context()
        rclpy.init(context=self.ctx, domain_id=domain)
        self.node = rclpy.create_node("listener", context=self.ctx)
        self.got: dict[str, list[tuple[float, bytes]]] = {t: [] for t in PLAYED}
        by_name = {t.name: t for t in TOPICS.values()}
        self.subs = [
            self.node.create_subscription(
                msg_class(by_name[name].type),
                name,
                lambda data, name=name: self.got[name].append((time.perf_counter(), data)),
                qos(by_name[name].qos),
                raw=True,
            )
            for name in PLAYED
        ]
        self.ex = executor(self.ctx)
        self.ex.add_node(self.node)
        self.stop = threading.Event()
        self.thread = threading.Thread(target=self._spin, daemon=True)
        self.thread.start()

    def _spin(self) -> None:
        while not self.stop.is_set():
            self.ex.spin_once(timeout_sec=0.05)

    def matched(self) -> bool:
        return all(s.get_publisher_count() > 0 for s in self.subs)

    def close(self) -> None:
        import rclpy

        self.stop.set()
        self.thread.join(timeout=5)
        self.ex.shutdown(timeout_sec=1.0)
        self.node.destroy_node()
        rclpy.try_shutdown(context=self.ctx)


@pytest.mark.parametrize("rate", [1.0, 0.25])
def test_replay_reaches_an_independent_subscriber_in_order_byte_for_byte(recording, rate):
    from predictive_drive.ros.processes import isolated_domain

    with isolated_domain() as domain:
        env = {**os.environ, "ROS_DOMAIN_ID": str(domain)}
        listener = Listener(domain)
        player = subprocess.Popen(
            [*CLI, "replay", str(recording), "--rate", str(rate), "--start-paused", "--json"]
            + ["--topics", *PLAYED],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        try:
            deadline = time.monotonic() + 60
            while not listener.matched():
                assert time.monotonic() < deadline, "the player's publishers never matched"
                time.sleep(0.05)
            go = subprocess.run(
                [*CLI, "param", "set", "player", "paused", "false"],
                env=env,
                capture_output=True,
                text=True,
                timeout=60,
            )
            assert go.returncode == 0, go.stderr
            out, err = player.communicate(timeout=120)
            assert player.returncode == 0, err
            time.sleep(0.2)
        finally:
            if player.poll() is None:
                player.kill()
                player.wait(timeout=10)
            listener.close()
    report = json.loads(out)
    for topic in PLAYED:
        recorded = [data for _, _, data in iter_messages(recording, topics=[topic])]
        received = [data for _, data in listener.got[topic]]
        assert report["published"][topic] == len(recorded)
        assert received == recorded, topic  # every one, in order, byte for byte
    clock = listener.got["/clock"]
    stamps = [int.from_bytes(d[4:8], "little") * 1e9 + int.from_bytes(d[8:12], "little")
              for _, d in clock]  # fmt: skip
    assert np.all(np.diff(stamps) > 0)
    assert report["achieved_rate"] <= rate * 1.02  # never faster than asked
    # the lag it reports is what makes the rate it reports: 0.05 s took (0.05 + lag)/rate
    span = 0.05 * 999 / 1000  # from the first message to the last
    want = rate * span / (span + report["lag_s"])
    assert report["achieved_rate"] == pytest.approx(want, rel=0.05)
    if rate < 1:  # a pace the subscriber keeps up with: its own measure agrees with the report
        arrivals = [t for topic in PLAYED for t, _ in listener.got[topic]]
        measured = 0.05 / (max(arrivals) - min(arrivals))
        assert report["achieved_rate"] == pytest.approx(measured, rel=0.1)


CASES = [
    ("im_short", "mptc"),
    ("im_short", "mptc_db"),
    ("im_short", "db_mptc"),
    ("ipmsm_short", "mptc"),
    ("ipmsm_short", "simplified1"),
    ("ipmsm_short", "simplified2"),
    ("ipmsm_short", "simplified3"),
    ("hs_ipmsm_mtpa_short", "foc_injection"),
]


@pytest.mark.parametrize("scenario, strategy", CASES, ids=[f"{a}-{b}" for a, b in CASES])
def test_replay_into_the_strategy_that_made_it_reproduces_every_command(
    tmp_path, scenario, strategy
):
    from predictive_drive.api.replay import replay_into
    from predictive_drive.readback import read_bag

    rec = tmp_path / "rec"
    run_inprocess_to_bag(load_scenario(scenario, strategy=strategy, duration=0.03), rec)
    d = replay_into(rec, out=tmp_path / "again")
    assert (d.vector_agreement, d.pulse_agreement) == (1.0, 1.0)
    a, _ = read_bag(rec)
    b, info = read_bag(tmp_path / "again")
    assert info.info["engine"] == "replay" and info.info["replay_of"] == str(rec.resolve())
    np.testing.assert_array_equal(a.state, b.state)
    np.testing.assert_array_equal(a.reference, b.reference)
    np.testing.assert_array_equal(a.command[:, :-1], b.command[:, :-1])  # compute_ns aside


def test_replay_into_another_strategy_and_across_a_recorded_switch(tmp_path):
    from predictive_drive.api.replay import replay_into
    from predictive_drive.api.run import run

    rec = tmp_path / "rec"
    run("im_short", duration=0.05, strategy="mptc", switches=[(0.02, "db_mptc")],
        engine="inprocess", out=rec)  # fmt: skip
    same = replay_into(rec, out=tmp_path / "same")  # switched where the recording switched
    assert (same.vector_agreement, same.pulse_agreement) == (1.0, 1.0)
    other = replay_into(rec, strategy="mptc_db", out=tmp_path / "other")
    assert 0.0 < other.pulse_agreement < 1.0 and other.steps == 1000
    assert other.steps_per_s > 0 and other.compute_us_per_step > 0
