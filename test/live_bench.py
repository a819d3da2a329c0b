"""The live view's cost: `python test/live_bench.py [PAIRS]` runs `im_short --duration 3` on the
ros engine without and with `--live` (a client subscribed to every topic), alternating, and
prints steps/s of each run and what the client received (the README's figures)."""

from __future__ import annotations

import json
import socket
import subprocess
import sys
import tempfile
import threading
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from foxglove_client import FoxgloveClient  # noqa: E402
from procs import kill_if_running

CLI = [sys.executable, "-m", "predictive_drive.cli", "run", "im_short", "--duration", "3", "--json"]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def one(live: bool, out: Path) -> tuple[float, dict[str, int]]:
    port = free_port()
    p = subprocess.Popen(
        CLI + ["--out", str(out)] + (["--live", str(port)] if live else []),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    got: dict[str, int] = {}

    def watch() -> None:
        c = FoxgloveClient(f"ws://127.0.0.1:{port}", timeout=30)
        g = c.pump(10, until=lambda g: len(g.channels) >= 8)
        c.subscribe([ch["topic"] for ch in g.channels.values()])
        c.pump(120)
        got.update({t: len(m) for t, m in g.messages.items()}, time=len(g.times))

    watcher = threading.Thread(target=watch, daemon=True)
    if live:
        watcher.start()
    try:
        stdout, _ = p.communicate(timeout=300)
    finally:
        kill_if_running(p)
    if live:
        watcher.join(timeout=30)
    d = json.loads(stdout)
    return d["steps"] / d["wall_s"], got


def main() -> None:
    pairs = int(sys.argv[1]) if len(sys.argv) > 1 else 3
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(pairs):
            for live in (False, True):
                rate, got = one(live, Path(tmp) / f"b{i}{int(live)}")
                print(f"live={live!s:<5} {rate:7.0f} steps/s  {got if live else ''}", flush=True)


if __name__ == "__main__":
    main()
