"""A scenario: every parameter of one run, as frozen dataclasses grouped by the node that owns them."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any

from ..errors import ConfigError
from .control import EXTERNAL, controller_class
from .control.speed_pi import SpeedPIParams
from .devices import Device
from .fields import check_fields, choice, flag, quantity
from .losses import LossParams
from .machines import Machine
from .signals import EXTERNAL_PREFIX, external_name
from .timebase import StepProfile, step_index

__all__ = ["MAX_STEPS", "LoggerParams", "PlantParams", "RunParams", "Scenario"]

#: the most steps a run may have (10^9: ~14 h of simulated time at 50 µs, days of wall time)
MAX_STEPS = 1_000_000_000


@dataclass(frozen=True)
class RunParams:
    """Shared by every node: what runs and for how long."""

    scenario: str = choice("scenario name (config/<name>.yaml)")
    machine: str = choice("machine type of the plant", tuple(m.value for m in Machine))
    ts: float = quantity("control period", "s", gt=0)
    duration: float = quantity("simulated run length", "s", gt=0)

    def __post_init__(self) -> None:
        check_fields(self)
        if self.duration < self.ts:
            raise ConfigError(
                f"duration {self.duration:g} s is shorter than one control period "
                f"(ts = {self.ts:g} s)"
            )
        if self.steps > MAX_STEPS:
            raise ConfigError(
                f"duration {self.duration:g} s at ts = {self.ts:g} s is {self.steps:.3g} steps; "
                f"at most {MAX_STEPS:.0e} (shorten the run or lengthen ts)"
            )

    @property
    def steps(self) -> int:
        """Control periods in the run: every step whose sample instant lies before ``duration``."""
        return step_index(self.duration, self.ts)


@dataclass(frozen=True)
class PlantParams:
    """Plant: machine, inverter, load steps, integrator sub-step; what makes it a real drive
    (docs/physics.md#a-real-drive), every one ideal by default: the computation delay, the
    inverter's dead time and device drops, the current and position sensors; whether a load
    machine holds its speed (docs/physics.md#mechanics-and-load); whether it publishes the
    period means (docs/physics.md#continuous-time-figures); and its losses and temperatures
    (``losses``, docs/physics.md#losses-and-temperature)."""

    motor: Any  #: the machine type's motor parameters (:data:`~.machines.MOTORS`)
    u_dc: float = quantity("DC-link voltage", "V", gt=0)
    load_times: tuple[float, ...] = quantity("times of the load-torque steps", "s", ge=0)
    load_values: tuple[float, ...] = quantity("load torque from each time on", "N·m")
    max_substep: float = quantity("integrator sub-step bound", "s", gt=0)
    actuation_delay_steps: int = quantity(
        "periods between sampling and the command acting (1: a DSP's computation delay)",
        ge=0, le=2, integer=True, default=0,
    )  # fmt: skip
    dead_time: float = quantity(
        "inverter dead time per switching edge (the leg follows its current's sign)", "s",
        ge=0, default=0.0,
    )  # fmt: skip
    device_drop: float = quantity(
        "on-state voltage of a conducting device or diode", "V", ge=0, default=0.0
    )
    current_noise: float = quantity(
        "Gaussian noise on each measured phase current", "A rms", ge=0, default=0.0
    )
    current_adc_bits: int = quantity(
        "ADC resolution of the phase currents (0: exact)", ge=0, le=24, integer=True, default=0
    )
    current_range: float = quantity(
        "ADC full scale: measures -range..+range", "A", gt=0,
        nan_default="none (needed with current_adc_bits)", default=math.nan,
    )  # fmt: skip
    encoder_lines: int = quantity(
        "incremental encoder lines per revolution, 4 counts each (0: exact angle and speed)",
        ge=0, integer=True, default=0,
    )  # fmt: skip
    speed_window: float = quantity(
        "speed from the encoder: count difference over this window", "s", gt=0, default=1e-3
    )
    u_dc_gain: float = quantity(
        "measured DC-link voltage over the true one (the sensor's gain: 1 exact)", gt=0,
        default=1.0,
    )  # fmt: skip
    sensor_seed: int = quantity(
        "seed of the sensors' noise (same seed, same recording)", ge=0, integer=True, default=0
    )
    held_speed_times: tuple[float, ...] = quantity(
        "times of the held speed's steps: with them a load machine holds the shaft at "
        "held_speed_rpm (a test bench's dynamometer) and the load profile must be 0", "s",
        ge=0, default=(),
    )  # fmt: skip
    held_speed_rpm: tuple[float, ...] = quantity(
        "the speed the load machine holds from each of held_speed_times on", "r/min", default=()
    )
    period_means: bool = flag(
        "integrate torque, flux and current between the samples: the state's *_avg fields and "
        "the continuous-time figures (off: NaN; costs a third of a run's time)"
    )
    #: the machine's magnetic saturation (:data:`~.machines.SATURATIONS`, the ``saturation``
    #: group; docs/physics.md#saturation); None (or model none): the linear machine
    saturation: Any = None
    losses: LossParams = LossParams()  #: everything off unless the section says

    def __post_init__(self) -> None:
        check_fields(self)
        if self.saturation is not None and not self.saturation.on:
            object.__setattr__(self, "saturation", None)  # model none: the linear plant
        if self.saturation is not None and self.losses.on:
            # the saturating machines have no temperature model, rotor-copper or flux hooks
            # for the loss ledger (docs/physics.md#losses-and-temperature)
            raise ConfigError(
                "plant.losses with plant.saturation: losses and temperatures are computed for "
                "the linear machines only; leave plant.losses.device empty and plant.losses.machine "
                "false (losses off), or set "
                "plant.saturation.model none"
            )
        self.load_profile()
        if self.current_adc_bits and math.isnan(self.current_range):
            raise ConfigError(
                f"plant.current_adc_bits: {self.current_adc_bits} bits need "
                f"plant.current_range (A, the ADC's full scale) > 0"
            )
        if self.held_speed_times or self.held_speed_rpm:
            self.held_speed()  # validates
            if any(self.load_values):
                raise ConfigError(
                    f"plant.load_values: {list(self.load_values)} with a held speed "
                    f"(plant.held_speed_times): the load machine holding the shaft takes "
                    f"whatever torque the motor makes; give load_values: [0.0]"
                )
        if self.losses.device and self.device_drop:
            raise ConfigError(
                f"plant.device_drop: {self.device_drop:g} V beside plant.losses.device "
                f"{self.losses.device!r}: the device file gives the on-state voltages (one model "
                f"of a conducting device); give device_drop: 0.0"
            )
        if not math.isnan(self.current_range) and not self.current_adc_bits:
            raise ConfigError(
                "plant.current_range: given without plant.current_adc_bits (1..24): "
                "the range only means something for an ADC"
            )

    def check_timing(self, ts: float) -> None:
        """ConfigError if a setting does not fit the control period ``ts`` (s)."""
        if self.dead_time >= 0.1 * ts:
            raise ConfigError(
                f"plant.dead_time: {self.dead_time:g} s must be below a tenth of the control "
                f"period ({0.1 * ts:g} s at ts = {ts:g} s)"
            )
        if self.encoder_lines and self.speed_window < ts:
            raise ConfigError(
                f"plant.speed_window: {self.speed_window:g} s is shorter than the control period "
                f"(ts = {ts:g} s); the encoder's speed needs at least one period"
            )

    @property
    def held(self) -> bool:
        """A load machine holds the shaft's speed (``held_speed_times``)."""
        return bool(self.held_speed_times)

    def held_speed(self) -> StepProfile:
        """The speed the load machine holds, rad/s."""
        rpm = 2.0 * math.pi / 60.0
        return StepProfile(
            tuple(self.held_speed_times), tuple(v * rpm for v in self.held_speed_rpm)
        )

    @property
    def sensed(self) -> bool:
        """Any sensor that is not exact."""
        return bool(self.current_noise or self.current_adc_bits or self.encoder_lines)

    def load_profile(self) -> StepProfile:
        return StepProfile(tuple(self.load_times), tuple(self.load_values))


@dataclass(frozen=True)
class LoggerParams:
    """Metrics window [window_start, window_end) (paper 000: 0.05-6 s); thd_window: [start, end]
    of the steady-state stretch whose phase-a current THD is reported (whole electrical cycles
    inside it), or empty for none."""

    window_start: float = quantity("start of the metrics window", "s", ge=0)
    window_end: float = quantity("end of the metrics window", "s", gt=0)
    thd_window: tuple[float, ...] = quantity(
        "[start, end] of the phase-a THD window, or [] for none", "s", ge=0, default=()
    )

    def __post_init__(self) -> None:
        check_fields(self)
        if not self.window_start < self.window_end:
            raise ConfigError(
                f"metrics_logger: need window_start < window_end, got "
                f"{self.window_start}, {self.window_end}"
            )
        if self.thd_window and not (
            len(self.thd_window) == 2 and self.thd_window[0] < self.thd_window[1]
        ):
            raise ConfigError(
                f"metrics_logger.thd_window must be [] or [start, end] with 0 <= start < end s, "
                f"got {list(self.thd_window)}"
            )


@dataclass(frozen=True)
class Scenario:
    """One run's parameters. ``family`` names the controller family
    (:data:`~.control.CONTROLLERS`) whose ``params_type`` ``controller`` is; ``source`` and
    ``text`` are the file it was read from and its text (what a recording stores)."""

    run: RunParams
    plant: PlantParams
    #: None: the speed loop is the user's (``own``) and its section is not the built-in's
    speed_pi: SpeedPIParams | None
    #: None: the torque controller is the user's (``own``) and its section is not the family's
    controller: Any
    logger: LoggerParams
    family: str
    source: str = ""
    text: str = ""
    #: the torque controller is a node of the user's own, named :attr:`own_name`; the
    #: section's own strategy is then not run
    external: bool = False
    #: the strategy name of a torque controller of the user's own: ``external:LABEL``
    own_name: str = EXTERNAL
    #: the nodes whose sections are the user's (``run --external``): their keys reach the node
    #: as parameters and are not checked against a built-in node's
    own: frozenset[str] = frozenset()
    #: the drawn drive this run is (JSON: its index, seed, factors and values; docs/
    #: reproduction.md#robustness), "" for none: what the recording's metadata says of it
    draw: str = ""
    #: the inverter's devices, read from the file ``plant.losses.device`` names (None: none)
    device: Device | None = None
    #: the devices the torque controller's ``device`` names (its loss-aware cost), read
    controller_device: Device | None = None

    def __post_init__(self) -> None:
        self.plant.check_timing(self.ts)
        cls = controller_class(self.family)
        if self.controller is None and "torque_controller" in self.own:
            pass  # the user's section: nothing of the family's to check
        elif not isinstance(self.controller, cls.params_type):
            raise ConfigError(
                f"torque_controller: family {self.family!r} takes {cls.params_type.__name__}, "
                f"got {type(self.controller).__name__}"
            )
        if cls.machine != self.run.machine:
            raise ConfigError(
                f"torque_controller.family: {self.family!r} controls a {cls.machine.value} "
                f"machine, but the scenario's machine is {self.run.machine!r}"
            )

    @property
    def name(self) -> str:
        return self.run.scenario

    @property
    def ts(self) -> float:
        return self.run.ts

    @property
    def machine(self) -> Machine:
        return Machine(self.run.machine)

    @property
    def speed_pi_params(self) -> SpeedPIParams:
        """The speed PI's settings; ConfigError where the speed loop is the user's own and its
        section is not the built-in's."""
        if self.speed_pi is None:
            raise ConfigError(
                f"{self.source}: speed_pi is a node of the user's own here: its section is its own"
            )
        return self.speed_pi

    @property
    def torque_limit(self) -> float:
        """T* saturates at ± this, N·m (NaN: a speed loop of the user's own says not)."""
        return math.nan if self.speed_pi is None else self.speed_pi.torque_limit

    @property
    def strategy(self) -> str:
        """The strategy the controller starts with (``external:LABEL``: a node of the user's
        own, :attr:`own_name`)."""
        return self.own_name if self.external else str(self.controller.strategy)

    def with_strategy(self, strategy: str | None) -> Scenario:
        """The same scenario starting with another strategy of its family (None: unchanged), or
        with a torque controller of the user's own (``external:LABEL``, see
        :func:`~.signals.external_name`); ConfigError lists the family's strategies."""
        if strategy is None:
            return self
        if strategy.startswith(EXTERNAL_PREFIX):
            name = external_name(strategy[len(EXTERNAL_PREFIX) :])
            return dataclasses.replace(self, external=True, own_name=name)
        if self.controller is None:
            raise ConfigError(
                f"strategy {strategy!r}: the torque controller's section is that of a controller "
                f"of one's own, not of {self.family!r}: there is no built-in strategy to run"
            )
        names = tuple(controller_class(self.family).strategies)
        if strategy not in names:
            raise ConfigError(
                f"strategy: unknown strategy {strategy!r} for controller family "
                f"{self.family!r}; valid: {', '.join(names)}"
            )
        return dataclasses.replace(
            self,
            controller=dataclasses.replace(self.controller, strategy=strategy),
            external=False,
        )

    def with_duration(self, duration: float | None) -> Scenario:
        """The same scenario run for ``duration`` s (None: unchanged)."""
        if duration is None:
            return self
        return dataclasses.replace(self, run=dataclasses.replace(self.run, duration=duration))
