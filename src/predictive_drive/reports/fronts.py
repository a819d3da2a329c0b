"""The fronts study (``predictive-drive reproduce fronts``;
docs/reproduction.md#fronts-distortion-against-switching-frequency): each strategy's distortion
against its switching frequency at a steady operating point, traced over its switching-effort
knob, with field-oriented control and SVPWM as the baseline on the same machine and point — the
comparison power electronics accepts (Geyer & Quevedo, IEEE TPEL 2014, 2015; Karamanakos et al.).

A study is data: per operating point its two scenarios (the MPTC family's and the FOC twin's, the
same drive: ``test_a_steady_point_is_the_same_drive_for_mptc_and_field_orientation``) and its
curves, each a strategy with the setting it is traced over and the values. Knobs:

- the finite-control-set strategies, the deadbeat ones too, over ``torque_controller.lambda_sw``
  at the papers' control period: they choose among the inverter's vectors each period, and the
  weight on commutations is what trades their distortion against switching (the deadbeat duty
  is part of the choice, not a carrier of its own);
- field-oriented control over the control period ``ts``, which is its carrier period (f_sw =
  1/Ts), its current loop tuned at every period by the technical optimum (kp = L/(2·1.5·Ts));
- the long horizons (mptc at N = 2, 3, 5 over λ_sw; direct_mpc at N = 1, 3, 5, 10 over its
  switching weight λ_u), one curve per N.

The values reach from the papers' law (λ_sw = 0) to where the drive stops following the
operating point, and for FOC from 0.5 to 20 kHz.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "COMMON_FSW",
    "FRONTS",
    "HOLD_SHARE",
    "KNOBS",
    "DIRECT_HORIZONS",
    "MAX_GAP",
    "MPTC_HORIZONS",
    "RANKED",
    "SHOWN",
    "Curve",
    "OperatingPoint",
]

#: the switching frequencies the table interpolates each front at, Hz
COMMON_FSW = (1e3, 2e3, 3e3, 4e3, 5e3, 7e3, 10e3)
#: the figures of every point (metric keys), and those the fronts are drawn and ranked by
SHOWN = ("f_sw_hz", "t_ripple_cont", "i_thd_cont", "t_rmse_cont", "psi_rmse_cont", "t_rmse")
RANKED = ("t_ripple_cont", "i_thd_cont")
#: a point whose mean torque misses T* by more than this share has left the operating point (the
#: switching effort outweighs any torque error): it is reported, not part of the front
HOLD_SHARE = 0.5
#: a front is interpolated between neighbours at most this ratio apart in f_sw; across a wider
#: gap (a strategy that jumps from one way of switching to another) it is not known: '-'
MAX_GAP = 2.0
#: the settings a curve may be traced over, with the range each may take
KNOBS: dict[str, tuple[float, float]] = {
    "torque_controller.lambda_sw": (0.0, 1e3),
    "torque_controller.lambda_u": (1e-9, 1e3),
    "ts": (1e-5, 1e-2),
}

_LAMBDA = "torque_controller.lambda_sw"
#: 0.5 to 20 kHz carriers, no two more than twice apart
_FOC_TS = tuple(1e-3 / f for f in (0.5, 1.0, 2.0, 3.0, 5.0, 7.0, 10.0, 15.0, 20.0))


@dataclass(frozen=True)
class Curve:
    """One strategy traced over one knob: ``knob`` (a key of :data:`KNOBS`) takes ``values`` in
    turn on scenario ``scenario``, with ``settings`` besides. ``label`` names the curve (the
    strategy's name unless a setting tells two curves of one strategy apart)."""

    strategy: str
    scenario: str
    knob: str
    values: tuple[float, ...]
    settings: dict[str, Any] = field(default_factory=dict)
    label: str = ""

    @property
    def name(self) -> str:
        return self.label or self.strategy


@dataclass(frozen=True)
class OperatingPoint:
    """A steady operating point: the curves run at it, and the papers' ranking of its strategies
    (best first, by the paper's torque figure; empty where no paper ranks them)."""

    caption: str
    curves: tuple[Curve, ...]
    papers_ranking: tuple[str, ...] = ()
    papers_source: str = ""


def _fcs(
    scenario: str, strategies: tuple[str, ...], values: dict[str, tuple[float, ...]]
) -> tuple[Curve, ...]:
    return tuple(Curve(s, scenario, _LAMBDA, values[s]) for s in strategies)


def _horizons(
    strategy: str, scenario: str, knob: str, values: tuple[float, ...], horizons: tuple[int, ...]
) -> tuple[Curve, ...]:
    """One curve per horizon N of a long-horizon law (docs/physics.md#long-horizons), named
    ``<strategy> N=<N>`` (plain ``mptc`` at N = 1: the papers' law)."""
    return tuple(
        Curve(
            strategy, scenario, knob, values, {"torque_controller.horizon": n},
            label=strategy if n == 1 and strategy == "mptc" else f"{strategy} N={n}",
        )
        for n in horizons
    )  # fmt: skip


_LAMBDA_U = (1e-4, 1e-3, 3e-3, 0.01, 0.03, 0.1, 0.3, 1.0)
#: the horizons the fronts trace: mptc's and direct_mpc's
MPTC_HORIZONS = (2, 3, 5)
DIRECT_HORIZONS = (1, 3, 5, 10)


_IM_LAMBDA = {
    "mptc": (0.0, 0.05, 0.1, 0.2, 0.3, 0.4, 0.5),
    "mptc_db": (0.0, 0.05, 0.1, 0.2, 0.3, 0.4),
    "db_mptc": (0.0, 0.1, 0.2, 0.25, 0.3, 0.35, 0.4, 0.5),
}
_PMSM_LAMBDA = (0.0, 0.005, 0.01, 0.02, 0.03, 0.04)
_PMSM = ("mptc", "simplified1", "simplified2", "simplified3")

FRONTS: dict[str, OperatingPoint] = {
    "im_steady": OperatingPoint(
        "paper 000's induction motor (Li et al., EMCA 2022) held at 2772 r/min, T* = 3 N·m",
        (
            *_fcs("im_steady", ("mptc", "mptc_db", "db_mptc"), _IM_LAMBDA),
            *_horizons("mptc", "im_steady", _LAMBDA, _IM_LAMBDA["mptc"], MPTC_HORIZONS),
            Curve("ifoc", "im_steady_foc", "ts", _FOC_TS, label="foc_im"),
        ),
        ("db_mptc", "mptc_db", "mptc"),
        "paper 000 Table 2, T_RMSE",
    ),
    "ipmsm_steady": OperatingPoint(
        "paper 001's interior PMSM (Li et al., CTA 2023, §6) held at 1000 r/min, T* = 15 N·m",
        (
            *_fcs("ipmsm_steady", _PMSM, dict.fromkeys(_PMSM, _PMSM_LAMBDA)),
            *_horizons("mptc", "ipmsm_steady", _LAMBDA, _PMSM_LAMBDA, MPTC_HORIZONS),
            *_horizons(
                "direct_mpc",
                "ipmsm_steady_mpc",
                "torque_controller.lambda_u",
                _LAMBDA_U,
                DIRECT_HORIZONS,
            ),  # fmt: skip
            Curve("foc_formula", "ipmsm_steady_foc", "ts", _FOC_TS, label="foc_mtpa"),
        ),
        ("mptc", "simplified2", "simplified1", "simplified3"),
        "paper 001 Table 9, T_rip",
    ),
    "hs_ipmsm_steady": OperatingPoint(
        "paper 002's high-speed interior PMSM (Yuan et al., JMEE 2018) held at 100 rad/s, "
        "T* = 4 N·m",
        (
            *_fcs("hs_ipmsm_steady", _PMSM, dict.fromkeys(_PMSM, _PMSM_LAMBDA + (0.06,))),
            *_horizons("mptc", "hs_ipmsm_steady", _LAMBDA, _PMSM_LAMBDA + (0.06,), MPTC_HORIZONS),
            *_horizons(
                "direct_mpc",
                "hs_ipmsm_steady_mpc",
                "torque_controller.lambda_u",
                _LAMBDA_U,
                DIRECT_HORIZONS,
            ),  # fmt: skip
            Curve("foc_formula", "hs_ipmsm_steady_foc", "ts", _FOC_TS, label="foc_mtpa"),
        ),
    ),
}
