"""Direct torque control of an induction motor with the classic switching table (Takahashi and
Noguchi, IEEE Trans. Ind. Appl. 1986), as a torque controller node of predictive_drive's
lock-step graph. It imports rclpy and std_msgs only: the topics and their labelled fields are the
whole contract (predictive_drive's docs/ros.md, "Writing your own controller").

Each step k: state k (/drive/state) and reference k (/drive/torque_reference) in, command k
(/drive/command) out, as a switching state held for the period (s_a, s_b, s_c) with three
diagnostics. The stator flux is estimated by the voltage model on the switching state it applied
and the measured currents; a two-level flux and a three-level torque hysteresis comparator and the
flux's sector pick the vector from the table.

Parameters: the torque controller's section of the scenario file (``motor.r_s``, ``motor.p``),
the shared ``ts`` and ``duration``, ``command_readers`` (how many subscribers /drive/command has
before command 0 goes out: 2, the plant and the recorder; 1 when a recording is replayed into the
node) and this node's own ``torque_band`` (N·m) and ``flux_band`` (Wb), the comparators' half
widths.
"""

from __future__ import annotations

import math
import sys
import time
from array import array

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.experimental.events_executor import EventsExecutor
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rclpy.task import Future
from std_msgs.msg import Float64MultiArray, MultiArrayDimension

#: the command's labelled fields: the switching state and three optional diagnostics
COMMAND_FIELDS = ("k", "t", "s_a", "s_b", "s_c", "torque_est", "flux_est", "flux_angle")
#: the six active vectors, V1 at 0° to V6 at 300° (phase a, b, c high or low)
ACTIVE = ((1, 0, 0), (1, 1, 0), (0, 1, 0), (0, 1, 1), (0, 0, 1), (1, 0, 1))
#: the lock-step topics: nothing may be lost
LOCKSTEP = QoSProfile(
    reliability=ReliabilityPolicy.RELIABLE,
    durability=DurabilityPolicy.VOLATILE,
    history=HistoryPolicy.KEEP_ALL,
)


class Fields:
    """Values of a labelled Float64MultiArray by name (``layout.dim[0].label``, comma separated).
    A publisher's labels do not change from one message to the next, so they are parsed once
    per layout seen; each message then costs a few index lookups, not a dict of every field."""

    def __init__(self, *names: str) -> None:
        self.names = names
        self._label = ""
        self._at: tuple[int, ...] = ()

    def __call__(self, msg: Float64MultiArray) -> tuple[float, ...]:
        label = msg.layout.dim[0].label
        if label != self._label:
            labels = label.split(",")
            self._at = tuple(labels.index(name) for name in self.names)
            self._label = label
        data = msg.data
        return tuple(data[i] for i in self._at)


def voltage(s: tuple[int, int, int], u_dc: float) -> complex:
    """The stator voltage (αβ, amplitude-invariant) of switching state ``s``."""
    a, b, c = s
    return complex(u_dc * (2 * a - b - c) / 3.0, u_dc * (b - c) / math.sqrt(3.0))


class SwitchingTableDTC:
    """The control law alone: ``step(i_ab, u_dc, torque_ref, flux_ref) -> (s, T̂, |ψ̂|, ∠ψ̂)``."""

    def __init__(self, *, r_s: float, p: int, ts: float, torque_band: float, flux_band: float):
        self.r_s, self.p, self.ts = r_s, p, ts
        self.torque_band, self.flux_band = torque_band, flux_band
        self.psi = 0j  #: stator-flux estimate, Wb (αβ)
        self.flux_up = True  #: the flux comparator's state (it has memory)
        self.s = (0, 0, 0)

    def step(
        self, i: complex, u_dc: float, torque_ref: float, flux_ref: float
    ) -> tuple[tuple[int, int, int], float, float, float]:
        psi = self.psi
        torque = 1.5 * self.p * (psi.real * i.imag - psi.imag * i.real)
        flux = abs(psi)
        if flux < flux_ref - self.flux_band:
            self.flux_up = True
        elif flux > flux_ref + self.flux_band:
            self.flux_up = False
        error = torque_ref - torque
        dt = 1 if error > self.torque_band else -1 if error < -self.torque_band else 0
        angle = math.atan2(psi.imag, psi.real) % (2 * math.pi)
        sector = int((angle + math.pi / 6) // (math.pi / 3)) % 6  # 0: -30°..30°
        if dt == 0:
            s = (1, 1, 1) if sum(self.s) >= 2 else (0, 0, 0)  # the zero vector nearer
        else:
            s = ACTIVE[(sector + dt * (1 if self.flux_up else 2)) % 6]
        self.s = s
        # the voltage model on what is applied for this period (forward Euler)
        self.psi = psi + self.ts * (voltage(s, u_dc) - self.r_s * i)
        return s, torque, flux, angle


class DTCNode(Node):
    """State k + reference k → command k, in step order."""

    def __init__(self) -> None:
        super().__init__(
            "dtc",
            allow_undeclared_parameters=True,
            automatically_declare_parameters_from_overrides=True,
        )

        def param(name: str, default: float | None = None) -> float:
            if self.has_parameter(name):
                return float(self.get_parameter(name).value)
            if default is None:
                raise SystemExit(f"{self.get_fully_qualified_name()}: parameter {name} is missing")
            return default

        ts = param("ts")
        self.steps = round(param("duration") / ts)
        self.readers = int(param("command_readers", 2))
        self.law = SwitchingTableDTC(
            r_s=param("motor.r_s"),
            p=int(param("motor.p")),
            ts=ts,
            torque_band=param("torque_band", 0.05),
            flux_band=param("flux_band", 0.005),
        )
        self.get_logger().info(
            f"switching-table DTC: torque band {self.law.torque_band:g} N·m, flux band "
            f"{self.law.flux_band:g} Wb, {self.steps} steps"
        )
        self.states: dict[int, tuple[float, ...]] = {}
        self.refs: dict[int, tuple[float, ...]] = {}
        self.state_fields = Fields("k", "t", "i_alpha", "i_beta", "u_dc")
        self.ref_fields = Fields("k", "torque_ref", "flux_ref")
        self.k = 0
        self.done = Future()  #: set after the last command: the spin loop ends then
        self.pub = self.create_publisher(Float64MultiArray, "command", LOCKSTEP)
        # one message, its layout built once; each step sets its data (an array of doubles:
        # rclpy takes it as it is, where a list is checked value by value)
        self.command = Float64MultiArray()
        n = len(COMMAND_FIELDS)
        self.command.layout.dim = [
            MultiArrayDimension(label=",".join(COMMAND_FIELDS), size=n, stride=n)
        ]
        self.create_subscription(Float64MultiArray, "state", self.on_state, LOCKSTEP)
        self.create_subscription(Float64MultiArray, "torque_reference", self.on_reference, LOCKSTEP)

    def on_state(self, msg: Float64MultiArray) -> None:
        s = self.state_fields(msg)
        self.states[int(s[0])] = s
        self.try_step()

    def on_reference(self, msg: Float64MultiArray) -> None:
        r = self.ref_fields(msg)
        self.refs[int(r[0])] = r
        self.try_step()

    def try_step(self) -> None:
        k = self.k
        if k not in self.states or k not in self.refs or self.done.done():
            return
        (_, t, i_alpha, i_beta, u_dc), (_, torque_ref, flux_ref) = (
            self.states.pop(k),
            self.refs.pop(k),
        )
        if k == 0:  # command 0 goes out once its readers listen (the plant and the recorder)
            deadline = time.monotonic() + 30.0
            while self.pub.get_subscription_count() < self.readers and time.monotonic() < deadline:
                time.sleep(0.005)
        s, torque, flux, angle = self.law.step(complex(i_alpha, i_beta), u_dc, torque_ref, flux_ref)
        # t: the state's own, to the bit (the plant checks it)
        self.command.data = array("d", (k, t, *s, torque, flux, angle))
        self.pub.publish(self.command)
        self.k = k + 1
        if self.k >= self.steps:  # the last command: the last state is not answered
            self.done.set_result(True)


def main(args: list[str] | None = None) -> int:
    rclpy.init(args=args)
    node = DTCNode()
    # the events executor runs the callbacks in C++ until the future is done or 0.1 s pass
    # (about three times the default executor's pace per message); always with a finite
    # timeout: without one it never runs a callback, and Ctrl-C / SIGTERM get through between
    executor = EventsExecutor()
    executor.add_node(node)
    try:
        while rclpy.ok() and not node.done.done():
            executor.spin_until_future_complete(node.done, timeout_sec=0.1)
        node.pub.wait_for_all_acked()  # the last commands reach the plant and the recorder
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    finally:
        executor.shutdown(timeout_sec=1.0)
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
