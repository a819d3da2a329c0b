"""A torque controller node of one's own that misbehaves at one step, for the tests of what the
graph does then (test_external.py): ``bad_controller.py MODE STEP --ros-args ...``. Until STEP it
answers every state with V1 for the whole period (s_a, s_b, s_c = 1, 0, 0); at STEP it does what
MODE says (``slow_start``: command 0 comes 4 s late, then all is well; ``silent``: it never
answers again, idle; ``busy``: it never answers again, computing all the while; ``no_exit``: all is well,
but it does not exit after the last command, and ``stubborn`` besides ignores SIGTERM; ``deaf``
ignores SIGINT and SIGTERM from the start, and stays when its peers are gone).
rclpy and std_msgs only, as a user's node."""

from __future__ import annotations

import math
import os
import signal
import sys
import time

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

LOCKSTEP = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
    history=HistoryPolicy.KEEP_ALL,
)
SWITCHING = ("k", "t", "s_a", "s_b", "s_c")
PULSES = ("k", "t", "delay_a", "delay_b", "delay_c", "duty_a", "duty_b", "duty_c")
#: MODE → the command at STEP (labels, values given k and t), or None: no command at all
MODES = {
    "switching_state_2": lambda k, t: (SWITCHING, (k, t, 1.0, 2.0, 0.0)),
    "wrong_step": lambda k, t: (SWITCHING, (k + 1, t, 1.0, 0.0, 0.0)),
    "unknown_field": lambda k, t: ((*SWITCHING, "gain"), (k, t, 1.0, 0.0, 0.0, 2.0)),
    "missing_field": lambda k, t: (SWITCHING[:4], (k, t, 1.0, 0.0)),
    "nan_duty": lambda k, t: (PULSES, (k, t, 0.0, 0.0, 0.0, math.nan, 0.0, 0.0)),
    "pulse_past_period": lambda k, t: (PULSES, (k, t, 0.6, 0.0, 0.0, 0.5, 0.0, 0.0)),
    "voltage_inf": lambda k, t: (("k", "t", "u_alpha", "u_beta"), (k, t, math.inf, 0.0)),
    "switching_state_nan": lambda k, t: (SWITCHING, (k, t, 1.0, math.nan, 0.0)),
    "wrong_time": lambda k, t: (SWITCHING, (k, t + 5e-5, 1.0, 0.0, 0.0)),
    "wrong_size": lambda k, t: (SWITCHING, (k, t, 1.0, 0.0)),  # five labels, four values
    "no_layout": lambda k, t: ((), (k, t, 1.0, 0.0, 0.0)),
}
#: MODE → what it does at STEP besides: a burst of commands for the steps after it
BURSTS = {"future_commands": 1000}


def message(labels: tuple[str, ...], values: tuple[float, ...]) -> Float64MultiArray:
    msg = Float64MultiArray()
    if labels:  # none: no layout at all
        msg.layout.dim = [MultiArrayDimension(label=",".join(labels), size=len(labels),
                                              stride=len(labels))]  # fmt: skip
    msg.data = [float(v) for v in values]
    return msg


class BadController(Node):
    def __init__(self, mode: str, at: int) -> None:
        super().__init__(
            "bad_controller",
            allow_undeclared_parameters=True,
            automatically_declare_parameters_from_overrides=True,
        )
        self.mode, self.at = mode, at
        ts, duration = (float(self.get_parameter(n).value) for n in ("ts", "duration"))
        self.ts = ts
        self.steps = round(duration / ts)  #: after the last command it ends, as the contract says
        readers = self.get_parameter_or("command_readers", None).value
        self.readers = 2 if readers is None else int(readers)
        self.done = False
        self.pub = self.create_publisher(Float64MultiArray, "command", LOCKSTEP)
        self.refs: set[int] = set()
        self.states: dict[int, float] = {}
        self.k = 0
        self.create_subscription(Float64MultiArray, "state", self.on_state, LOCKSTEP)
        self.create_subscription(Float64MultiArray, "torque_reference", self.on_ref, LOCKSTEP)

    def on_state(self, msg: Float64MultiArray) -> None:
        self.states[int(msg.data[0])] = msg.data[1]
        self.step()

    def on_ref(self, msg: Float64MultiArray) -> None:
        self.refs.add(int(msg.data[0]))
        self.step()

    def step(self) -> None:
        k = self.k
        if k not in self.states or k not in self.refs:
            return
        if k == 0:
            while self.pub.get_subscription_count() < self.readers:
                time.sleep(0.005)
            if self.mode == "slow_start":  # as a node still loading or discovering would
                time.sleep(4.0)
        t = self.states.pop(k)
        if k == self.at and self.mode != "slow_start":
            if self.mode == "dies":
                os._exit(3)
            if self.mode == "silent":
                self.k = -1  # never answers again
                return
            if self.mode == "busy":  # computes and computes (a search that exploded)
                while rclpy.ok():
                    sum(range(10_000))
                self.k = -1
                return
            if self.mode == "exit0":  # as a node that believes the run is over
                raise SystemExit(0)
            if self.mode in BURSTS:  # the commands of the steps to come, all at once
                for j in range(k + 1, k + 1 + BURSTS[self.mode]):
                    self.pub.publish(message(SWITCHING, (j, j * self.ts, 1.0, 0.0, 0.0)))
                self.k = -1
                return
            if self.mode in MODES:
                self.pub.publish(message(*MODES[self.mode](float(k), t)))
            else:
                self.pub.publish(message(SWITCHING, (k, t, 1.0, 0.0, 0.0)))
        else:
            self.pub.publish(message(SWITCHING, (k, t, 1.0, 0.0, 0.0)))
        self.k = k + 1
        self.done = self.k == self.steps


def main() -> int:
    mode, at = sys.argv[1], int(sys.argv[2])
    rclpy.init(args=sys.argv)
    if mode in ("stubborn", "deaf"):  # after rclpy's own handlers are in
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
    if mode == "deaf":
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    node = BadController(mode, at)
    try:
        while rclpy.ok() and not node.done:
            rclpy.spin_once(node, timeout_sec=0.1)
        node.pub.wait_for_all_acked()
        # the run is over; it stays all the same, until SIGTERM (rclpy's handler shuts the
        # context down) or, stubborn, for good
        while mode in ("stubborn", "deaf") or (mode == "no_exit" and rclpy.ok()):
            time.sleep(0.1)
    except (KeyboardInterrupt, rclpy.executors.ExternalShutdownException):
        pass
    return 0


if __name__ == "__main__":
    sys.exit(main())
