"""Scenario files: ROS 2 parameter files (``<node>: ros__parameters: ...``) → :class:`Scenario`.

The same file feeds the nodes with ``--ros-args --params-file``. Sections: ``/**`` (shared by all
nodes) and ``/drive/<node>`` for plant, speed_pi, torque_controller and metrics_logger. Nested maps
(``motor:``) become dotted ROS parameters (``motor.r_s``). The shared ``machine`` picks the plant's
motor model; the torque controller's ``family`` picks its controller family, whose settings class
reads the rest of that section.
"""

from __future__ import annotations

import dataclasses
import re
import typing
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

import yaml

from .core.control import CONTROLLERS, controller_class
from .core.control.speed_pi import SpeedPIParams
from .core.devices import Device, load_device, parse_device
from .core.losses import LossParams
from .core.machines import Machine, motor_class, saturation_class
from .core.scenario import LoggerParams, PlantParams, RunParams, Scenario
from .core.signals import EXTERNAL_PREFIX
from .errors import ConfigError
from .interface import NAMESPACE, NODES

__all__ = [
    "FAMILY_KEY",
    "OWN_NODES",
    "apply_settings",
    "LEGACY_FAMILIES",
    "SHARED",
    "RclLoader",
    "build_section",
    "config_dir",
    "device_names",
    "device_of",
    "family_of",
    "load_scenario",
    "load_scenario_text",
    "nested_types",
    "parse_yaml",
    "resolve_scenario_path",
    "scenario_names",
    "section_class",
    "section_classes",
    "section_fields",
    "section_parameters",
]

SHARED = "/**"

try:  # libyaml's parser where PyYAML has it: a scenario parses in a tenth of the time
    from yaml import CSafeLoader as _SafeLoader
except ImportError:  # pragma: no cover — PyYAML built without libyaml
    from yaml import SafeLoader as _SafeLoader  # type: ignore[assignment]


class RclLoader(_SafeLoader):
    """YAML as rcl reads a parameter file (``--params-file``): a number in exponent form without
    a dot (``5e-5``) is a number, not the string YAML 1.1 makes of it; a key given twice in one
    mapping is an error, not a silent overwrite."""

    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: dict[Any, yaml.Node] = {}
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=deep)
            if key in seen:
                raise yaml.constructor.ConstructorError(
                    "while reading a mapping",
                    node.start_mark,
                    f"key {key!r} given twice (first at line {seen[key].start_mark.line + 1})",
                    key_node.start_mark,
                )
            seen[key] = key_node
        return super().construct_mapping(node, deep=deep)


RclLoader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def parse_yaml(text: str, where: str | Path) -> Any:
    """Parameter-file YAML (see :class:`RclLoader`); ConfigError names ``where``."""
    try:
        return yaml.load(text, Loader=RclLoader)  # noqa: S506 — a SafeLoader subclass
    except yaml.YAMLError as e:
        raise ConfigError(f"{where}: not valid YAML: {e}") from None


#: the torque controller's key that names its controller family (not a field of its settings)
FAMILY_KEY = "family"
#: the family of a recording made before scenarios named one, by machine
LEGACY_FAMILIES = {Machine.INDUCTION: "mptc_im", Machine.PMSM: "mptc_pmsm"}


def config_dir() -> Path:
    """The scenario folder: the source tree's ``config/`` when this package runs from a source
    checkout, else the installed ``share/predictive_drive/config`` found the ROS way, through the
    ament index (``AMENT_PREFIX_PATH``: a colcon install, a ROS install), else under this
    interpreter's prefix (a pip install into a venv)."""
    import sys

    source = Path(__file__).resolve().parents[2] / "config"
    if (source.parent / "package.xml").is_file() and source.is_dir():
        return source
    looked = [str(source)]
    share = _ament_share()
    if share is not None:
        if (share / "config").is_dir():
            return share / "config"
        looked.append(str(share / "config"))
    else:
        looked.append("the ament index (AMENT_PREFIX_PATH): no predictive_drive")
    prefix = Path(sys.prefix) / "share" / "predictive_drive" / "config"
    if prefix.is_dir():
        return prefix
    looked.append(str(prefix))
    raise ConfigError(f"no scenario folder found; looked in: {'; '.join(looked)}")


def _ament_share() -> Path | None:
    """The package's share directory from the ament index, or None where there is none."""
    try:
        from ament_index_python.packages import get_package_share_directory
    except ImportError:  # a plain pip install without ROS
        return None
    try:
        return Path(get_package_share_directory("predictive_drive"))
    except LookupError:  # PackageNotFoundError is a KeyError
        return None
    except OSError:  # no AMENT_PREFIX_PATH at all: a venv of the PyPI wheels, which set none
        return None


def scenario_names() -> list[str]:
    return sorted(p.stem for p in config_dir().glob("*.yaml"))


def device_names() -> list[str]:
    """The device files of the scenario folder's ``devices/`` (their names)."""
    return sorted(p.stem for p in (config_dir() / "devices").glob("*.json"))


def device_of(plant: PlantParams, where: str | Path, *, text: str | None = None) -> Device | None:
    """The devices ``plant.losses.device`` names — a file of the scenario folder's ``devices/``
    by its name, or a path — read and checked against the DC link (None where it names none).
    ``text``: the file's text as a recording stored it, read instead. ConfigError names the
    key, the file and the field."""
    name = plant.losses.device
    if not name:
        return None
    key = f"{where}: /drive/plant.losses.device"
    device = read_device(name, key, text=text)
    device.check_voltage(plant.u_dc, key)
    return device


def controller_device_of(params: Any, where: str | Path) -> Device | None:
    """The devices a torque controller's ``device`` names (its loss-aware cost's switching
    energies), read as :func:`device_of` reads the plant's; None where it names none."""
    name = getattr(params, "device", "")
    if not name:
        return None
    return read_device(name, f"{where}: /drive/torque_controller.device")


def read_device(name: str, key: str, *, text: str | None = None) -> Device:
    """The device file ``name`` (a name in the scenario folder's ``devices/``, or a path), or
    its stored ``text``; ``key`` names the setting in errors."""
    if text is not None:
        return parse_device(text, f"{name} (stored)")
    p = Path(name)
    if p.suffix != ".json" and "/" not in name:
        p = config_dir() / "devices" / f"{name}.json"
        if not p.is_file():
            raise ConfigError(
                f"{key}: no device {name!r}; available: {', '.join(device_names())} (or "
                f"give a path to a .json device file)"
            )
    elif not p.is_file():
        raise ConfigError(f"{key}: no device file {p}")
    try:
        return load_device(p)
    except ConfigError as e:
        raise ConfigError(f"{key}: {e}") from None


def resolve_scenario_path(name_or_path: str | Path) -> Path:
    """The file of a scenario given by name (``im_paper``: the scenario folder's
    ``im_paper.yaml``) or by path (with a .yaml suffix, a folder in it, or a file that exists). A
    bare name is a scenario's even where a folder of that name lies in the working directory
    (``bags/im_short`` beside ``im_short``...)."""
    p = Path(name_or_path)
    bare = isinstance(name_or_path, str) and "/" not in name_or_path and not p.suffix
    if not bare and (p.suffix in (".yaml", ".yml") or p.exists()):
        if p.is_dir():
            raise ConfigError(f"scenario {p} is a directory, not a scenario file")
        if not p.is_file():
            raise ConfigError(f"scenario file {p} does not exist")
        return p
    candidate = config_dir() / f"{name_or_path}.yaml"
    if not candidate.is_file():
        if bare and p.is_file():  # a scenario file of the user's, named without a suffix
            return p
        raise ConfigError(
            f"unknown scenario {str(name_or_path)!r}; available: {', '.join(scenario_names())} "
            f"(or give a path to a .yaml file)"
        )
    return candidate


def section_fields(cls: type) -> list[str]:
    return [f.name for f in dataclasses.fields(cls)]


def nested_types(cls: type) -> dict[str, type]:
    """The fields of ``cls`` that are themselves parameter dataclasses (``motor``), by name."""
    hints = typing.get_type_hints(cls)
    return {
        f.name: hints[f.name]
        for f in dataclasses.fields(cls)
        if isinstance(hints[f.name], type) and dataclasses.is_dataclass(hints[f.name])
    }


def section_class(
    node: str, machine: str, family: str | None = None
) -> tuple[type, dict[str, type]]:
    """(dataclass the node's section builds, nested dataclasses by key) for a machine type; the
    torque controller's depends on its controller ``family``."""
    if node == "torque_controller":
        if family is None:
            raise ValueError("the torque controller's section depends on its family")
        ctrl = controller_class(family).params_type
        return ctrl, nested_types(ctrl)
    fixed: dict[str, tuple[type, dict[str, type]]] = {
        "plant": (
            PlantParams,
            {
                "motor": motor_class(machine),
                "saturation": saturation_class(machine),
                "losses": LossParams,
            },
        ),
        "speed_pi": (SpeedPIParams, {}),
        "metrics_logger": (LoggerParams, {}),
    }
    return fixed[node]


def section_classes(machine: str, family: str) -> dict[str, tuple[type, dict[str, type]]]:
    """:func:`section_class` of every node."""
    return {node: section_class(node, machine, family) for node in NODES}


def _coerce(value: Any, hint: Any, where: str) -> Any:
    origin = typing.get_origin(hint)
    if hint is bool:
        if not isinstance(value, bool):
            raise ConfigError(f"{where}: expected true or false, got {value!r}")
        return value
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
        kinds = {type(v) for v in value}
        if len(kinds) > 1:  # rcl's parameter-file parser refuses a mixed sequence
            raise ConfigError(
                f"{where}: {value!r} mixes "
                f"{' and '.join(sorted(k.__name__ for k in kinds))}; a ROS 2 parameter file's "
                f"list holds one type (write 0.0, not 0, beside 0.5)"
            )
        return tuple(
            _coerce(v, typing.get_args(hint)[0], f"{where}[{i}]") for i, v in enumerate(value)
        )
    raise ConfigError(f"{where}: unsupported parameter type {hint!r}")  # pragma: no cover


#: what a ROS 2 parameter can hold, in words (a section of the user's own is checked for it)
ROS_PARAMETER_KINDS = (
    "true/false, an integer, a number, a string, or a non-empty list of one of these (all of "
    "one kind: 0.0, not 0, beside 0.5); a group of them as a nested map"
)


def check_ros_parameters(params: Any, where: str, prefix: str = "") -> None:
    """Every value of ``params`` (nested maps as dotted names) is one a ROS 2 parameter file can
    give a node, as rcl parses them: ConfigError names the key and what a parameter can hold.
    Checked before anything starts (a list of mixed kinds failed inside rcl's argument parser,
    an empty one inside the node's rclpy, with the graph up)."""
    for key, value in params.items():
        name = f"{prefix}{key}"
        if isinstance(value, dict):
            check_ros_parameters(value, where, f"{name}.")
            continue
        scalar = (bool, int, float, str)
        if isinstance(value, list):
            kinds = {type(v) for v in value}
            fine = len(kinds) == 1 and next(iter(kinds)) in scalar
        else:
            fine = isinstance(value, scalar)
        if not fine:
            raise ConfigError(
                f"{where}.{name}: {value!r} cannot be a ROS parameter; one holds "
                f"{ROS_PARAMETER_KINDS}"
            )


def build_section(cls: type, data: Any, nested: dict[str, type], where: str) -> Any:
    """The dataclass ``cls`` from one section's parameters; ConfigError names ``where`` and the key."""
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
            kwargs[f.name] = build_section(nested[f.name], data[f.name], {}, key_where)
        else:
            kwargs[f.name] = _coerce(data[f.name], hints[f.name], key_where)
    try:
        return cls(**kwargs)
    except ConfigError as e:
        raise ConfigError(f"{where}: {e}") from None


def _family_hint(key: str, family: Any) -> str:
    """A sentence naming the controller families that have ``key``, when the scenario's family
    (``family``) does not: a setting of another family is a different mistake from a typo."""
    if family is None:
        return ""
    owners = [
        name
        for name, cls in CONTROLLERS.items()
        if name != family and key in section_fields(cls.params_type)
    ]
    if not owners:
        return ""
    return (
        f" ({key} is a setting of the controller famil{'ies' if len(owners) > 1 else 'y'} "
        f"{', '.join(owners)}; this scenario's torque controller is {family})"
    )


def family_of(params: dict[str, Any], where: str, default: str | None = None) -> str:
    """The controller family a torque_controller section names; ConfigError lists the valid ones."""
    family = params.get(FAMILY_KEY, default)
    if family is None:
        raise ConfigError(f"{where}: missing key {FAMILY_KEY!r}; one of {', '.join(CONTROLLERS)}")
    if family not in CONTROLLERS:
        raise ConfigError(
            f"{where}.{FAMILY_KEY}: {family!r} is not one of {', '.join(CONTROLLERS)}"
        )
    return str(family)


def _params(doc: dict[str, Any], key: str, path: str | Path) -> dict[str, Any]:
    if key not in doc:
        raise ConfigError(
            f"{path}: missing section {key!r} (a ROS 2 parameter file needs "
            f"{', '.join([SHARED] + [f'{NAMESPACE}/{n}' for n in NODES])})"
        )
    section = doc[key]
    if not isinstance(section, dict) or set(section) != {"ros__parameters"}:
        raise ConfigError(f"{path}: section {key!r} must hold exactly one key 'ros__parameters'")
    params = section["ros__parameters"]
    if not isinstance(params, dict):
        raise ConfigError(f"{path}: {key}.ros__parameters must be a mapping")
    return params


def load_scenario(
    name_or_path: str | Path,
    *,
    strategy: str | None = None,
    duration: float | None = None,
    own: Collection[str] = (),
) -> Scenario:
    """Read and validate a scenario, with the command line's overrides applied (the starting
    strategy, the run length in s); every error names the file and the key. ``own``: the nodes
    that are the user's (``run --external``), whose sections are theirs (see
    :func:`load_scenario_text`)."""
    path = resolve_scenario_path(name_or_path)
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError as e:
        raise ConfigError(
            f"{path}: not a scenario file (not UTF-8 text: byte {e.start} is {e.object[e.start]:#x})"
        ) from None
    except OSError as e:
        raise ConfigError(f"{path}: cannot read it: {e.strerror}") from None
    sc = load_scenario_text(text, path, own=own, strategy=strategy)
    return sc.with_strategy(strategy).with_duration(duration)


def load_scenario_text(
    text: str,
    path: str | Path,
    *,
    legacy: bool = False,
    own: Collection[str] = (),
    strategy: str | None = None,
    device_text: str | None = None,
) -> Scenario:
    """Validate scenario text; ``path`` names it in errors (a file, or a bag it was stored in).
    ``strategy``: the strategy the run starts with, in place of the file's, before the
    controller's keys are checked (a horizon is checked against the strategy that runs, not
    the file's). ``legacy``: a recording's stored text, which may predate the ``family`` key. ``own``: nodes
    of the user's own (:data:`OWN_NODES`): their sections' keys are the user's, passed to their
    node as they are and not checked; the scenario holds the built-in settings only where the
    section happens to be a valid one (else None), and a torque controller of one's own is
    named as its family's where the section names one of this machine (else the machine's
    first). The devices ``plant.losses.device`` names are read (``device_text``: from that text,
    as a recording stored it)."""
    unknown_own = sorted(set(own) - set(OWN_NODES))
    if unknown_own:
        raise ConfigError(
            f"--external {unknown_own[0]}: not a node you can replace; one of {', '.join(OWN_NODES)}"
        )
    doc = parse_yaml(text, path)
    if not isinstance(doc, dict):
        raise ConfigError(f"{path}: expected a ROS 2 parameter file (a mapping of node sections)")
    expected = {SHARED, *(f"{NAMESPACE}/{n}" for n in NODES)}
    unknown = sorted(set(doc) - expected)
    if unknown:
        raise ConfigError(
            f"{path}: unknown section {unknown[0]!r}; allowed: {', '.join(sorted(expected))}"
        )
    run = build_section(RunParams, _params(doc, SHARED, path), {}, f"{path}: {SHARED}")
    ctrl_key = f"{NAMESPACE}/torque_controller"
    ctrl_params = dict(_params(doc, ctrl_key, path))
    if "torque_controller" in own:
        family = _own_family(ctrl_params, run.machine)
    else:
        default = LEGACY_FAMILIES[Machine(run.machine)] if legacy else None
        family = family_of(ctrl_params, f"{path}: {ctrl_key}", default)
    ctrl_params.pop(FAMILY_KEY, None)
    if strategy is not None and "torque_controller" not in own:
        if not strategy.startswith(EXTERNAL_PREFIX):  # a built-in's: checked with its keys
            ctrl_params["strategy"] = strategy
    if (controls := controller_class(family).machine) != run.machine:
        raise ConfigError(
            f"{path}: {ctrl_key}.{FAMILY_KEY}: {family!r} controls a {controls} machine, but the "
            f"scenario's machine is {run.machine!r}"
        )
    known = section_fields(controller_class(family).params_type)
    for key in ctrl_params if "torque_controller" not in own else ():  # the user's: any key
        if key not in known and (hint := _family_hint(key, family)):
            raise ConfigError(
                f"{path}: {ctrl_key}: unknown key {key!r}; allowed keys: {', '.join(known)}{hint}"
            )
    built: dict[str, Any] = {}
    for node, (cls, nested) in section_classes(run.machine, family).items():
        key = f"{NAMESPACE}/{node}"
        params = ctrl_params if node == "torque_controller" else _params(doc, key, path)
        if node not in own:
            built[node] = build_section(cls, params, nested, f"{path}: {key}")
            continue
        check_ros_parameters(params, f"{path}: {key}")
        try:  # the user's: the built-in settings where it happens to hold them
            built[node] = build_section(cls, params, nested, f"{path}: {key}")
        except ConfigError:
            built[node] = None
    device = device_of(built["plant"], path, text=device_text)
    ctrl = built["torque_controller"]
    # the plant's file where the controller names the same (as read: a recording's stored one)
    same = device is not None and getattr(ctrl, "device", "") == built["plant"].losses.device
    ctrl_device = device if same else controller_device_of(ctrl, path)
    try:
        sc = Scenario(
            run,
            built["plant"],
            built["speed_pi"],
            built["torque_controller"],
            built["metrics_logger"],
            family=family,
            source=str(path),
            text=text,
            external="torque_controller" in own,
            own=frozenset(own),
            device=device,
            controller_device=ctrl_device,
        )
    except ConfigError as e:  # its messages name the section and key
        raise ConfigError(f"{path}: {e}") from None
    _check_windows(sc, path)
    return sc


#: the nodes a user may replace with their own (``run --external``)
OWN_NODES = ("torque_controller", "speed_pi")


def _own_family(params: dict[str, Any], machine: str) -> str:
    """The family a torque controller of one's own is filed under (its strategy names): the
    one its section names where that is one of this machine's, else the machine's first."""
    named = params.get(FAMILY_KEY)
    if named in CONTROLLERS and controller_class(str(named)).machine == machine:
        return str(named)
    return next(f for f, cls in CONTROLLERS.items() if cls.machine == machine)


def section_parameters(text: str, node: str) -> dict[str, Any]:
    """The parameters a scenario's section gives ``node``, as rcl names them (nested maps as
    ``motor.r_s``): what a node of the user's own is started with, for the bag's metadata."""
    doc = parse_yaml(text, "scenario")
    section = doc.get(f"{NAMESPACE}/{node}", {}) if isinstance(doc, dict) else {}
    params = section.get("ros__parameters", {}) if isinstance(section, dict) else {}

    def flat(d: dict[str, Any], prefix: str) -> dict[str, Any]:
        out: dict[str, Any] = {}
        for k, v in d.items():
            out.update(flat(v, f"{prefix}{k}.") if isinstance(v, dict) else {f"{prefix}{k}": v})
        return out

    return flat(params, "") if isinstance(params, dict) else {}


def _check_windows(sc: Scenario, path: str | Path) -> None:
    """The file's metrics windows must lie in its run (a shorter --duration clips them)."""
    lo, d = sc.logger, sc.run.duration
    if lo.window_end > d:
        raise ConfigError(
            f"{path}: /drive/metrics_logger.window_end {lo.window_end:g} s lies beyond the run "
            f"({d:g} s); the window is [window_start, window_end) of it"
        )
    if lo.thd_window and lo.thd_window[1] > d:
        raise ConfigError(
            f"{path}: /drive/metrics_logger.thd_window ends at {lo.thd_window[1]:g} s, beyond "
            f"the run ({d:g} s)"
        )


def apply_settings(
    text: str, settings: dict[str, Any], where: str | Path, *, own: Collection[str] = ()
) -> str:
    """Scenario text with parameters replaced, as a new parameter file (a run's bag stores it).

    Keys are dotted: ``ts`` or ``duration`` (shared), or ``<node>.<key>[.<sub>]``, e.g.
    ``torque_controller.motor.l_q``. A value is a number, a string or a list; a string ``*f``
    multiplies the present value by ``f`` (``*0.7``: 70 % of it). The section of a node of the
    user's own (``own``) takes any key, groups made as needed (``torque_controller.gain=3``).
    ConfigError names the key and what it may be."""
    doc = parse_yaml(text, where)
    if not isinstance(doc, dict):
        raise ConfigError(f"{where}: expected a ROS 2 parameter file")
    for key, value in settings.items():
        node, _, rest = key.partition(".")
        if node in NODES and rest:
            section, path = f"{NAMESPACE}/{node}", rest.split(".")
        elif not rest:
            section, path = SHARED, [node]
        else:
            raise ConfigError(
                f"setting {key!r}: expected a shared key (ts, duration, ...) or "
                f"<node>.<key> with node one of {', '.join(NODES)}"
            )
        params = _params(doc, section, where)
        theirs = node in own
        for depth, part in enumerate(path[:-1]):
            if part not in params and (
                theirs or part in _defaulted(doc, node, where, tuple(path[:depth]))
            ):  # the user's, or a group left to its default (``plant.saturation``)
                params[part] = {}
            sub = params.get(part)
            if not isinstance(sub, dict):
                raise ConfigError(f"setting {key!r}: {section} has no group {part!r}")
            params = sub
        leaf = path[-1]
        optional = _defaulted(doc, node, where, tuple(path[:-1]))
        if leaf not in params and leaf not in optional and not theirs:
            family = params.get(FAMILY_KEY) if node == "torque_controller" else None
            meant = [k for k in _setting_keys(doc, where) if k.rsplit(".", 1)[-1] == leaf]
            raise ConfigError(
                f"setting {key!r}: {'.'.join([section, *path[:-1]])} has no key {leaf!r} here"
                + (f"; did you mean {' or '.join(meant)}?" if meant else "")
                + f" (keys there: {', '.join(sorted(set(params) | optional))})"
                + _family_hint(leaf, family)
            )
        if isinstance(value, str) and value.startswith("*"):
            try:
                factor = float(value[1:])
            except ValueError:
                raise ConfigError(f"setting {key!r}: {value!r} is not *<number>") from None
            present = params.get(leaf)
            if isinstance(present, bool) or not isinstance(present, (int, float)):
                raise ConfigError(f"setting {key!r}: {present!r} is not a number to scale")
            value = present * factor
        params[leaf] = value
    return str(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True))


def _setting_keys(doc: dict[str, Any], where: str | Path) -> list[str]:
    """Every key a setting can name in this scenario, dotted as settings name them (``ts``,
    ``torque_controller.lambda_psi``, ``plant.motor.r_s``), the ones left to their default too."""

    def walk(params: dict[str, Any], prefix: str) -> list[str]:
        out = []
        for k, v in params.items():
            out += walk(v, f"{prefix}{k}.") if isinstance(v, dict) else [f"{prefix}{k}"]
        return out

    keys = walk(_params(doc, SHARED, where), "")
    for node in NODES:
        if f"{NAMESPACE}/{node}" in doc:
            keys += walk(_params(doc, f"{NAMESPACE}/{node}", where), f"{node}.")
            for k in sorted(_defaulted(doc, node, where)):
                group = _defaulted(doc, node, where, (k,))
                keys += [f"{node}.{k}.{g}" for g in sorted(group)] or [f"{node}.{k}"]
    return list(dict.fromkeys(keys))


def _defaulted(
    doc: dict[str, Any], node: str, where: str | Path, group: tuple[str, ...] = ()
) -> set[str]:
    """The keys of ``node``'s section (or of its nested ``group``, e.g. ``("saturation",)``) a
    scenario file may leave out (they have a default): a setting may give them though the file
    does not."""
    if node not in NODES:
        return set()
    machine = _params(doc, SHARED, where).get("machine")
    family = _params(doc, f"{NAMESPACE}/torque_controller", where).get(FAMILY_KEY)
    try:
        cls, nested = section_class(node, str(machine), family)
    except (KeyError, ValueError):
        return set()
    for part in group:
        if part not in nested:
            return set()
        cls = nested[part]
        nested = nested_types(cls)
    return {f.name for f in dataclasses.fields(cls) if f.default is not dataclasses.MISSING}


#: what a torque controller of the user's own keeps of a built-in family's section: the
#: controller's model of the machine (docs/ros.md#writing-your-own-controller)
YOURS_KEEPS = ("motor",)


def for_your_controller(text: str, where: str | Path, settings: Mapping[str, Any]) -> str:
    """Scenario text as a torque controller of the user's own gets it. Where the section is a
    built-in family's (it names one), the family's own keys (family, strategy, its weights and
    thresholds) mean nothing to the user's node: the section keeps only :data:`YOURS_KEEPS`
    and the keys ``settings`` give it (``torque_controller.KEY``, applied after). A section
    that names no built-in family is the user's, and stays as it is."""
    doc = parse_yaml(text, where)
    key = f"{NAMESPACE}/torque_controller"
    if not isinstance(doc, dict) or not isinstance(doc.get(key), dict):
        return text
    params = _params(doc, key, where)
    if params.get(FAMILY_KEY) not in CONTROLLERS:
        return text
    doc[key]["ros__parameters"] = {k: v for k, v in params.items() if k in YOURS_KEEPS}
    return str(yaml.safe_dump(doc, sort_keys=False, allow_unicode=True))


def scenario_with(
    scenario: str | Path, settings: dict[str, Any], out_dir: Path, *, own: Collection[str] = ()
) -> Path:
    """The scenario as a file in ``out_dir`` with ``settings`` applied (see
    :func:`apply_settings`; the file itself when there are none): what a ROS engine's nodes
    read and the run's bag stores."""
    path = resolve_scenario_path(scenario)
    yours = "torque_controller" in own
    if not settings and not yours:
        return path
    tag = "_".join(f"{k.rsplit('.', 1)[-1]}_{v}" for k, v in settings.items())
    out = out_dir / f"{path.stem}_{re.sub(r'[^A-Za-z0-9_.-]', '', tag)}.yaml"
    text = path.read_text()
    if yours:
        text = for_your_controller(text, path, settings)
    out.write_text(apply_settings(text, settings, path, own=own))
    return out
