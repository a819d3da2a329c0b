"""In-process engine: the three components wired exactly as the ROS graph wires them.

Per step k: the controller answers state k with command k using reference k (computed by the speed
PI from state k-1: the documented one-sample delay); the PI computes reference k+1 from state k; the
plant applies command k for Ts and returns state k+1. The records also go to every ``sink``,
:data:`SINK_BATCH` steps at a time (see :data:`Sink`).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from ..errors import ConfigError
from .control import Controller, make_controller, strategy_names
from .control.base import parse_switch
from .control.speed_pi import SpeedPI
from .devices import Device
from .plant import InverterPlant, make_plant
from .saturation import make_saturated_plant
from .scenario import PlantParams, Scenario
from .sensors import Sensors
from .trace import Trace, TraceBuilder

__all__ = [
    "SINK_BATCH",
    "Components",
    "Sink",
    "build",
    "build_controller",
    "build_plant",
    "run_inprocess",
]

#: called with the rows of consecutive steps as the trace packs them (little-endian doubles, one
#: row per step): states, references, commands, and the plant's losses (b"" where it books
#: none). The last call of a run also brings its final state, reference and losses, which have
#: no command (one row fewer). A run stopped by an exception hands over the steps it completed
#: before the exception goes on.
Sink = Callable[[bytes, bytes, bytes, bytes], None]
#: steps handed to the sinks at once: 25.6 ms of a 20 kHz run (the sink's work then runs on
#: arrays, a few numpy calls for hundreds of steps)
SINK_BATCH = 512


@dataclasses.dataclass
class Components:
    plant: InverterPlant
    speed_pi: SpeedPI
    controller: Controller


def build_plant(
    machine: str, p: PlantParams, *, ts: float, device: Device | None = None
) -> InverterPlant:
    """The plant of a scenario's plant section (shared by the in-process engine and plant_node);
    ``device``: the devices ``p.losses.device`` names, read from their file."""
    p.check_timing(ts)
    if bool(p.losses.device) != (device is not None):
        raise ConfigError(
            f"plant.losses.device {p.losses.device!r}: its device file was not read "
            f"(config.load_device reads it)"
        )
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
    settings: dict[str, Any] = dict(
        ts=ts,
        u_dc=p.u_dc,
        load=p.load_profile(),
        max_substep=p.max_substep,
        actuation_delay_steps=p.actuation_delay_steps,
        dead_time=p.dead_time,
        device_drop=p.device_drop,
        sensors=sensors,
        period_means=p.period_means,
        held_speed=p.held_speed() if p.held else None,
        u_dc_gain=p.u_dc_gain,
        losses=p.losses if p.losses.on else None,
        device=device,
    )
    if p.saturation is not None:  # a saturating machine (docs/physics.md#saturation)
        return make_saturated_plant(machine, p.motor, p.saturation, **settings)
    return make_plant(machine, p.motor, **settings)


def build_controller(scenario: Scenario) -> Controller:
    """The controller of a scenario's torque_controller section."""
    return make_controller(
        scenario.family, scenario.controller, ts=scenario.ts, device=scenario.controller_device
    )


def build(scenario: Scenario) -> Components:
    if scenario.speed_pi is None or scenario.controller is None or scenario.external:
        raise ConfigError(
            f"{scenario.source}: a node of it is the user's own (run --external): the in-process "
            f"engine runs this package's nodes only"
        )
    return Components(
        plant=build_plant(
            scenario.run.machine, scenario.plant, ts=scenario.ts, device=scenario.device
        ),
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

    ``switches``: (step, switch) pairs — a strategy's name or ``horizon=N``
    (:func:`~.control.base.parse_switch`); it takes effect at that step boundary.
    """
    n = scenario.run.steps if steps is None else steps
    c = build(scenario)
    plant, pi, ctrl = c.plant, c.speed_pi, c.controller
    builder = TraceBuilder(scenario.ts, strategy_names(scenario.family))
    (s_add, s_pack), (r_add, r_pack), (c_add, c_pack) = (
        builder.packer(r) for r in ("state", "reference", "command")
    )
    #: the plant's losses, taken a batch of steps at a time (none: it books none)
    lossy = plant.losses() is not None
    l_add = builder.buffers["losses"].extend
    pending = sorted(switches)
    next_switch = pending[0][0] if pending else n
    state = plant.state()
    immediate = pi.immediate  # T* from state k applies at k (else at k+1: see SpeedPI)
    ref = pi.step(state) if immediate else pi.initial()
    every = max(1, n // 200)
    buffers = [builder.buffers[r] for r in ("state", "reference", "command", "losses")]
    handed = [0, 0, 0, 0]  #: bytes of each buffer the sinks have had

    def hand_over() -> None:
        if lossy:  # the losses up to the last state added
            l_add(plant.take_losses().astype("<f8", copy=False).tobytes())
        if not sinks:
            return
        rows = [bytes(b[h:]) for b, h in zip(buffers, handed)]
        for i, b in enumerate(buffers):
            handed[i] = len(b)
        for s in sinks:
            s(*rows)

    due = SINK_BATCH if sinks or lossy else n + 1  #: the step after which the rows go on
    try:
        for k in range(n):
            if k >= next_switch:
                while pending and pending[0][0] <= k:
                    ctrl.switch(*parse_switch(pending.pop(0)[1]))
                next_switch = pending[0][0] if pending else n
            cmd = ctrl.step(state, ref)
            s_add(s_pack(*state))
            r_add(r_pack(*ref))
            c_add(c_pack(*cmd))
            if k + 1 == due:
                hand_over()
                due += SINK_BATCH
            if immediate:
                state = plant.step(cmd)
                ref = pi.step(state)
            else:
                ref = pi.step(state)
                state = plant.step(cmd)
            if progress is not None and k % every == 0:
                progress(k)
        s_add(s_pack(*state))
        r_add(r_pack(*ref))
    finally:  # what was completed reaches the sinks however the run ends
        hand_over()
    if progress is not None:
        progress(n)
    return builder.build()
