"""The plant node: motor + inverter + load (``ros2 run predictive_drive plant_node --ros-args
--params-file config/<scenario>.yaml``).

Lock-step (SPEC §5): publishes state k, applies command k for Ts, publishes state k+1; /clock and
/drive/joint_states decimated to 1 kHz of simulated time.
"""

from __future__ import annotations

import sys
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.duration import Duration

from ..core.runner import build_plant
from ..core.signals import Command, State
from ..interface import CODECS, LAUNCHER_NODE, NAMESPACE, TOPICS, node_name
from ..recording import tool_every, tool_messages
from .node_base import WatchedNode, run_main

__all__ = ["PlantNode", "main"]

_STATE, _CMD = CODECS["state"], CODECS["command"]


class PlantNode(WatchedNode):
    """Motor + inverter + load. Step 0 goes out once every peer listens."""

    section = "plant"

    def __init__(self, **kw: Any) -> None:
        super().__init__("plant", **kw)
        run, params = self.load_params()
        self.n = run.steps
        self.plant = build_plant(run.machine, params, ts=run.ts)
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
            missing.append(f"3 subscribers of {TOPICS['state'].name}")
        if self.pub_joint.get_subscription_count() < 1:
            missing.append(f"the logger's {TOPICS['joint_states'].name} subscription")
        if self.await_launcher and not any(
            (i.node_namespace, i.node_name) == (NAMESPACE, LAUNCHER_NODE)
            for i in self.get_subscriptions_info_by_topic(TOPICS["clock"].name)
        ):
            missing.append(
                f"the launcher's {TOPICS['clock'].name} subscription ({node_name(LAUNCHER_NODE)})"
            )
        if self.count_publishers(TOPICS["command"].name) < 1:
            missing.append(f"a {TOPICS['command'].name} publisher")
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
        return (
            f"no {TOPICS['command'].name} for step {self.plant.k} from "
            f"{node_name('torque_controller')}"
        )

    def on_command(self, data: bytes) -> None:
        cmd = Command(*_CMD.decode(data))
        self.progressed()
        self.publish_state(self.plant.step(cmd))


def main(args: list[str] | None = None) -> int:
    return run_main(PlantNode, args)


if __name__ == "__main__":
    sys.exit(main())
