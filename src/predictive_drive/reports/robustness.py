"""The robustness study (``predictive-drive reproduce robustness``; docs/reproduction.md#robustness):
every strategy of a family ranked over many drives whose plant parameters are drawn around the
papers' values, the controller keeping its nominal model (what a drive tuned on nameplate data
does) — model error as a distribution, not one mismatch at a time.

A study is data: per point its scenario, strategies, the spreads its drives are drawn from
(``KEY=normal:S``: the value times 1 + S·z; see :mod:`predictive_drive.api.draws`), the settings
every run has, and the single-error conditions run beside the draws (the nominal drive, a 20 %
L_q error either way, saturation) with the papers' ranking to hold them to. Its columns are
metric keys (:data:`SHOWN`, :data:`RANKED`): any metric declared in ``core.metrics`` shows by
adding its key here (the losses of the issue "Losses and temperature", once they are metrics).

Spreads (stated assumptions, not measurements): R_s ±10 % (σ; about ±25 K of copper
temperature), L_d and L_q ±10 % (saturation and manufacturing), ψ_f ±5 % (magnet temperature
±40 K at 0.12 %/K), J ±20 % (the load's inertia, where the speed loop runs), the DC-link
sensor's gain ±2 %.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "DEFAULT_DRAWS",
    "DEFAULT_SEED",
    "RANKED",
    "ROBUSTNESS",
    "SHOWN",
    "RobustnessPoint",
]

#: the figures of every drive, by metric key (add a metric's key to show it), and those the
#: strategies are ranked by, lowest first
SHOWN = ("t_rmse", "thd", "f_sw_hz")
RANKED = ("t_rmse", "thd")
#: drives drawn per point unless told (``--draws``), and the seed (``--seed``)
DEFAULT_DRAWS = 100
DEFAULT_SEED = 1


@dataclass(frozen=True)
class RobustnessPoint:
    """One operating point or transient: the drives drawn on ``scenario`` by ``spreads``, every
    run with ``settings``, each of ``strategies`` on each drive; and ``conditions`` (name →
    settings) run once per strategy beside them."""

    caption: str
    scenario: str
    strategies: tuple[str, ...]
    spreads: tuple[str, ...]
    settings: dict[str, Any] = field(default_factory=dict)
    conditions: dict[str, dict[str, Any]] = field(default_factory=dict)
    papers_ranking: tuple[str, ...] = ()
    papers_source: str = ""


_PMSM = ("mptc", "simplified1", "simplified2", "simplified3")
#: the sampled figures need no period means (a third of a run's time)
_FAST: dict[str, Any] = {"plant.period_means": False}
_PMSM_SPREADS = (
    "plant.motor.r_s=normal:0.1",
    "plant.motor.l_d=normal:0.1",
    "plant.motor.l_q=normal:0.1",
    "plant.motor.psi_f=normal:0.05",
    "plant.u_dc_gain=normal:0.02",
)
#: the papers' machines saturating: L_q down 20 % at rated current (the assumed curve)
_CURVE: dict[str, Any] = {"plant.saturation.model": "curve", "plant.saturation.lq_drop": 0.2}
_SINGLE: dict[str, dict[str, Any]] = {
    "nominal": {},
    "L_q +20 %": {"plant.motor.l_q": "*1.2"},
    "L_q -20 %": {"plant.motor.l_q": "*0.8"},
    "saturated": _CURVE,
}
_PAPER_001 = (("mptc", "simplified2", "simplified1", "simplified3"), "paper 001 Table 9, T_rip")

ROBUSTNESS: dict[str, RobustnessPoint] = {
    "ipmsm_steady": RobustnessPoint(
        "paper 001's interior PMSM held at 1000 r/min, T* = 15 N·m (rated)",
        "ipmsm_steady",
        _PMSM,
        _PMSM_SPREADS,
        _FAST,
        _SINGLE,
        *_PAPER_001,
    ),
    "ipmsm_transient": RobustnessPoint(
        "paper 001's interior PMSM through a speed reversal (1000 to -1000 r/min) and load "
        "steps of ±15 N·m (ipmsm_short)",
        "ipmsm_short",
        _PMSM,
        (*_PMSM_SPREADS, "plant.motor.j=normal:0.2"),
        {},
        _SINGLE,
        *_PAPER_001,
    ),
    "ipmsm_saturated": RobustnessPoint(
        "paper 001's interior PMSM at the steady point, saturating: L_q down 10-30 % at rated "
        "current (the assumed curve's level drawn), the controller linear",
        "ipmsm_steady",
        _PMSM,
        (
            "plant.saturation.lq_drop=uniform:0.5",
            "plant.motor.r_s=normal:0.1",
        ),
        {**_FAST, **_CURVE},
        {"nominal": {}},
        *_PAPER_001,
    ),
    "pmsyrm_steady": RobustnessPoint(
        "the 5.6-kW PM-SyRM of published saturation (Lelli et al. 2024) held at 900 r/min, "
        "T* = 29.7 N·m (rated), the controller linear",
        "pmsyrm_steady",
        _PMSM,
        (
            "plant.motor.r_s=normal:0.1",
            "plant.saturation.a_d0=normal:0.1",
            "plant.saturation.a_q0=normal:0.1",
            "plant.saturation.psi_n=normal:0.05",
        ),
        _FAST,
        {"nominal": {}, "controller with the map": {"torque_controller.saturation": "plant"}},
        *_PAPER_001,
    ),
}
