"""The papers' tables, each in one place: the published numbers (docs/reproduction.md), the rows we run, the
caption, how our figures are computed, and the columns printed side by side.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..core.metrics import METRICS, Metric

__all__ = [
    "PAPER_000_TABLE2",
    "PAPER_001_TABLE1",
    "PAPER_001_TABLE2",
    "PAPER_001_TABLE9",
    "MTPA_STUDIES",
    "PAPER_TABLES",
    "Column",
    "MTPAStudy",
    "PaperRow",
    "PaperTable",
]

#: Li et al., EMCA 2022, Table 2 (window 0.05-6 s) and the deadbeat shares quoted in its §4
PAPER_000_TABLE2: dict[str, dict[str, float]] = {
    "mptc": {"t_rmse": 0.2582, "psi_rmse": 0.0083, "deadbeat_share": 0.0},
    "mptc_db": {"t_rmse": 0.1887, "psi_rmse": 0.0083, "deadbeat_share": 0.4404},
    "db_mptc": {"t_rmse": 0.0624, "psi_rmse": 0.0047, "deadbeat_share": 0.9980},
}

#: Li et al., CTA 2023 (paper 001) Table 2: SPMSM, strategy 1 threshold sweep and conventional MPTC.
#: Keys: torque threshold in N·m (None: conventional). f_ave in Hz. Whole 4 s run (80 000 samples).
PAPER_001_TABLE2: dict[float | None, dict[str, float]] = {
    th: {"t_rmse": t, "psi_rmse": p, "cal_ave": c, "f_ave_hz": f * 1e3}
    for th, t, p, c, f in (
        (0.1, 0.9613, 0.0046, 6.49, 6.32),
        (0.2, 0.9644, 0.0047, 5.97, 6.13),
        (0.3, 0.9733, 0.0051, 5.42, 5.91),
        (0.4, 0.9762, 0.0052, 4.85, 5.56),
        (0.5, 0.9851, 0.0057, 4.38, 5.2),
        (0.6, 1.0037, 0.0064, 4.0, 4.93),
        (0.7, 1.0086, 0.0088, 3.62, 4.57),
        (0.8, 0.9961, 0.0086, 2.87, 3.54),
        (0.9, 0.9988, 0.0099, 2.35, 2.74),
        (1.0, 1.0289, 0.0128, 2.16, 2.41),
        (1.1, 1.076, 0.0171, 2.06, 2.16),
        (1.2, 1.131, 0.0238, 1.99, 2.0),
        (1.3, 1.193, 0.0297, 1.93, 1.88),
        (1.4, 1.2601, 0.0349, 1.89, 1.8),
        (1.5, 1.3273, 0.0392, 1.86, 1.73),
        (None, 0.9614, 0.0045, 7.0, 6.45),
    )
}

#: Li et al., CTA 2023 (paper 001) Table 9 (IPMSM, 2 s), the zero-vector shares quoted in §6 and the
#: computation time relative to conventional MPTC of Table 11 (STM32H743: 2592.4 ms for 80 000
#: conventional steps, 32.4 µs per step)
PAPER_001_TABLE9: dict[str, dict[str, float]] = {
    "mptc": {
        "t_rmse": 1.2668, "psi_rmse": 0.0043, "thd": 0.068, "cal_ave": 7.0,
        "f_ave_hz": 5150.0, "zero_share": 0.3442, "compute_ratio": 1.0,
    },
    "simplified1": {
        "t_rmse": 1.3894, "psi_rmse": 0.0053, "thd": 0.0678, "cal_ave": 4.08,
        "f_ave_hz": 3990.0, "zero_share": 0.4565, "compute_ratio": 0.5770,
    },
    "simplified2": {
        "t_rmse": 1.3793, "psi_rmse": 0.0051, "thd": 0.0695, "cal_ave": 2.30,
        "f_ave_hz": 3970.0, "zero_share": 0.4600, "compute_ratio": 0.3296,
    },
    "simplified3": {
        "t_rmse": 1.3953, "psi_rmse": 0.0056, "thd": 0.0686, "cal_ave": 2.04,
        "f_ave_hz": 3920.0, "zero_share": 0.4602, "compute_ratio": 0.2948,
    },
}  # fmt: skip

#: paper 001 Table 1: conventional MPTC on the SPMSM, zero-vector use by torque-error band
#: (|ΔT| ≤ b N·m → (N, N_V0)); the last row (None) is all 80 000 samples
PAPER_001_TABLE1: dict[float | None, tuple[int, int]] = {
    0.1: (6018, 4509), 0.2: (12153, 8913), 0.3: (18397, 13014), 0.4: (24714, 16669),
    0.5: (30896, 19687), 0.6: (36874, 22101), 0.7: (42757, 23942), 0.8: (48384, 25349),
    0.9: (53452, 26293), 1.0: (58233, 26962), 1.1: (62382, 27400), 1.2: (65930, 27700),
    1.3: (68792, 27889), 1.4: (71166, 28017), 1.5: (73130, 28058), None: (80000, 28092),
}  # fmt: skip


@dataclass(frozen=True)
class PaperRow:
    """One row of a paper's table: the strategy, the scenario settings changed for it (dotted
    keys, see :func:`predictive_drive.config.apply_settings`), the paper's figures, and a label."""

    strategy: str
    settings: dict[str, Any]
    paper: dict[str, float]
    label: str = ""

    @property
    def name(self) -> str:
        return self.label or self.strategy


@dataclass(frozen=True)
class Column:
    """A column of a reproduced table: ours and the paper's figure of metric ``key``, shown as
    :data:`~predictive_drive.core.metrics.METRICS` says, under the paper's own name ``title``
    where it has one (paper 001 says T_rip for T_RMSE)."""

    key: str
    title: str = ""

    @property
    def metric(self) -> Metric:
        return METRICS[self.key]

    @property
    def heading(self) -> str:
        m = self.metric
        return f"{self.title} {m.unit}".rstrip() if self.title else m.heading


@dataclass(frozen=True)
class PaperTable:
    """A paper's table to reproduce. ``caption`` and ``how`` say ``{window}`` where the metrics
    window goes: the window the runs used, and the paper's beside it where a shortened run used
    another (:meth:`text`)."""

    caption: str
    how: str  #: how our figures were computed (printed under the table)
    rows: tuple[PaperRow, ...]
    columns: tuple[Column, ...]
    compute_ratios: bool = False  #: replay each run through its controller to time it
    window: str = ""  #: the paper's window, as the runs' window is written ("0.05-6 s")

    def text(self, template: str, used: str) -> str:
        """``template`` (the caption or ``how``) with the window the runs ``used`` in it."""
        shown = used if used == self.window else f"{used} (the paper's: {self.window})"
        return template.format(window=shown)


PAPER_TABLES: dict[str, PaperTable] = {
    "im_paper": PaperTable(
        "paper 000 (Li et al., EMCA 2022) Table 2, window {window}",
        "true plant torque/flux at each sample k against the reference in force at k over "
        "{window}; f_ave counts two device transitions per leg change (the paper gives no f_ave); "
        "compute = median wall time of the control law per step on this machine. The paper's MPTC "
        "T_RMSE (0.2582) was not reproduced under any reading tried; an independent "
        "implementation of the same equations got 0.230.",
        tuple(PaperRow(s, {}, v) for s, v in PAPER_000_TABLE2.items()),
        (
            Column("t_rmse"),
            Column("psi_rmse"),
            Column("deadbeat_share"),
            Column("f_ave_hz"),
            Column("f_sw_hz"),
            Column("cal_ave"),
            Column("compute_us_per_step"),
        ),
        window="0.05-6 s",
    ),
    "spmsm_analysis": PaperTable(
        "paper 001 (Li et al., CTA 2023) Table 2: SPMSM, strategy-1 threshold sweep, {window}",
        "T_rip/psi_rip = RMSE of the true torque/flux against the references over every sample "
        "of {window}; Cal_ave = vector predictions per step; f_ave = device transitions / (6 t), two "
        "per leg change (the paper's own f_ave figures are lower under every reading tried). "
        "J (not in the paper) is assumed 0.001 kg m^2; T_rip depends on it through the speed "
        "PI, which amplifies speed ripple into T*.",
        (PaperRow("mptc", {}, PAPER_001_TABLE2[None]),)
        + tuple(
            PaperRow(
                "simplified1",
                {"torque_controller.torque_threshold": th},
                v,
                f"simplified1 ±{th:g}",
            )
            for th, v in PAPER_001_TABLE2.items()
            if th is not None
        ),
        (
            Column("t_rmse", "T_rip"),
            Column("psi_rmse", "psi_rip"),
            Column("cal_ave"),
            Column("f_ave_hz"),
            Column("f_sw_hz"),
            Column("zero_share"),
        ),
        window="0-4 s",
    ),
    "ipmsm_validation": PaperTable(
        "paper 001 (Li et al., CTA 2023) Table 9 (IPMSM, {window}), zero-vector shares of §6, "
        "compute time relative to conventional of Table 11",
        "T_rip/psi_rip over {window}; THD = phase-a current distortion over the whole "
        "electrical cycles in 0.2-0.5 s (every spectral line up to 10 kHz but DC and the "
        "fundamental; integer harmonics alone in the next column); f_ave two transitions per leg "
        "change; compute ratio = the strategy's decision time over the run relative to "
        "conventional MPTC, its decisions replayed in a tight loop on the run's recorded "
        "estimates (the paper's per-case method) less the cost of the same loop without the "
        "decision, runs interleaved in 500-step chunks, median "
        "of 5 repeats; µs/step the same time per step (JSON also gives the per-step figures of "
        "a controller stepping through the run: compute_ratio_in_loop). U_dc, J, psi*, the PI "
        "gains are assumed (see the scenario file).",
        tuple(PaperRow(s, {}, v) for s, v in PAPER_001_TABLE9.items()),
        (
            Column("t_rmse", "T_rip"),
            Column("psi_rmse", "psi_rip"),
            Column("thd"),
            Column("thd_harmonics", "(harm.)"),
            Column("cal_ave"),
            Column("f_ave_hz"),
            Column("f_sw_hz"),
            Column("zero_share"),
            Column("compute_ratio"),
            Column("compute_ns_hot"),
        ),
        compute_ratios=True,
        window="0-2 s",
    ),
}


@dataclass(frozen=True)
class MTPAStudy:
    """An MTPA study (docs/physics.md#field-oriented-control-and-mtpa): every strategy at every load
    step of the scenario, then the mismatch cases — the controller's L_d and L_q scaled by (f_d,
    f_q) — for the strategies that depend on a model, and paper 002's printed injection form beside
    the corrected one."""

    caption: str
    how: str
    claims: tuple[str, ...]  #: what the paper claims, checked per load
    strategies: tuple[str, ...] = ("foc_zero_d", "foc_formula", "foc_injection")
    mismatch_strategies: tuple[str, ...] = ("foc_formula", "foc_injection")
    #: (f_d, f_q): each alone at 0.7 and 1.3, then both together, alike and opposite
    mismatches: tuple[tuple[float, float], ...] = (
        (0.7, 1.0),
        (1.3, 1.0),
        (1.0, 0.7),
        (1.0, 1.3),
        (0.7, 0.7),
        (1.3, 1.3),
        (0.7, 1.3),
        (1.3, 0.7),
    )


_MTPA_HOW = (
    "theta = mean over the second half of each load step of the measured current angle "
    "atan2(-i_d, |i_q|) (the dither averages out); |i_s| = mean of the measured amplitude "
    "|i_alpha_beta| there; theta_MTPA, |i_s|_MTPA and |i_s| under i_d = 0 computed from the "
    "plant's parameters at the load torque (paper 002 eq 8, 10); settle = time from the load step "
    "until the angle, averaged over one dither period, stays within 0.5 deg of its final value. "
    "Mismatch: the controller's L_d, L_q scaled (the plant's unchanged). foc_injection (corrected) "
    "demodulates the torque per ampere of a voltage-model flux estimate against the measured "
    "current angle; as_printed is paper 002 eq 16 + sin demodulation."
)

MTPA_STUDIES: dict[str, MTPAStudy] = {
    "ipmsm_mtpa": MTPAStudy(
        "MTPA on paper 001's interior PMSM (paper 002's laws): loads 5, 10, 15 N·m",
        _MTPA_HOW,
        (),
    ),
    "hs_ipmsm_mtpa": MTPAStudy(
        "paper 002 (Yuan et al., JMEE 2018) Fig 6 scenario: 100 rad/s, loads 2, 4, 6 N·m",
        _MTPA_HOW,
        (
            "the current angle settles at each load step well under a second",
            "less current than i_d = 0 control",
        ),
    ),
}
