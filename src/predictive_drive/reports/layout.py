"""A Foxglove (and Lichtblick) layout for the drive's topics, generated from the one field table.

The per-step topics carry their field names only as ``layout.dim[0].label``, so a plot names a
field by its position (``/drive/state.data[7]`` is the torque). This module writes those
positions from :mod:`predictive_drive.core.signals`, so the layout cannot drift from the
messages: ``predictive-drive layout`` regenerates ``layouts/drive.foxglove.json``, and a test
holds every path to the labels.
"""

from __future__ import annotations

import contextlib
import json
from pathlib import Path
from typing import Any

from ..core.signals import DEVICES
from ..errors import ConfigError
from ..interface import TOPICS
from ..outputs import check_output_file

__all__ = ["PLOTS", "foxglove_layout", "write_layout"]

#: plot title → (topic key, field) series; one plot panel each
PLOTS: dict[str, list[tuple[str, str]]] = {
    "speed (rad/s)": [("state", "omega_m"), ("reference", "speed_ref")],
    "torque (N·m)": [("state", "torque"), ("reference", "torque_ref"), ("command", "torque_est")],
    "stator flux (Wb)": [
        ("state", "psi_alpha"),
        ("state", "psi_beta"),
        ("command", "flux_est"),
        ("reference", "flux_ref"),
    ],
    "currents (A)": [
        ("state", "i_alpha"),
        ("state", "i_beta"),
        ("command", "i_d_ref"),
        ("command", "i_q_ref"),
    ],
    "strategy (index), horizon, vector, current angle (rad)": [
        ("command", "strategy"),
        ("command", "horizon"),
        ("command", "vector"),
        ("command", "current_angle"),
    ],
    # /drive/losses: a run with plant.losses (docs/physics.md#losses-and-temperature); empty
    # without
    "temperatures (°C): junctions, heatsink, winding, rotor": [
        *(("losses", f"tj_{name}") for name in DEVICES),
        ("losses", "t_sink"),
        ("losses", "t_winding"),
        ("losses", "t_rotor"),
    ],
}


def _path(key: str, field: str) -> str:
    topic = TOPICS[key]
    return f"{topic.name}.data[{topic.fields.index(field)}]"


def _plot(title: str, series: list[tuple[str, str]]) -> dict[str, Any]:
    return {
        "title": title,
        "paths": [
            {
                "value": _path(key, field),
                "enabled": True,
                "timestampMethod": "receiveTime",
                "label": f"{TOPICS[key].name.rsplit('/', 1)[-1]}.{field}",
            }
            for key, field in series
        ],
        "showXAxisLabels": True,
        "showYAxisLabels": True,
        "showLegend": True,
        "legendDisplay": "floating",
        "isSynced": True,
        "xAxisVal": "timestamp",
        "sidebarDimension": 240,
    }


def _mosaic(ids: list[str], direction: str = "column") -> Any:
    """A balanced split tree of the panels (Foxglove's mosaic layout)."""
    if len(ids) == 1:
        return ids[0]
    half = len(ids) // 2
    other = "row" if direction == "column" else "column"
    return {
        "direction": direction,
        "first": _mosaic(ids[:half], other),
        "second": _mosaic(ids[half:], other),
        "splitPercentage": 100 * half / len(ids),
    }


def foxglove_layout() -> dict[str, Any]:
    """The layout: a plot per entry of :data:`PLOTS`, and the /diagnostics summary."""
    config: dict[str, Any] = {}
    ids = []
    for n, (title, series) in enumerate(PLOTS.items()):
        pid = f"Plot!drive{n}"
        config[pid] = _plot(title, series)
        ids.append(pid)
    config["DiagnosticSummary!drive"] = {
        "minLevel": 0,
        "pinnedIds": [],
        "hardwareIdFilter": "",
        "topicToRender": TOPICS["diagnostics"].name,
    }
    ids.append("DiagnosticSummary!drive")
    return {
        "configById": config,
        "globalVariables": {},
        "userNodes": {},
        "playbackConfig": {"speed": 1},
        "layout": _mosaic(ids),
    }


def write_layout(path: str | Path, *, replace: bool = False) -> Path:
    """Write the layout as JSON (the format Foxglove imports), whole or not at all (a temporary
    file renamed); a file already there is replaced only with ``replace``. ConfigError names the
    path and why it is not written."""
    p = Path(path)
    if p.is_dir():
        raise ConfigError(f"layout --out {p}: a directory, not a file")
    if p.exists() and not replace:
        raise ConfigError(f"layout --out {p}: the file exists; --force replaces it")
    check_output_file(p, option="layout --out")
    text = json.dumps(foxglove_layout(), indent=2, ensure_ascii=False) + "\n"
    tmp = p.with_name(p.name + ".tmp")
    try:
        p.parent.mkdir(parents=True, exist_ok=True)
        tmp.write_text(text)
        tmp.replace(p)
    except OSError as e:
        with contextlib.suppress(OSError):  # under a file, on a read-only disk: nothing to undo
            tmp.unlink(missing_ok=True)
        raise ConfigError(f"layout --out {p}: cannot write it: {e.strerror or e}") from None
    return p
