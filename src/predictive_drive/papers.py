"""The papers' published numbers, for side-by-side tables (SPEC §8). Data only."""

from __future__ import annotations

__all__ = ["PAPER_000_TABLE2", "PAPER_001_TABLE1", "PAPER_001_TABLE2", "PAPER_001_TABLE9"]

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
