"""The realism study (``predictive-drive reproduce realism``;
docs/physics.md#the-papers-strategies-on-a-real-drive): the papers' strategies on paper 000's
induction motor and paper 001's IPMSM, each run ideal and then with one more piece of a real
drive per column — one period of computation delay, its compensation, dead time with device
drops, sensors. The columns are cumulative: "+ sensors" also has the delay, its compensation
and the dead time.

The real drive's figures are typical of a drive of the scenario's size, not taken from a paper
(the papers assume the ideal drive): a 2 µs dead time (4 % of the 50 µs period) and 1.5 V
drops, as an IGBT inverter; two phase-current sensors with 0.1 % of their range in noise and a
12-bit ADC over about twice the run's largest current; an encoder and speed window that the
scenario's speed loop tolerates (see each scenario).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

__all__ = [
    "CONDITIONS",
    "DEAD_TIME_KEYS",
    "DELAY_KEYS",
    "HARDWARE_KEYS",
    "RANKED",
    "REALISM",
    "SENSOR_KEYS",
    "SHOWN",
    "STUDY_KEY",
    "RealismScenario",
    "condition_settings",
]

#: the columns, in order
CONDITIONS = ("ideal", "delay", "compensated", "+ dead time", "+ sensors")
#: the setting the study itself varies (a --set of it is refused)
STUDY_KEY = "torque_controller.delay_compensation"
#: the real drive's settings, by the column that adds them
DELAY_KEYS = ("plant.actuation_delay_steps",)
DEAD_TIME_KEYS = ("plant.dead_time", "plant.device_drop")
SENSOR_KEYS = (
    "plant.current_noise", "plant.current_adc_bits", "plant.current_range",
    "plant.encoder_lines", "plant.speed_window", "plant.sensor_seed",
)  # fmt: skip
HARDWARE_KEYS = DELAY_KEYS + DEAD_TIME_KEYS + SENSOR_KEYS
#: the figures shown per column (metric keys), and those the strategies are ranked by (lower
#: is better); the speed error shows where the speed loop, not the torque control, failed
SHOWN = ("t_rmse", "psi_rmse", "thd", "f_sw_hz", "speed_rmse")
RANKED = ("t_rmse", "psi_rmse", "thd")


@dataclass(frozen=True)
class RealismScenario:
    """One scenario of the study: its strategies, the real drive's settings (keys of
    :data:`HARDWARE_KEYS`) and the study's own settings for every run of it."""

    caption: str
    strategies: tuple[str, ...]
    hardware: dict[str, Any]
    settings: dict[str, Any]


def _hardware(current_range: float, encoder_lines: int, speed_window: float) -> dict[str, Any]:
    return {
        "plant.actuation_delay_steps": 1,
        "plant.dead_time": 2e-6,
        "plant.device_drop": 1.5,
        "plant.current_noise": 1e-3 * current_range,
        "plant.current_adc_bits": 12,
        "plant.current_range": current_range,
        "plant.encoder_lines": encoder_lines,
        "plant.speed_window": speed_window,
        "plant.sensor_seed": 1,
    }


REALISM: dict[str, RealismScenario] = {
    "im_paper": RealismScenario(
        "paper 000's induction motor (Li et al., EMCA 2022), 0.05-6 s",
        ("mptc", "mptc_db", "db_mptc"),
        # |i| reaches 12.8 A at start, 8.2 A at the 99th percentile; the speed loop is slow
        # (kp/J = 12 rad/s): an industrial 2500-line encoder, speed over 1 ms
        _hardware(20.0, 2500, 1e-3),
        # paper 000 names no THD window: 2772 r/min at +3 N·m, settled, before the load step
        {"metrics_logger.thd_window": [1.0, 1.45]},
    ),
    "ipmsm_validation": RealismScenario(
        "paper 001's interior PMSM (Li et al., CTA 2023, §6), 0-2 s",
        ("mptc", "simplified1", "simplified2", "simplified3"),
        # |i| reaches 52 A at start, 28 A at the 99th percentile. The assumed speed PI is fast
        # (kp/J = 5000 rad/s): a 1 ms speed window's 0.5 ms lag makes it a limit cycle
        # (docs), and so does 0.25 ms: a servo's 17-bit encoder (32768 lines), speed over 0.1 ms
        _hardware(60.0, 32768, 1e-4),
        {},
    ),
}


def condition_settings(hardware: dict[str, Any]) -> list[tuple[str, dict[str, Any]]]:
    """Each column with its settings, cumulative: (name, settings)."""
    delay = {k: hardware[k] for k in DELAY_KEYS}
    compensated = {**delay, STUDY_KEY: True}
    dead = {**compensated, **{k: hardware[k] for k in DEAD_TIME_KEYS}}
    sensors = {**dead, **{k: hardware[k] for k in SENSOR_KEYS}}
    return list(zip(CONDITIONS, ({}, delay, compensated, dead, sensors)))
