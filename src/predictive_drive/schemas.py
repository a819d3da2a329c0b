"""Message definitions as rosbag2 writes them into MCAP schemas, and their RIHS01 type hashes,
read from the .msg and type-description files the ROS message packages install under
``share/<pkg>/msg/`` (in the interpreter's prefix, where the PyPI wheels put them, or in the
ament prefixes of a ROS install)."""

from __future__ import annotations

import json
import os
import sys
from functools import cache
from pathlib import Path

from .errors import BagError

__all__ = ["message_definition", "type_hash"]


def _share_dirs() -> list[Path]:
    dirs = [Path(sys.prefix) / "share"]
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            dirs.append(Path(prefix) / "share")
    return dirs


def _interface_file(type_name: str, suffix: str) -> Path:
    pkg, _, name = type_name.split("/")
    for d in _share_dirs():
        p = d / pkg / "msg" / f"{name}{suffix}"
        if p.is_file():
            return p
    raise BagError(
        f"message definition {type_name} not found under share/{pkg}/msg/ in "
        f"{', '.join(str(d) for d in _share_dirs())} (are the ROS message packages installed?)"
    )


def _deps(text: str, pkg: str) -> list[str]:
    builtin = {
        "bool",
        "byte",
        "char",
        "float32",
        "float64",
        "int8",
        "uint8",
        "int16",
        "uint16",
        "int32",
        "uint32",
        "int64",
        "uint64",
        "string",
        "wstring",
    }
    out = []
    for line in text.splitlines():
        line = line.split("#", 1)[0].strip()
        if not line:
            continue
        parts = line.split()
        if len(parts) < 2 or "=" in parts[1]:
            continue
        base = parts[0].split("[", 1)[0].split("<=", 1)[0]
        if base in builtin:
            continue
        if "/" in base:
            dep_pkg, dep = base.split("/")[0], base.split("/")[-1]
        else:
            dep_pkg, dep = ("builtin_interfaces" if base in ("Time", "Duration") else pkg), base
        full = f"{dep_pkg}/msg/{dep}"
        if full not in out:
            out.append(full)
    return out


@cache
def message_definition(type_name: str) -> str:
    """Full ros2msg text with dependencies, as rosbag2 writes it into MCAP schemas."""
    main = _interface_file(type_name, ".msg").read_text()
    parts = [main]
    seen: set[str] = set()
    queue = _deps(main, type_name.split("/")[0])
    while queue:
        dep = queue.pop(0)
        if dep in seen:
            continue
        seen.add(dep)
        text = _interface_file(dep, ".msg").read_text()
        pkg, _, name = dep.split("/")
        parts.append("=" * 80 + f"\nMSG: {pkg}/{name}\n" + text)
        queue.extend(_deps(text, pkg))
    return "\n".join(p.rstrip("\n") for p in parts) + "\n"


@cache
def type_hash(type_name: str) -> str:
    """RIHS01 type hash of a message type, from the type description the packages install."""
    data = json.loads(_interface_file(type_name, ".json").read_text())
    for h in data.get("type_hashes", []):
        if h["type_name"] == type_name:
            return str(h["hash_string"])
    raise BagError(f"no type hash for {type_name} in its type description")
