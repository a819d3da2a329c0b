"""The speed PI node: state k → reference k+1, the documented one-sample delay, or reference k
with ``speed_loop: immediate`` (``ros2 run predictive_drive speed_pi_node --ros-args
--params-file config/<scenario>.yaml``)."""

from __future__ import annotations

import sys
from typing import Any

from rclpy.duration import Duration

from ..codec import CODECS
from ..core.control.speed_pi import SpeedPI
from ..core.signals import State
from ..interface import TOPICS, node_name
from .node_base import WatchedNode, run_main

__all__ = ["SpeedPINode", "main"]

_STATE, _REF = CODECS["state"], CODECS["reference"]


class SpeedPINode(WatchedNode):
    """Speed PI: answers state k with the reference for k+1 (and state 0 also with reference 0),
    or, with ``speed_loop: immediate``, with the reference for k (the controller waits for it)."""

    patience = 0.5  #: see WatchedNode.patience

    section = "speed_pi"

    def __init__(self, **kw: Any) -> None:
        super().__init__("speed_pi", **kw)
        run, params = self.load_params()
        self.n = run.steps
        self.pi = SpeedPI(params, ts=run.ts)
        self.pub_ref = self.publisher("reference")
        self.lockstep = [self.pub_ref]
        self.sub_state = self.subscription("state", self.on_state)
        self._next = 0

    @property
    def last_step(self) -> int:
        return self._next - 1

    def stalled_message(self) -> str:
        return f"no {TOPICS['state'].name} for step {self._next} from {node_name('plant')}"

    def on_state(self, data: bytes) -> None:
        state = State(*_STATE.decode(data))
        k = int(state.k)
        self.progressed(started=k > 0)
        self._next = k + 1
        if k == 0:
            # controller and logger must hear reference 0
            self.wait_matched(self.pub_ref, 2, "torque_controller, metrics_logger")
            if not self.pi.immediate:
                self.pub_ref.publish(_REF.encode(self.pi.initial()))
        if k < self.n or self.pi.immediate:
            self.pub_ref.publish(_REF.encode(self.pi.step(state)))
        if k == self.n:
            self.pub_ref.wait_for_all_acked(Duration(seconds=self.peer_timeout))
            self.finished = True


def main(args: list[str] | None = None) -> int:
    return run_main(SpeedPINode, args)


if __name__ == "__main__":
    sys.exit(main())
