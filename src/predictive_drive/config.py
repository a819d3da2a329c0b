"""Scenario files: ROS 2 parameter files (``<node>: ros__parameters: ...``) → :class:`Scenario`.

The same file feeds the nodes with ``--ros-args --params-file``. Sections: ``/**`` (shared by all
nodes) and ``/drive/<node>`` for plant, speed_pi, torque_controller and metrics_logger. Nested maps
(``motor:``) become dotted ROS parameters (``motor.r_s``).
"""

from __future__ import annotations

import dataclasses
import typing
from pathlib import Path
from typing import Any

import yaml

from .core.control import InductionControllerParams, Machine, PMSMControllerParams
from .core.motors import PMSM, InductionMotor
from .core.scenario import LoggerParams, PlantParams, RunParams, Scenario
from .core.speed_pi import SpeedPIParams
from .errors import ConfigError

__all__ = [
    "NAMESPACE",
    "MACHINE_SECTIONS",
    "NODE_SECTIONS",
    "config_dir",
    "flatten",
    "load_scenario",
    "load_scenario_text",
    "resolve_scenario_path",
    "scenario_names",
    "section_fields",
]

NAMESPACE = "/drive"
SHARED = "/**"
Sections = dict[str, tuple[type, dict[str, type]]]


def _sections(motor: type, controller: type) -> Sections:
    return {
        "plant": (PlantParams, {"motor": motor}),
        "speed_pi": (SpeedPIParams, {}),
        "torque_controller": (controller, {"motor": motor}),
        "metrics_logger": (LoggerParams, {}),
    }


#: machine → node name → (dataclass built from its section, nested dataclasses by key)
MACHINE_SECTIONS: dict[Machine, Sections] = {
    Machine.INDUCTION: _sections(InductionMotor, InductionControllerParams),
    Machine.PMSM: _sections(PMSM, PMSMControllerParams),
}
#: the node sections every scenario file has (their classes depend on the machine)
NODE_SECTIONS = tuple(MACHINE_SECTIONS[Machine.INDUCTION])


def config_dir() -> Path:
    """The scenario folder: the source tree's ``config/`` or the installed ``share/.../config``."""
    here = Path(__file__).resolve()
    candidates = [here.parents[2] / "config"]
    import sys

    candidates.append(Path(sys.prefix) / "share" / "predictive_drive" / "config")
    for c in candidates:
        if c.is_dir():
            return c
    raise ConfigError(f"no scenario folder found; looked in {', '.join(map(str, candidates))}")


def scenario_names() -> list[str]:
    return sorted(p.stem for p in config_dir().glob("*.yaml"))


def resolve_scenario_path(name_or_path: str | Path) -> Path:
    p = Path(name_or_path)
    if p.suffix in (".yaml", ".yml") or p.exists():
        if not p.is_file():
            raise ConfigError(f"scenario file {p} does not exist")
        return p
    candidate = config_dir() / f"{name_or_path}.yaml"
    if not candidate.is_file():
        raise ConfigError(
            f"unknown scenario {str(name_or_path)!r}; available: {', '.join(scenario_names())} "
            f"(or give a path to a .yaml file)"
        )
    return candidate


def section_fields(cls: type) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)]


def _coerce(value: Any, hint: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    if hint is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ConfigError(f"{where}: expected a number, got {value!r}")
        return float(value)
    if hint is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ConfigError(f"{where}: expected an integer, got {value!r}")
        return value
    if hint is str:
        if not isinstance(value, str):
            raise ConfigError(f"{where}: expected a string, got {value!r}")
        return value
    if origin is tuple:
        if not isinstance(value, list):
            raise ConfigError(f"{where}: expected a list of numbers, got {value!r}")
        return tuple(
            _coerce(v, typing.get_args(hint)[0], f"{where}[{i}]") for i, v in enumerate(value)
        )
    raise ConfigError(f"{where}: unsupported parameter type {hint!r}")  # pragma: no cover


def _build(cls: type, data: Any, nested: dict[str, type], where: str) -> Any:
    if not isinstance(data, dict):
        raise ConfigError(f"{where}: expected a mapping of parameters, got {data!r}")
    names = section_fields(cls)
    unknown = sorted(set(data) - set(names))
    if unknown:
        raise ConfigError(f"{where}: unknown key {unknown[0]!r}; allowed keys: {', '.join(names)}")
    hints = typing.get_type_hints(cls)
    kwargs: dict[str, Any] = {}
    for f in dataclasses.fields(cls):
        if f.name not in data:
            if f.default is dataclasses.MISSING:
                raise ConfigError(f"{where}: missing key {f.name!r}")
            continue
        key_where = f"{where}.{f.name}"
        if f.name in nested:
            kwargs[f.name] = _build(nested[f.name], data[f.name], {}, key_where)
        else:
            kwargs[f.name] = _coerce(data[f.name], hints[f.name], key_where)
    try:
        return cls(**kwargs)
    except ConfigError as e:
        raise ConfigError(f"{where}: {e}") from None


def _params(doc: dict[str, Any], key: str, path: Path) -> dict[str, Any]:
    if key not in doc:
        raise ConfigError(
            f"{path}: missing section {key!r} (a ROS 2 parameter file needs "
            f"{', '.join([SHARED] + [f'{NAMESPACE}/{n}' for n in NODE_SECTIONS])})"
        )
    section = doc[key]
    if not isinstance(section, dict) or set(section) != {"ros__parameters"}:
        raise ConfigError(f"{path}: section {key!r} must hold exactly one key 'ros__parameters'")
    params = section["ros__parameters"]
    if not isinstance(params, dict):
        raise ConfigError(f"{path}: {key}.ros__parameters must be a mapping")
    return params


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Read and validate a scenario; every error names the file and the key."""
    path = resolve_scenario_path(name_or_path)
    return load_scenario_text(path.read_text(), path)


def load_scenario_text(text: str, path: str | Path) -> Scenario:
    """Validate scenario text; ``path`` names it in errors (a file, or a bag it was stored in)."""
    try:
        doc = yaml.safe_load(text)
    except yaml.YAMLError as e:
        raise ConfigError(f"{path}: not valid YAML: {e}") from None
    if not isinstance(doc, dict):
        raise ConfigError(f"{path}: expected a ROS 2 parameter file (a mapping of node sections)")
    expected = {SHARED, *(f"{NAMESPACE}/{n}" for n in NODE_SECTIONS)}
    unknown = sorted(set(doc) - expected)
    if unknown:
        raise ConfigError(
            f"{path}: unknown section {unknown[0]!r}; allowed: {', '.join(sorted(expected))}"
        )
    run = _build(RunParams, _params(doc, SHARED, path), {}, f"{path}: {SHARED}")
    built = {}
    for node, (cls, nested) in MACHINE_SECTIONS[Machine(run.machine)].items():
        key = f"{NAMESPACE}/{node}"
        built[node] = _build(cls, _params(doc, key, path), nested, f"{path}: {key}")
    return Scenario(
        run,
        built["plant"],
        built["speed_pi"],
        built["torque_controller"],
        built["metrics_logger"],
        str(path),
    )


def flatten(obj: Any, prefix: str = "") -> dict[str, Any]:
    """Dataclass → dotted ROS parameter names and values (tuples as lists)."""
    out: dict[str, Any] = {}
    for f in dataclasses.fields(obj):
        v = getattr(obj, f.name)
        if dataclasses.is_dataclass(v):
            out.update(flatten(v, f"{prefix}{f.name}."))
        else:
            out[f"{prefix}{f.name}"] = list(v) if isinstance(v, tuple) else v
    return out
