"""The live view (`run --live`): a Foxglove WebSocket client connects, subscribes and decodes what
the drive serves; the strategy is a parameter it can read and set."""

from __future__ import annotations

import os
import re
import signal
import socket
import subprocess
import sys
import time

import numpy as np
import pytest

from predictive_drive.codec import CODECS, encode_clock, stamp_ns
from predictive_drive.errors import ConfigError
from predictive_drive.interface import TOPICS
from predictive_drive.readback import read_bag

pytest.importorskip("foxglove")
from foxglove_client import FoxgloveClient  # noqa: E402
from procs import signal_tree, wait_until  # noqa: E402

STRATEGY = "/drive/torque_controller.strategy"
CLI = [sys.executable, "-m", "predictive_drive.cli"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


@pytest.mark.core
def test_the_view_speaks_foxglove_sdk_v1_only():
    """What docs/ros.md tells users of Foxglove and Lichtblick: the handshake accepts the
    ``foxglove.sdk.v1`` subprotocol (also when a client offers it beside the older one) and
    refuses a client that offers only ``foxglove.websocket.v1`` with HTTP 400."""
    import websocket

    from predictive_drive.live import LiveView

    view = LiveView(port=free_port(), ts=50e-6, strategy="mptc", strategy_names=("mptc",))
    try:
        for offered in (["foxglove.sdk.v1"], ["foxglove.websocket.v1", "foxglove.sdk.v1"]):
            ws = websocket.create_connection(view.url, subprotocols=offered, timeout=5)
            assert ws.getsubprotocol() == "foxglove.sdk.v1"
            ws.close()
        with pytest.raises(websocket.WebSocketBadStatusException) as e:
            websocket.create_connection(view.url, subprotocols=["foxglove.websocket.v1"], timeout=5)
        assert e.value.status_code == 400
    finally:
        view.close()


@pytest.mark.core
def test_the_view_serves_decimated_topics_time_and_the_strategy():
    from predictive_drive.live import LiveView

    asked = []
    view = LiveView(
        port=free_port(),
        ts=50e-6,
        strategy="mptc",
        strategy_names=("mptc", "mptc_db", "db_mptc"),
        set_strategy=asked.append,
    )
    client = FoxgloveClient(view.url)
    try:
        got = client.pump(5, until=lambda g: len(g.channels) >= 8)
        by_topic = {ch["topic"]: ch for ch in got.channels.values()}
        state = by_topic["/drive/state"]
        assert (state["encoding"], state["schemaEncoding"]) == ("cdr", "ros2msg")
        assert state["schemaName"] == "std_msgs/msg/Float64MultiArray"
        assert (
            "Capability" not in str(got.server_info) and "time" in got.server_info["capabilities"]
        )
        client.subscribe(["/drive/state", "/clock"])
        wait_until(
            lambda: all(view._channels[c].has_sinks() for c in ("state", "clock")),
            "the subscription never reached the server",
            timeout=10,
            every=0.01,
        )
        fields = TOPICS["state"].fields
        for k in range(100):
            t = k * 50e-6
            row = tuple(float(k) if f == "k" else t if f == "t" else 0.5 for f in fields)
            view.offer("state", stamp_ns(t), CODECS["state"].encode(row))
            if k % 20 == 0:
                view.offer("clock", stamp_ns(t), encode_clock(t))
        got = client.pump(5, until=lambda g: len(g.messages.get("/drive/state", [])) >= 5)
        ks = [CODECS["state"].decode(d)[0] for _, d in got.messages["/drive/state"]]
        assert ks == [0.0, 20.0, 40.0, 60.0, 80.0]  # one message per ms of simulated time
        assert [ns for ns, _ in got.messages["/drive/state"]] == [
            k * 50_000 for k in range(0, 100, 20)
        ]
        client.pump(1, until=lambda g: len(g.times) >= 5)
        assert got.times == [k * 50_000 for k in range(0, 100, 20)]  # /clock is the app's time

        client.get_parameters([STRATEGY], "g1")
        got = client.pump(5, until=lambda g: g.parameters)
        assert got.parameters[0]["parameters"] == [{"name": STRATEGY, "value": "mptc"}]
        client.subscribe_parameters([STRATEGY])
        client.set_parameters({STRATEGY: "dtc"}, "s1")
        client.pump(5, until=lambda g: g.statuses)
        assert "valid: mptc, mptc_db, db_mptc" in got.statuses[0]["message"]
        client.set_parameters({STRATEGY: "db_mptc"}, "s2")
        client.pump(5, until=lambda g: asked)
        assert asked == ["db_mptc"]
        view.strategy_changed("db_mptc")  # what the controller's parameter event brings
        client.pump(5, until=lambda g: g.parameters[-1]["parameters"][0]["value"] == "db_mptc")
        assert got.parameters[-1]["parameters"] == [{"name": STRATEGY, "value": "db_mptc"}]
    finally:
        client.close()
        view.close()


@pytest.mark.core
def test_a_port_in_use_is_refused_before_the_run(tmp_path):
    from predictive_drive.api.run import run

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        s.listen()
        port = s.getsockname()[1]
        with pytest.raises(ConfigError, match=rf"--live {port}: cannot serve on 127.0.0.1:{port}"):
            run("im_short", engine="inprocess", live=port, out=tmp_path / "b")
    assert not (tmp_path / "b").exists()


def close_and_stop(client: FoxgloveClient | None, p: subprocess.Popen[str]) -> str:
    """The client gone, Ctrl-C to the run; its stderr (SIGKILL to all of it if it hangs)."""
    if client is not None:
        client.close()
    os.kill(p.pid, signal.SIGINT)
    try:
        return p.communicate(timeout=60)[1]
    except subprocess.TimeoutExpired:
        signal_tree(p.pid, signal.SIGKILL)
        p.communicate(timeout=10)
        raise


@pytest.mark.process
def test_a_client_watches_the_graph_and_switches_its_strategy(tmp_path):
    """`run --live PORT` on the ROS graph: a client connects, receives the drive's topics and
    /clock, sets the strategy; the controller takes it (the commands show it, the bag records
    the parameter event), then Ctrl-C ends the run with a readable bag."""
    port = free_port()
    bag = tmp_path / "live"
    said: list[str] = []  # what the run said before the graph started
    p = subprocess.Popen(
        [*CLI, "run", "im_short", "--duration", "30", "--strategy", "mptc",
         "--live", str(port), "--out", str(bag)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    client = None
    try:
        while "ROS_DOMAIN_ID=" not in (line := p.stderr.readline()):
            assert line, "the run ended before it started the graph"
            said.append(line)
        domain = re.search(r"ROS_DOMAIN_ID=(\d+)", line).group(1)
        client = FoxgloveClient(f"ws://127.0.0.1:{port}", timeout=60)
        got = client.pump(10, until=lambda g: len(g.channels) >= 8)
        client.subscribe(["/drive/state", "/drive/command", "/clock", "/diagnostics"])
        client.pump(20, until=lambda g: len(g.messages.get("/drive/command", [])) > 50)
        client.subscribe_parameters([STRATEGY])
        client.set_parameters({STRATEGY: "db_mptc"}, "s1")
        names = ("mptc", "mptc_db", "db_mptc")
        strategy = TOPICS["command"].fields.index("strategy")

        def switched(g):
            return any(
                CODECS["command"].decode(d)[strategy] == names.index("db_mptc")
                for _, d in g.messages.get("/drive/command", [])[-20:]
            )

        t0 = time.monotonic()
        client.pump(20, until=switched)
        assert switched(got)
        print(f"switch seen in the commands {time.monotonic() - t0:.2f} s after the set")
        updated = [{"name": STRATEGY, "value": "db_mptc"}]
        client.pump(20, until=lambda g: any(par["parameters"] == updated for par in g.parameters))
        assert any(par["parameters"] == updated for par in got.parameters)
        # a switch from outside (another shell's `param set`) reaches the app too
        outside = subprocess.run(
            [*CLI, "param", "set", "torque_controller", "strategy", "mptc_db",
             "--timeout", "30"],
            env={**os.environ, "ROS_DOMAIN_ID": domain},
            capture_output=True, text=True, timeout=60,
        )  # fmt: skip
        assert outside.returncode == 0, outside.stderr
        updated = [{"name": STRATEGY, "value": "mptc_db"}]
        client.pump(20, until=lambda g: any(par["parameters"] == updated for par in g.parameters))
        assert any(par["parameters"] == updated for par in got.parameters)
        states = [CODECS["state"].decode(d) for _, d in got.messages["/drive/state"]]
        ks = np.array([s[0] for s in states])
        assert np.all(ks % 20 == 0) and np.all(np.diff(ks) > 0)
        assert len(got.times) > 10 and np.all(np.diff(got.times) > 0)
        client.pump(20, until=lambda g: "/diagnostics" in g.messages)
        assert got.messages["/diagnostics"]
    finally:
        err = close_and_stop(client, p)
    assert p.returncode == 130, err
    assert re.search(rf"live view on ws://127.0.0.1:{port}", "".join(said) + err)
    tr, info = read_bag(bag)
    assert info.complete
    assert [e.changed for _, e in info.events] == [
        (("strategy", "db_mptc"),),
        (("strategy", "mptc_db"),),
    ]


@pytest.mark.process
def test_in_process_the_strategy_is_shown_and_read_only(tmp_path):
    """`run --engine inprocess --live PORT`: the app reads the strategy, and a set is refused
    with the reason (the in-process loop has no parameter to take it); the run goes on."""
    port = free_port()
    bag = tmp_path / "inproc"
    p = subprocess.Popen(
        [*CLI, "run", "im_short", "--engine", "inprocess", "--duration", "30",
         "--strategy", "mptc_db", "--live", str(port), "--out", str(bag)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )  # fmt: skip
    client = None
    try:
        client = FoxgloveClient(f"ws://127.0.0.1:{port}", timeout=60)
        client.subscribe_parameters([STRATEGY])
        client.get_parameters([STRATEGY], "g1")
        got = client.pump(10, until=lambda g: g.parameters)
        assert got.parameters[0]["parameters"] == [{"name": STRATEGY, "value": "mptc_db"}]
        client.set_parameters({STRATEGY: "db_mptc"}, "s1")
        client.pump(10, until=lambda g: g.statuses)
        assert got.statuses[0]["message"] == f"{STRATEGY} is read-only in this engine"
        assert got.parameters[-1]["parameters"] == [{"name": STRATEGY, "value": "mptc_db"}]
        assert p.poll() is None
    finally:
        err = close_and_stop(client, p)
    assert p.returncode == 130, err
    tr, info = read_bag(bag)
    assert not info.events and tr.steps > 0
    assert set(tr.col("command", "strategy").astype(int)) == {1}  # mptc_db throughout
