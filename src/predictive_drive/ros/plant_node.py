"""The plant node: motor + inverter + load (``ros2 run predictive_drive plant_node --ros-args
--params-file config/<scenario>.yaml``).

Lock-step (docs/ros.md): publishes state k, applies command k for Ts, publishes state k+1; with
``plant.losses`` on, /drive/losses k right after state k; /clock and /drive/joint_states decimated
to 1 kHz of simulated time. Back-pressure: it runs at most
:data:`~predictive_drive.interface.RECORDING_WINDOW` steps ahead of what the recorder says it has
written (/drive/recorded); a state beyond that is held until the recorder catches up, and a
recorder silent for ``peer_timeout`` while the drive waits ends the run, named. Scheduled
switches (``switch_steps``): state k waits until the torque controller has taken every switch
scheduled at or before k (seen on /parameter_events), so a ``--switch`` lands exactly.
"""

from __future__ import annotations

import sys
import time
from typing import Any

from rcl_interfaces.msg import ParameterDescriptor
from rclpy.duration import Duration

from ..codec import CODECS, command_for_step
from ..config import device_of
from ..core.commands import CommandError
from ..core.control.base import SWITCHABLE
from ..core.runner import build_plant
from ..core.signals import State
from ..interface import LAUNCHER_NODE, NAMESPACE, RECORDING_WINDOW, TOPICS, node_name
from ..recording import tool_every, tool_messages
from .node_base import WatchedNode, run_main
from .transport import qos

__all__ = ["PlantNode", "main"]

_STATE, _LOSSES, _RECORDED = CODECS["state"], CODECS["losses"], CODECS["recorded"]


class PlantNode(WatchedNode):
    """Motor + inverter + load. Step 0 goes out once every peer listens."""

    patience = 0.25  #: see WatchedNode.patience
    start_patience = 0.0

    section = "plant"

    def __init__(self, **kw: Any) -> None:
        super().__init__("plant", **kw)
        run, params = self.load_params()
        self.n = run.steps
        device = device_of(params, self._where())  # the file plant.losses.device names
        self.plant = build_plant(run.machine, params, ts=run.ts, device=device)
        self._every = tool_every(run.ts)
        self.pub_state = self.publisher("state")
        self.pub_clock = self.publisher("clock")
        self.pub_joint = self.publisher("joint_states")
        self.lockstep = [self.pub_state, self.pub_clock, self.pub_joint]
        #: /drive/losses, a plant that books its losses only
        self.pub_losses = self.publisher("losses") if self.plant.losses() is not None else None
        if self.pub_losses is not None:
            self.lockstep.append(self.pub_losses)
        self.sub_cmd = self.subscription("command", self.on_command)
        self.sub_recorded = self.subscription("recorded", self.on_recorded)
        self.recorded = -1  #: every step up to this one is in the bag
        self._recorded_at = time.monotonic()
        self.held: State | None = None  #: a state not yet published (see _may_publish)
        self._held_since = time.monotonic()
        self.await_launcher = self.declare_parameter(
            "await_launcher",
            False,
            ParameterDescriptor(
                description="step 0 also waits for the launcher's /clock subscription (it "
                "follows progress and sends timed strategy switches)",
                read_only=True,
            ),
        ).value
        #: scheduled strategy switches (--switch): state k is not published before the torque
        #: controller has taken every switch scheduled at or before k
        self.switch_steps = self.declare_switch_steps(
            "the plant waits at each until /drive/torque_controller has taken it"
        )
        self.switches_taken = 0
        self._seen: dict[str, Any] = {}  #: the last strategy (horizon) the controller announced
        if self.switch_steps:
            from rcl_interfaces.msg import ParameterEvent

            # rclpy's own parameter events, over DDS in every engine
            events = TOPICS["parameter_events"]
            self.sub_events = self.create_subscription(
                ParameterEvent, events.name, self.on_parameter_event, qos(events.qos)
            )
        self.k_started = False
        self.published = -1  #: the last state published

    def _not_listening(self) -> list[str]:
        """Who step 0 still waits for, by node, and what of each: speed_pi, torque_controller,
        metrics_logger (and the launcher when ``await_launcher``)."""
        waits: dict[str, list[str]] = {}

        def lacks(node: str, what: str) -> None:
            waits.setdefault(node_name(node), []).append(what)

        state, clock = TOPICS["state"].name, TOPICS["clock"].name
        if self.pub_state.get_subscription_count() < 3:
            there = self._nodes_on(self.get_subscriptions_info_by_topic(state))
            absent = [
                n for n in ("speed_pi", "torque_controller", "metrics_logger") if n not in there
            ]
            for n in absent:
                lacks(n, f"no {state} subscription")
            if not absent:  # nodes of other names (not started as the graph's): by count
                waits[f"3 subscribers of {state}"] = []
        if self.pub_joint.get_subscription_count() < 1:
            lacks("metrics_logger", f"no {TOPICS['joint_states'].name} subscription")
        if self.pub_losses is not None and self.pub_losses.get_subscription_count() < 1:
            lacks("metrics_logger", f"no {TOPICS['losses'].name} subscription")
        if self.await_launcher and LAUNCHER_NODE not in self._nodes_on(
            self.get_subscriptions_info_by_topic(clock)
        ):
            lacks(LAUNCHER_NODE, f"no {clock} subscription")
        if self.count_publishers(TOPICS["command"].name) < 1:
            lacks("torque_controller", f"no {TOPICS['command'].name} publisher")
        return [f"{who} ({', '.join(what)})" if what else who for who, what in waits.items()]

    @staticmethod
    def _nodes_on(infos: list[Any]) -> set[str]:
        """The names of this graph's nodes (namespace /drive) among a topic's endpoints."""
        return {i.node_name for i in infos if i.node_namespace == NAMESPACE}

    def check(self) -> None:
        if not self.k_started and not self._not_listening():
            self.k_started = True
            # command 0 is still start-up (startup_timeout): a controller may be finishing its
            # discovery of the recorder; the peer timeout counts from command 0 on
            self.resumed()
            self._offer(self.plant.state())
            return
        held = self.held
        if held is None:
            super().check()
            return
        if self.failure:
            return
        k = int(held.k)
        now = time.monotonic()
        if not self._switched(k) and now - self._held_since > self.peer_timeout:
            self.fail(
                f"{self.get_fully_qualified_name()}: the strategy switch scheduled at step "
                f"{self.switch_steps[self.switches_taken]} was not taken by "
                f"{node_name('torque_controller')} within {self.peer_timeout} s"
            )
        elif not self._recording_allows(k) and now - self._recorded_at > self.peer_timeout:
            self.fail(
                f"{self.get_fully_qualified_name()}: the recorder {node_name('metrics_logger')} "
                f"has written every step up to {self.recorded} and said nothing on "
                f"{TOPICS['recorded'].name} for {self.peer_timeout} s; the drive waits at step "
                f"{k} (at most {RECORDING_WINDOW} steps ahead of the recording): the recorder "
                f"is stalled"
            )

    def resumed(self) -> None:
        super().resumed()
        self._recorded_at = self._held_since = time.monotonic()

    def _recording_allows(self, k: int) -> bool:
        """Back-pressure: the recording is at most RECORDING_WINDOW steps behind."""
        return k - self.recorded <= RECORDING_WINDOW

    def _switched(self, k: int) -> bool:
        """Every switch scheduled at or before step k has been taken by the controller."""
        due = self.switches_taken < len(self.switch_steps)
        return not (due and self.switch_steps[self.switches_taken] <= k)

    def _offer(self, state: State) -> None:
        """Publish state k now, or hold it until the recorder and the scheduled switches allow."""
        k = int(state.k)
        if self._recording_allows(k) and self._switched(k):
            self.publish_state(state)
        else:
            if not self._switched(k):
                self.get_logger().info(
                    f"state {k} waits for the strategy switch scheduled at step "
                    f"{self.switch_steps[self.switches_taken]}"
                )
            self.held = state
            self._held_since = time.monotonic()

    def _release(self) -> None:
        held = self.held
        if held is not None and self._recording_allows(int(held.k)) and self._switched(int(held.k)):
            self.held = None
            self.progressed()
            self.publish_state(held)

    def on_recorded(self, data: bytes) -> None:
        self.recorded = int(_RECORDED.decode(data)[0])
        self._recorded_at = time.monotonic()
        self._release()

    def on_parameter_event(self, event: Any) -> None:
        if event.node != node_name("torque_controller"):
            return
        for p in event.changed_parameters:
            # a request sent twice sets the same value twice: one switch
            value = p.value.string_value if p.name == "strategy" else p.value.integer_value
            if p.name in SWITCHABLE and value != self._seen.get(p.name):
                self._seen[p.name] = value
                self.switches_taken += 1
        self._release()

    def publish_state(self, state: State) -> None:
        """State k, its losses (the plant is at k until command k comes) and tool messages."""
        self.pub_state.publish(_STATE.encode(state))
        if self.pub_losses is not None:
            self.pub_losses.publish(_LOSSES.encode(self.plant.losses()))  # type: ignore[arg-type]
        self.published = int(state.k)
        for key, _ns, data in tool_messages(state, self._every):
            (self.pub_clock if key == "clock" else self.pub_joint).publish(data)
        if int(state.k) >= self.n:
            for p in self.lockstep:
                p.wait_for_all_acked(Duration(seconds=self.peer_timeout))
            self.finished = True

    @property
    def last_step(self) -> int:
        """The last state published (a state held for the recorder or a switch is not)."""
        return self.published

    def stalled_message(self) -> str:
        if not self.k_started:
            return f"step 0 still waits for {', '.join(self._not_listening())}"
        return (
            f"no {TOPICS['command'].name} for step {self.plant.k} from "
            f"{node_name('torque_controller')}"
        )

    def on_command(self, data: bytes) -> None:
        """Command k in whichever form the controller gives it (built-in: the fast path); a
        command that cannot be applied ends the run, naming the field and the step."""
        plant = self.plant
        try:
            cmd = command_for_step(data, k=plant.k, t=plant.k * plant.ts, u_dc=self._u_dc)
        except CommandError as e:
            self._refuse(str(e))
            return
        self.progressed()
        self._offer(plant.step(cmd))

    def _u_dc(self) -> float:
        return float(self.plant.u_dc)

    def _refuse(self, why: str) -> None:
        """A command the plant cannot apply ends the run (docs/ros.md#writing-your-own-controller)."""
        self.fail(
            f"{node_name('plant')}: refused {TOPICS['command'].name} from "
            f"{node_name('torque_controller')}: {why}"
        )


def main(args: list[str] | None = None) -> int:
    return run_main(PlantNode, args)


if __name__ == "__main__":
    sys.exit(main())
