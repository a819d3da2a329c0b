"""Foxglove's TypeScript MCAP reader (``@mcap/core``, which Lichtblick uses too) as the tests run
it: installed once per session with npm from ``test/ts_reader``'s lock file, run with Node.js
on a file (``read.js``); what it reads is held to what the ``mcap`` library reads."""

from __future__ import annotations

import hashlib
import json
import shutil
import subprocess
from pathlib import Path
from typing import Any

from mcap.reader import make_reader

SOURCE = Path(__file__).parent / "ts_reader"


def install(into: Path) -> Path | str:
    """The reader installed in ``into`` (package.json, lock file, read.js, node_modules), or why
    it could not be: no Node.js or npm here, or npm could not install it."""
    node, npm = shutil.which("node"), shutil.which("npm")
    if not node or not npm:
        return "no Node.js / npm on PATH"
    for name in ("package.json", "package-lock.json", "read.js"):
        shutil.copy(SOURCE / name, into / name)
    r = subprocess.run(
        [npm, "ci", "--no-audit", "--no-fund", "--loglevel=error"],
        cwd=into,
        capture_output=True,
        text=True,
        timeout=300,
    )
    if r.returncode != 0:
        return f"npm ci could not install @mcap/core: {r.stderr.strip()[-500:]}"
    return into


def read(folder: Path, mcap: Path) -> dict[str, Any]:
    """What the TypeScript reader reads of ``mcap`` (see read.js)."""
    r = subprocess.run(
        ["node", str(folder / "read.js"), str(mcap)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stderr
    return json.loads(r.stdout)


def library(mcap: Path) -> dict[str, Any]:
    """The same of ``mcap`` as the mcap library reads it: messages per topic, a SHA-256 of each
    topic's payloads in log-time order, the schemas' names."""
    counts: dict[str, int] = {}
    hashes: dict[str, Any] = {}
    with open(mcap, "rb") as f:
        reader = make_reader(f)
        schemas = sorted(s.name for s in reader.get_summary().schemas.values())
        for _, channel, message in reader.iter_messages(log_time_order=True):
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            hashes.setdefault(channel.topic, hashlib.sha256()).update(message.data)
    return {
        "counts": counts,
        "digests": {t: h.hexdigest() for t, h in hashes.items()},
        "schemas": schemas,
    }


def assert_reads_like_the_library(folder: Path, mcap: Path) -> None:
    """Every message, in log-time order, one schema per type, each channel's sequence numbers
    1, 2, 3, ... in the file's order; the same messages as the mcap library's."""
    got = read(folder, mcap)
    want = library(mcap)
    assert got["backwards"] == 0 and got["badSequences"] == 0 and got["complete"], got
    assert got["streamedTotal"] == sum(want["counts"].values())
    assert len(set(got["schemas"])) == len(got["schemas"])
    assert {k: got[k] for k in want} == want
