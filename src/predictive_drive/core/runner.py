"""In-process engine: the three components wired exactly as the ROS graph wires them.

Per step k: the controller answers state k with command k using reference k (computed by the speed
PI from state k-1: the documented one-sample delay); the PI computes reference k+1 from state k; the
plant applies command k for Ts and returns state k+1. Each step's records also go to every
``sink(record, row)`` (state k, reference k, command k).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Sequence

from .control import Controller, make_controller, strategy_names
from .control.speed_pi import SpeedPI
from .plant import InverterPlant, make_plant
from .scenario import PlantParams, Scenario
from .sensors import Sensors
from .signals import Command, Reference, State
from .trace import Trace, TraceBuilder

__all__ = ["Components", "build", "build_controller", "build_plant", "run_inprocess"]

#: called with each step's state k, reference k and command k (None after the last step, whose
#: state and reference close the run), then the same rows packed as little-endian doubles (what
#: the trace keeps; b"" for the missing command)
Sink = Callable[[State, Reference, Command | None, bytes, bytes, bytes], None]


@dataclasses.dataclass
class Components:
    plant: InverterPlant
    speed_pi: SpeedPI
    controller: Controller


def build_plant(machine: str, p: PlantParams, *, ts: float) -> InverterPlant:
    """The plant of a scenario's plant section (shared by the in-process engine and plant_node)."""
    p.check_timing(ts)
    sensors = None
    if p.sensed:
        sensors = Sensors(
            ts=ts,
            pole_pairs=p.motor.p,
            noise=p.current_noise,
            adc_bits=p.current_adc_bits,
            adc_range=p.current_range,
            encoder_lines=p.encoder_lines,
            speed_window=p.speed_window,
            seed=p.sensor_seed,
        )
    return make_plant(
        machine,
        p.motor,
        ts=ts,
        u_dc=p.u_dc,
        load=p.load_profile(),
        max_substep=p.max_substep,
        actuation_delay_steps=p.actuation_delay_steps,
        dead_time=p.dead_time,
        device_drop=p.device_drop,
        sensors=sensors,
    )


def build_controller(scenario: Scenario) -> Controller:
    """The controller of a scenario's torque_controller section."""
    return make_controller(scenario.family, scenario.controller, ts=scenario.ts)


def build(scenario: Scenario) -> Components:
    return Components(
        plant=build_plant(scenario.run.machine, scenario.plant, ts=scenario.ts),
        speed_pi=SpeedPI(scenario.speed_pi, ts=scenario.ts),
        controller=build_controller(scenario),
    )


def run_inprocess(
    scenario: Scenario,
    *,
    steps: int | None = None,
    switches: Iterable[tuple[int, str]] = (),
    sinks: Sequence[Sink] = (),
    progress: Callable[[int], None] | None = None,
) -> Trace:
    """Run ``steps`` control periods (default: the scenario's duration) and return the trace.

    ``switches``: (step, strategy) pairs; the strategy changes at that step boundary.
    """
    n = scenario.run.steps if steps is None else steps
    c = build(scenario)
    plant, pi, ctrl = c.plant, c.speed_pi, c.controller
    builder = TraceBuilder(scenario.ts, strategy_names(scenario.family))
    (s_add, s_pack), (r_add, r_pack), (c_add, c_pack) = (
        builder.packer(r) for r in ("state", "reference", "command")
    )
    pending = sorted(switches)
    next_switch = pending[0][0] if pending else n
    state = plant.state()
    immediate = pi.immediate  # T* from state k applies at k (else at k+1: see SpeedPI)
    ref = pi.step(state) if immediate else pi.initial()
    every = max(1, n // 200)
    for k in range(n):
        if k >= next_switch:
            while pending and pending[0][0] <= k:
                ctrl.set_strategy(pending.pop(0)[1])
            next_switch = pending[0][0] if pending else n
        cmd = ctrl.step(state, ref)
        sb, rb, cb = s_pack(*state), r_pack(*ref), c_pack(*cmd)
        s_add(sb)
        r_add(rb)
        c_add(cb)
        for s in sinks:
            s(state, ref, cmd, sb, rb, cb)
        if immediate:
            state = plant.step(cmd)
            ref = pi.step(state)
        else:
            ref = pi.step(state)
            state = plant.step(cmd)
        if progress is not None and k % every == 0:
            progress(k)
    sb, rb = s_pack(*state), r_pack(*ref)
    s_add(sb)
    r_add(rb)
    for s in sinks:
        s(state, ref, None, sb, rb, b"")
    if progress is not None:
        progress(n)
    return builder.build()
