"""The papers' published numbers, for side-by-side tables (SPEC §8). Data only."""

from __future__ import annotations

__all__ = ["PAPER_000_TABLE2"]

#: Li et al., EMCA 2022, Table 2 (window 0.05-6 s) and the deadbeat shares quoted in its §4
PAPER_000_TABLE2: dict[str, dict[str, float]] = {
    "mptc": {"t_rmse": 0.2582, "psi_rmse": 0.0083, "deadbeat_share": 0.0},
    "mptc_db": {"t_rmse": 0.1887, "psi_rmse": 0.0083, "deadbeat_share": 0.4404},
    "db_mptc": {"t_rmse": 0.0624, "psi_rmse": 0.0047, "deadbeat_share": 0.9980},
}
