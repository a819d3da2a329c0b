"""The package's layering (docs/architecture.md#the-layers): arrows point down, the core is ROS-free
and numpy-only, and only ``ros/`` touches rclpy. Module lists come from ``pkgutil``, not a hand
list."""

from __future__ import annotations

import ast
import importlib.util
import pkgutil
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

import predictive_drive

pytestmark = pytest.mark.core

PKG = "predictive_drive"
MODULES = sorted(m.name for m in pkgutil.walk_packages(predictive_drive.__path__, f"{PKG}."))
#: modules that may import rclpy when imported: the nodes, launcher and tools of ros/ (its package
#: __init__ and the launcher↔node contract in ros.placement stay ROS-free)
ROS_MODULES = [m for m in MODULES if m.startswith(f"{PKG}.ros.") and m != f"{PKG}.ros.placement"]


def _source(module: str) -> tuple[Path, bool]:
    spec = importlib.util.find_spec(module)
    assert spec is not None and spec.origin is not None, module
    path = Path(spec.origin)
    return path, path.name == "__init__.py"


def import_arrows() -> dict[str, set[str]]:
    """module → the package's modules it imports (as written, lazy imports inside functions too)."""
    known = set(MODULES) | {PKG}
    arrows: dict[str, set[str]] = {}
    for m in MODULES:
        path, is_pkg = _source(m)
        base = m.split(".") if is_pkg else m.split(".")[:-1]
        out: set[str] = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                parts = base[: len(base) - node.level + 1] if node.level else []
                target = ".".join(parts + ([node.module] if node.module else []))
                names = [target] + [f"{target}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            for name in names:
                while name and name not in known:
                    name = name.rpartition(".")[0]
                # a module importing its own package's __init__ (re-exports) is not an arrow
                if name and name != m and name.startswith(PKG) and not m.startswith(name + "."):
                    out.add(name)
        arrows[m] = out
    return arrows


ARROWS = import_arrows()


def test_module_list_is_found():
    assert f"{PKG}.core.control.mptc_im" in MODULES and f"{PKG}.ros.plant_node" in MODULES


def test_no_import_cycle():
    state: dict[str, int] = {}
    cycles: list[list[str]] = []

    def visit(m: str, path: list[str]) -> None:
        state[m] = 1
        for d in sorted(ARROWS.get(m, ())):
            if state.get(d) == 1:
                cycles.append(path[path.index(d) :] + [d])
            elif d not in state:
                visit(d, [*path, d])
        state[m] = 2

    for m in MODULES:
        if m not in state:
            visit(m, [m])
    assert not cycles


def forbidden(source: str, allowed: Callable[[str], bool]) -> set[tuple[str, str]]:
    """Arrows from modules under ``source`` to modules ``allowed`` refuses."""
    return {
        (m, d) for m, ds in ARROWS.items() if m.startswith(source) for d in ds if not allowed(d)
    }


def test_core_imports_only_core_and_errors():
    core = f"{PKG}.core"
    assert not forbidden(core, lambda d: d.startswith(core) or d == f"{PKG}.errors")


def test_ros_never_imports_api():
    assert not forbidden(f"{PKG}.ros", lambda d: not d.startswith(f"{PKG}.api"))


def test_modules_outside_ros_do_not_import_rclpy():
    """Imported one after another in a fresh interpreter; the first that pulls rclpy in is named."""
    # a __main__ module runs its command when imported: it is checked through its package
    ros_free = [m for m in MODULES if m not in ROS_MODULES and not m.endswith(".__main__")]
    code = (
        "import importlib, sys\n"
        f"for m in {ros_free!r}:\n"
        "    importlib.import_module(m)\n"
        "    assert 'rclpy' not in sys.modules, m + ' imports rclpy'\n"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0, r.stderr
    assert f"{PKG}.api.run" in ros_free and f"{PKG}.cli" in ros_free


def test_core_imports_only_numpy_and_stdlib():
    code = (
        "import sys, importlib, pkgutil\n"
        "before = set(sys.modules)\n"
        "import predictive_drive.core as c\n"
        "for m in pkgutil.walk_packages(c.__path__, 'predictive_drive.core.'):\n"
        "    importlib.import_module(m.name)\n"
        "new = set(sys.modules) - before\n"
        "third = {n.split('.')[0] for n in new} - set(sys.stdlib_module_names)\n"
        "assert third <= {'numpy', 'predictive_drive'}, third\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, timeout=60)
