"""The efficiency study (``predictive-drive reproduce efficiency``;
docs/reproduction.md#efficiency-maps): the drive's efficiency η over a grid of steady
torque-speed points, one map per strategy family on the same machine, inverter and losses.

A study is data: the machine's steady scenarios (one per family, the same drive: the fronts'
twins), the grid (speeds held by the load machine, T* held after a 10 ms ramp, ψ* the MTPA
flux of T*), the settings every run has (the inverter's devices, the machine's losses) and the
maps (a strategy on its family's scenario, with its own settings; the PMSM finite-control-set
families with the rotor-motion compensated prediction, as on the fronts). Every point is checked
against its operating point as the fronts check theirs (:data:`~.fronts.TOLERANCE`): a point
that does not hold it is blank on its map and listed.

Losses (stated assumptions, as ``ipmsm_drive_cycle`` takes them): the SiC MOSFET inverter
(config/devices), junction temperatures fed back; the machine's copper losses with the winding
at its temperature, iron losses (k_h = 6 W/(Hz·Wb²), k_e = 0.14 W/(Hz²·Wb²): about 40 W at
50 Hz and 0.25 Wb), no friction; the coolant and the motor parameters at 20 °C, so the plant
starts as the controllers' model.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from .fronts import SIC

__all__ = [
    "EFFICIENCY",
    "RAMP_STEPS",
    "SETTLE_S",
    "SHOWN",
    "EfficiencyMap",
    "EfficiencyStudy",
]

#: the figures of every point (metric keys); the maps draw η and the inverter's loss
SHOWN = (
    "efficiency", "p_in", "p_out", "p_inverter", "p_sw_t", "p_sw_d", "p_machine", "p_copper",
    "p_iron", "f_sw_hz", "t_ripple_cont", "i_thd_cont", "tj_max",
)  # fmt: skip
#: T* rises to its value over this many steps of 0.5 ms (as the steady scenarios ramp it)
RAMP_STEPS = 20
#: the window starts this long after the run does (the ramp and the transient behind it), s
SETTLE_S = 0.05


@dataclass(frozen=True)
class EfficiencyMap:
    """One strategy's map: ``strategy`` on ``scenario`` (its family's steady scenario), with
    ``settings`` besides the study's; ``label`` names it (the strategy's name by default)."""

    strategy: str
    scenario: str
    settings: dict[str, Any] = field(default_factory=dict)
    label: str = ""

    @property
    def name(self) -> str:
        return self.label or self.strategy


@dataclass(frozen=True)
class EfficiencyStudy:
    """A machine's grid: ``speeds_rpm`` (r/min) × ``torques`` (N·m), each point a steady run of
    every map, with ``settings`` on every run; the window at least ``min_window`` s and two
    electrical periods long."""

    caption: str
    speeds_rpm: tuple[float, ...]
    torques: tuple[float, ...]
    maps: tuple[EfficiencyMap, ...]
    settings: dict[str, Any] = field(default_factory=dict)
    min_window: float = 0.2


#: the losses every run books (see the module's docstring)
_LOSSES: dict[str, Any] = {
    "plant.losses.device": SIC,
    "plant.losses.machine": True,
    "plant.losses.coolant": 20.0,
    "plant.losses.iron_hysteresis": 6.0,
    "plant.losses.iron_eddy": 0.14,
}

EFFICIENCY = EfficiencyStudy(
    "paper 001's interior PMSM (Li et al., CTA 2023, §6) on the SiC MOSFET inverter, 312 V: "
    "100-1000 r/min (rated) × 1.5-15 N·m (rated)",
    tuple(float(n) for n in range(100, 1001, 100)),
    tuple(1.5 * k for k in range(1, 11)),
    (
        EfficiencyMap("mptc", "ipmsm_steady"),
        EfficiencyMap("foc_formula", "ipmsm_steady_foc"),
        # the smallest switching weight of the fronts: λ_u = 0.01 (the scenario's) holds T* 2 %
        # low at rated torque, a fixed bias of the law that is a larger share at light load
        EfficiencyMap("direct_mpc", "ipmsm_steady_mpc", {"torque_controller.lambda_u": 1e-4}),
    ),
    _LOSSES,
)
