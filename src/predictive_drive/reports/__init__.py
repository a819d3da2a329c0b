"""What the package draws and tabulates beyond a run's metrics: the papers' tables
(:mod:`.papers`), the runs' figures (:mod:`.figures`, matplotlib) and the Foxglove layout
(:mod:`.layout`)."""

__all__ = ["figures", "layout", "papers"]
