"""The torque controller node (``ros2 run predictive_drive torque_controller_node --ros-args
--params-file config/<scenario>.yaml``): state k + reference k → command k, with the control law
of its ``family``; ``strategy`` switches at run time through the standard parameter services."""

from __future__ import annotations

import sys
from dataclasses import dataclass
from typing import Any

from rcl_interfaces.msg import SetParametersResult
from rclpy.duration import Duration
from rclpy.parameter import Parameter

from ..codec import CODECS
from ..config import FAMILY_KEY, controller_device_of, family_of, section_class
from ..core.control import CONTROLLERS, make_controller
from ..core.control.base import SWITCHABLE
from ..core.fields import Quantity, check_fields, quantity
from ..core.scenario import RunParams
from ..core.signals import Reference, State
from ..interface import TOPICS, node_name
from .node_base import WatchedNode, describe, run_main

__all__ = ["TorqueControllerNode", "main"]

_STATE, _REF, _CMD = CODECS["state"], CODECS["reference"], CODECS["command"]


@dataclass(frozen=True)
class CommandReaders:
    """Who must hear command 0 before it goes out."""

    command_readers: int = quantity(
        "subscribers /drive/command must have before command 0 (the plant and the logger; a "
        "replay into this node: the replayer alone)",
        ge=1,
        integer=True,
        default=2,
    )

    def __post_init__(self) -> None:
        check_fields(self)


class TorqueControllerNode(WatchedNode):
    """The inner controller. A ``strategy`` request is validated in the on-set callback (an
    unknown name is refused with the valid ones; the running strategy stays) and applied in the
    post-set callback, so it takes effect at the next step boundary."""

    section = "torque_controller"
    writable = SWITCHABLE

    def __init__(self, **kw: Any) -> None:
        super().__init__("torque_controller", **kw)
        run, params = self.load_params()
        self.links = CommandReaders(**self.declare_fields(CommandReaders))
        self.n = run.steps
        device = controller_device_of(params, self._where())  # the loss-aware cost's
        self.ctrl = make_controller(self.family, params, ts=run.ts, device=device)
        self.pub_cmd = self.publisher("command")
        self.lockstep = [self.pub_cmd]
        self._states: dict[int, State] = {}
        self._refs: dict[int, Reference] = {}
        self._k = 0
        self.sub_state = self.subscription("state", self.on_state)
        self.sub_ref = self.subscription("reference", self.on_reference)
        #: the launcher's scheduled switches (--switch): a strategy request is applied at the
        #: next of these steps instead of at once, so it lands exactly where it was scheduled
        self.schedule = self.declare_switch_steps(
            "a strategy request is applied at the next of them"
        )
        self._deferred: list[tuple[int, str, Any]] = []  #: (step, key, value)
        self.add_on_set_parameters_callback(self.on_set_parameters)
        self.add_post_set_parameters_callback(self.on_parameters_set)

    def section_class(self, run: RunParams) -> tuple[type, dict[str, type]]:
        q = Quantity("controller family (picks the settings below)", choices=tuple(CONTROLLERS))
        value = self.declare_parameter(FAMILY_KEY, None, describe(q, str, read_only=True)).value
        params = {} if value is None else {FAMILY_KEY: value}
        self.family = family_of(params, self._where())
        return section_class(self.section, run.machine, self.family)

    def on_set_parameters(self, params: list[Parameter]) -> SetParametersResult:
        """Validate only: every requested strategy (or horizon) must be one the controller can
        run (:meth:`~..core.control.base.Controller.switch_refusal`)."""
        for p in params:
            if p.name in SWITCHABLE and (reason := self.ctrl.switch_refusal(p.name, p.value)):
                running = getattr(self.ctrl, "horizon" if p.name == "horizon" else "strategy")
                now = running if p.name == "horizon" else running.name
                return SetParametersResult(
                    successful=False, reason=f"{reason} (running {p.name} stays {now})"
                )
        return SetParametersResult(successful=True)

    def on_parameters_set(self, params: list[Parameter]) -> None:
        """Apply an accepted switch: the next command is made by the new strategy (or, with a
        schedule, the command of the next scheduled step)."""
        for p in params:
            if p.name not in SWITCHABLE:
                continue
            if p.value == self._last(p.name):
                continue  # a request sent twice (see the launcher's resend): taken already
            if self.schedule:
                self._deferred.append((self.schedule.pop(0), p.name, p.value))
            else:
                self._switch(p.name, p.value)

    def _last(self, key: str) -> Any:
        """The value ``key`` has or will have once the deferred switches are taken."""
        for _, k, value in reversed(self._deferred):
            if k == key:
                return value
        return self.ctrl.strategy.name if key == "strategy" else self.ctrl.horizon

    def _switch(self, key: str, value: Any) -> None:
        # the same value again (a request sent twice) changes nothing: no new law instance
        now = self.ctrl.strategy.name if key == "strategy" else self.ctrl.horizon
        if value != now:
            self.ctrl.switch(key, value)
            self.get_logger().info(f"{key} → {value} from step {self._k}")

    @property
    def last_step(self) -> int:
        return self._k - 1

    def stalled_message(self) -> str:
        if self.schedule and self.schedule[0] <= self._k:
            return (
                f"no strategy request for the switch scheduled at step {self.schedule[0]} "
                f"(the plant waits there for it)"
            )
        if self._k in self._states:
            return f"no {TOPICS['reference'].name} for step {self._k} from {node_name('speed_pi')}"
        return f"no {TOPICS['state'].name} for step {self._k} from {node_name('plant')}"

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
            self.progressed(started=k > 0)
            state = self._states.pop(k)
            ref = self._refs.pop(k)
            if k >= self.n:
                self.finished = True
                return
            while self._deferred and self._deferred[0][0] <= k:
                self._switch(*self._deferred.pop(0)[1:])
            if k == 0:
                self.wait_matched(self.pub_cmd, self.links.command_readers, "its readers")
            self.pub_cmd.publish(_CMD.encode(self.ctrl.step(state, ref)))
            self._k = k + 1
            if self._k == self.n:
                self.pub_cmd.wait_for_all_acked(Duration(seconds=self.peer_timeout))


def main(args: list[str] | None = None) -> int:
    return run_main(TorqueControllerNode, args)


if __name__ == "__main__":
    sys.exit(main())
