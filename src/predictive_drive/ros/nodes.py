"""The four drive nodes. Each: declare parameters from the scenario dataclasses, build the core
object, create publishers/subscriptions; callbacks unpack → core → pack → publish.

Lock-step (SPEC §5): the plant publishes state k; the speed PI answers with the reference for k+1
(and the initial reference 0 with state 0); the controller answers state k + reference k with
command k; the plant applies it and publishes state k+1. The logger records everything.
"""

from __future__ import annotations

import struct
import time
from pathlib import Path
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.duration import Duration

from ..bag import BagWriter
from ..config import NAMESPACE, resolve_scenario_path
from ..core.control import strategy_names
from ..core.runner import build_controller, build_plant
from ..core.signals import Command, Reference, State
from ..core.speed_pi import SpeedPI
from ..interface import CODECS, TOPICS
from ..recording import RunRecorder, tool_every, tool_messages
from .common import DriveNode
from .graph import LAUNCHER_NODE

__all__ = ["MetricsLoggerNode", "PlantNode", "SpeedPINode", "TorqueControllerNode"]

_STATE, _REF, _CMD = CODECS["state"], CODECS["reference"], CODECS["command"]


class _Watched(DriveNode):
    """A lock-step node that fails when the message it waits for does not come in time."""

    waiting_for = ""

    def __init__(self, name: str, **kw: Any) -> None:
        super().__init__(name, **kw)
        self._last_progress = time.monotonic()
        self._started = False

    def progressed(self) -> None:
        self._last_progress = time.monotonic()
        self._started = True

    def check(self) -> None:
        if self.finished or self.failure:
            return
        limit = self.peer_timeout if self._started else self.startup_timeout
        if time.monotonic() - self._last_progress > limit:
            self.fail(
                f"{self.get_fully_qualified_name()}: {self.stalled_message()} within {limit} s"
            )

    def stalled_message(self) -> str:
        return f"no message from {self.waiting_for}"


class PlantNode(_Watched):
    """Motor + inverter + load. Publishes /drive/state every step, /clock and /drive/joint_states
    decimated to 1 kHz of simulated time."""

    section = "plant"
    waiting_for = "/drive/torque_controller on /drive/command"

    def __init__(self, **kw: Any) -> None:
        super().__init__("plant", **kw)
        run, params = self.load_params()
        self.n = run.steps
        self.plant = build_plant(params, ts=run.ts)
        self._every = tool_every(run.ts)
        self.pub_state = self.publisher("state")
        self.pub_clock = self.publisher("clock")
        self.pub_joint = self.publisher("joint_states")
        self.sub_cmd = self.subscription("command", self.on_command)
        self.await_launcher = self.declare_parameter(
            "await_launcher",
            False,
            ParameterDescriptor(
                description="step 0 also waits for the launcher's /clock subscription (it "
                "follows progress and sends timed strategy switches)",
                read_only=True,
            ),
        ).value
        self.k_started = False

    def _not_listening(self) -> list[str]:
        """Who step 0 still waits for: speed_pi, torque_controller, metrics_logger (and the
        launcher when ``await_launcher``)."""
        missing = []
        if self.pub_state.get_subscription_count() < 3:
            missing.append("3 subscribers of /drive/state")
        if self.pub_joint.get_subscription_count() < 1:
            missing.append("the logger's /drive/joint_states subscription")
        if self.await_launcher and not any(
            (i.node_namespace, i.node_name) == (NAMESPACE, LAUNCHER_NODE)
            for i in self.get_subscriptions_info_by_topic(TOPICS["clock"].name)
        ):
            missing.append(f"the launcher's /clock subscription ({NAMESPACE}/{LAUNCHER_NODE})")
        if self.count_publishers("/drive/command") < 1:
            missing.append("a /drive/command publisher")
        return missing

    def check(self) -> None:
        if not self.k_started and not self._not_listening():
            self.k_started = True
            self.progressed()
            self.publish_state(self.plant.state())
            return
        super().check()

    def publish_state(self, state: State) -> None:
        self.pub_state.publish(_STATE.encode(state))
        for key, _ns, data in tool_messages(state, self._every):
            (self.pub_clock if key == "clock" else self.pub_joint).publish(data)
        if int(state.k) >= self.n:
            for p in (self.pub_state, self.pub_clock, self.pub_joint):
                p.wait_for_all_acked(Duration(seconds=self.peer_timeout))
            self.finished = True

    def stalled_message(self) -> str:
        if not self.k_started:
            return f"step 0 still waits for {', '.join(self._not_listening())}"
        return f"no /drive/command for step {self.plant.k} from /drive/torque_controller"

    def on_command(self, data: bytes) -> None:
        cmd = Command(*_CMD.decode(data))
        self.progressed()
        self.publish_state(self.plant.step(cmd))


class SpeedPINode(_Watched):
    """Speed PI: state k → reference k+1 (the documented one-sample delay)."""

    section = "speed_pi"

    def __init__(self, **kw: Any) -> None:
        super().__init__("speed_pi", **kw)
        run, params = self.load_params()
        self.n = run.steps
        self.pi = SpeedPI(params, ts=run.ts)
        self.pub_ref = self.publisher("reference")
        self.sub_state = self.subscription("state", self.on_state)
        self._next = 0

    def stalled_message(self) -> str:
        return f"no /drive/state for step {self._next} from /drive/plant"

    def on_state(self, data: bytes) -> None:
        state = State(*_STATE.decode(data))
        self.progressed()
        k = int(state.k)
        self._next = k + 1
        if k == 0:
            # controller and logger must hear reference 0
            self.wait_matched(self.pub_ref, 2, "torque_controller, metrics_logger")
            self.pub_ref.publish(_REF.encode(self.pi.initial()))
        if k < self.n:
            self.pub_ref.publish(_REF.encode(self.pi.step(state)))
        else:
            self.pub_ref.wait_for_all_acked(Duration(seconds=self.peer_timeout))
            self.finished = True


class TorqueControllerNode(_Watched):
    """Predictive torque controller; ``strategy`` switches at run time through the parameter
    services (validated; takes effect at the next step boundary)."""

    section = "torque_controller"

    def __init__(self, **kw: Any) -> None:
        super().__init__("torque_controller", **kw)
        run, params = self.load_params()
        self.n = run.steps
        self.ctrl = build_controller(params, ts=run.ts)
        self.machine = run.machine
        self.pub_cmd = self.publisher("command")
        self._states: dict[int, State] = {}
        self._refs: dict[int, Reference] = {}
        self._k = 0
        self.sub_state = self.subscription("state", self.on_state)
        self.sub_ref = self.subscription("reference", self.on_reference)
        self.add_on_set_parameters_callback(self.on_set_parameters)

    def on_set_parameters(self, params: list[Any]) -> SetParametersResult:
        for p in params:
            if p.name == "strategy":
                names = strategy_names(self.machine)
                if p.value not in names:
                    return SetParametersResult(
                        successful=False,
                        reason=f"unknown strategy {p.value!r} for machine {self.machine!r}; "
                        f"valid: {', '.join(names)} (running strategy stays "
                        f"{self.ctrl.strategy.name})",
                    )
                self.ctrl.set_strategy(p.value)
                self.get_logger().info(f"strategy → {p.value} from step {self._k}")
        return SetParametersResult(successful=True)

    def stalled_message(self) -> str:
        if self._k in self._states:
            return f"no /drive/torque_reference for step {self._k} from /drive/speed_pi"
        return f"no /drive/state for step {self._k} from /drive/plant"

    def on_state(self, data: bytes) -> None:
        s = State(*_STATE.decode(data))
        self._states[int(s.k)] = s
        self._try()

    def on_reference(self, data: bytes) -> None:
        r = Reference(*_REF.decode(data))
        self._refs[int(r.k)] = r
        self._try()

    def _try(self) -> None:
        k = self._k
        if k in self._states and k in self._refs:
            self.progressed()
            state = self._states.pop(k)
            ref = self._refs.pop(k)
            if k >= self.n:
                self.finished = True
                return
            if k == 0:
                self.wait_matched(self.pub_cmd, 2, "plant, metrics_logger")
            self.pub_cmd.publish(_CMD.encode(self.ctrl.step(state, ref)))
            self._k = k + 1
            if self._k == self.n:
                self.pub_cmd.wait_for_all_acked(Duration(seconds=self.peer_timeout))


class MetricsLoggerNode(_Watched):
    """Records every topic of the run (raw bytes, no decode on the hot path but the metrics'),
    publishes running metrics on /diagnostics, closes the bag cleanly on any ending."""

    section = "metrics_logger"
    EXTRA = {
        "bag": "bag directory to write (default bags/<scenario>_<strategy>_<time>)",
        "strategy": "the controller's starting strategy (for the bag's metadata)",
        "scenario_file": "scenario file to store in the bag (default config/<scenario>.yaml)",
    }

    def __init__(self, **kw: Any) -> None:
        super().__init__("metrics_logger", **kw)
        run, self.params = self.load_params()

        extra = {
            k: self.declare_parameter(
                k, "", ParameterDescriptor(description=d, read_only=True)
            ).value
            for k, d in self.EXTRA.items()
        }
        path = resolve_scenario_path(extra["scenario_file"] or run.scenario)
        text = path.read_text()
        from ..api import bag_info, default_bag_dir, prepare

        sc, _ = prepare(path, strategy=extra["strategy"] or None, duration=run.duration)
        self.n = run.steps
        out = Path(extra["bag"]) if extra["bag"] else default_bag_dir(sc)
        self.writer = BagWriter(out, info=bag_info(sc, text, "ros"))
        self.pub_diag = self.publisher("diagnostics")
        self.rec = RunRecorder(
            self.writer,
            ts=run.ts,
            torque_limit=sc.speed_pi.torque_limit,
            strategy_names=strategy_names(run.machine),
            record_tools=False,
            publish=self._publish_diagnostics,
        )
        ticks = self.n // tool_every(run.ts) + 1
        self._counts = {"state": 0, "reference": 0, "command": 0, "clock": 0, "joint_states": 0}
        self._need = {
            "state": self.n + 1,
            "reference": self.n + 1,
            "command": self.n,
            "clock": ticks,
            "joint_states": ticks,
        }
        # tool topics first: the plant starts once it sees this node's /drive/state subscription
        self.subs = [
            self.subscription(key, lambda d, key=key: self.on_tool(key, d))
            for key in ("clock", "joint_states")
        ] + [
            self.subscription(rec, lambda d, rec=rec: self.on_record(rec, d))
            for rec in ("state", "reference", "command")
        ]
        self.get_logger().info(f"recording to {out}")
        self._closed = False

    def _publish_diagnostics(self, _key: str, data: bytes) -> None:
        if self.context.ok():  # not while shutting down: the recording matters more
            self.pub_diag.publish(data)

    def stalled_message(self) -> str:
        missing = [r for r, c in self._counts.items() if c < self._need[r]]
        return (
            f"recording stalled: waiting for {', '.join('/drive/' + m for m in missing)} "
            f"(state {self._counts['state']}/{self._need['state']})"
        )

    def on_record(self, rec: str, data: bytes) -> None:
        self.progressed()
        self.rec.record_raw(rec, data)
        self._counts[rec] += 1
        self._maybe_done()

    def _maybe_done(self) -> None:
        if self._counts == self._need:
            self.close()
            self.finished = True

    def on_tool(self, key: str, data: bytes) -> None:
        sec, nsec = struct.unpack_from("<iI", data, 4)
        self.writer.write(key, sec * 1_000_000_000 + nsec, data)
        self._counts[key] += 1
        self._maybe_done()

    def fail(self, message: str) -> None:
        super().fail(message)
        self._publish_diagnostics("diagnostics", self.rec.error(message))
        self.close()

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            try:
                self.rec.finish()
            finally:
                self.writer.close()
            self.get_logger().info(
                f"bag closed: {self.writer.directory} ({self.writer.message_count} messages)"
            )


NODE_CLASSES = {
    "plant": PlantNode,
    "speed_pi": SpeedPINode,
    "torque_controller": TorqueControllerNode,
    "metrics_logger": MetricsLoggerNode,
}
