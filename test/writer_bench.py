"""MCAP writers on a drive's messages: `python test/writer_bench.py [REPEATS]` writes the state,
reference and command of 20,000 im_paper steps (60,000 messages) four ways — the mcap library's
writer, foxglove-sdk's writer (Rust, one call per message), our ChunkWriter message by message,
and our ChunkWriter in blocks of 512 steps as the in-process recorder writes them — each with
768 KiB chunks, compressed inline (zstd level 1; the mcap library's at its fixed level 3), and
prints the wall time of each (docs/performance.md's figures). It also says whether the files
hold the same messages, as the mcap library reads them."""

from __future__ import annotations

import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

import foxglove
import numpy as np
from foxglove.mcap import MCAPCompression, MCAPWriteOptions
from mcap.reader import make_reader

from predictive_drive.codec import CODECS
from predictive_drive.config import load_scenario
from predictive_drive.core.runner import run_inprocess
from predictive_drive.mcapio import ChunkWriter

STEPS = 20000
TOPICS = ("/drive/state", "/drive/torque_reference", "/drive/command")
CHUNK = 768 * 1024
SCHEMA = ("std_msgs/msg/Float64MultiArray", "ros2msg", b"float64[] data")


def messages() -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Each topic's rows and log times (a command 1 ns after its state: a different time)."""
    tr = run_inprocess(load_scenario("im_paper", strategy="db_mptc"), steps=STEPS)
    rows = [tr.state[:STEPS], tr.reference[:STEPS], tr.command[:STEPS]]
    t = np.rint(tr.state[:STEPS, 1] * 1e9).astype(np.int64)
    return rows, [t, t, t + 1]


def one_by_one(rows: list[np.ndarray], times: list[np.ndarray]) -> list[tuple[int, int, bytes]]:
    codecs = [CODECS["state"], CODECS["reference"], CODECS["command"]]
    return [
        (j, int(times[j][k]), codecs[j].encode(tuple(rows[j][k])))
        for k in range(STEPS)
        for j in range(3)
    ]


def with_sdk(path: Path, msgs: list[tuple[int, int, bytes]]) -> float:
    ctx = foxglove.Context()
    options = MCAPWriteOptions(
        compression=MCAPCompression.Zstd,
        chunk_size=CHUNK,
        profile="ros2",
        compression_level=1,
        compression_threads=0,  # inline, as the others here (default: a thread per CPU)
    )
    writer = foxglove.open_mcap(path, context=ctx, writer_options=options, allow_overwrite=True)
    schema = foxglove.Schema(name=SCHEMA[0], encoding=SCHEMA[1], data=SCHEMA[2])
    channels = [
        foxglove.Channel(t, schema=schema, message_encoding="cdr", context=ctx) for t in TOPICS
    ]
    t0 = time.perf_counter()
    for j, t, data in msgs:
        channels[j].log(data, log_time=t)
    writer.close()
    return time.perf_counter() - t0


def with_library(path: Path, msgs: list[tuple[int, int, bytes]]) -> float:
    from mcap.writer import CompressionType, Writer

    t0 = time.perf_counter()
    with open(path, "wb") as f:
        w = Writer(f, chunk_size=CHUNK, compression=CompressionType.ZSTD)
        w.start(profile="ros2", library="writer_bench")
        schema = w.register_schema(*SCHEMA)
        ids = [w.register_channel(t, "cdr", schema) for t in TOPICS]
        seq = [0, 0, 0]
        for j, t, data in msgs:
            seq[j] += 1
            w.add_message(ids[j], t, data, t, seq[j])
        w.finish()
    return time.perf_counter() - t0


def ours(path: Path, write: Callable[[ChunkWriter, list[int]], None]) -> float:
    t0 = time.perf_counter()
    with open(path, "wb") as f:
        w = ChunkWriter(f, chunk_size=CHUNK, level=1)
        w.start(profile="ros2", library="writer_bench")
        schema = w.register_schema(*SCHEMA)
        ids = [w.register_channel(t, "cdr", schema, {}) for t in TOPICS]
        write(w, ids)
        w.finish()
        w.close()
    return time.perf_counter() - t0


def read(path: Path) -> list[tuple[str, int, int, bytes]]:
    with open(path, "rb") as f:
        return [
            (ch.topic, m.log_time, m.sequence, bytes(m.data))
            for _, ch, m in make_reader(f).iter_messages(log_time_order=True)
        ]


def main(repeats: int) -> None:
    rows, times = messages()
    msgs = one_by_one(rows, times)
    codecs = [CODECS["state"], CODECS["reference"], CODECS["command"]]

    def each(w: ChunkWriter, ids: list[int]) -> None:
        for j, t, data in msgs:
            w.add(ids[j], t, data)

    def blocks(w: ChunkWriter, ids: list[int]) -> None:
        group = w.group([(ids[j], codecs[j].prefix, 8 * rows[j].shape[1]) for j in range(3)])
        for s in range(0, STEPS, 512):
            group.add_steps(
                [t[s : s + 512] for t in times],
                [np.ascontiguousarray(r[s : s + 512]).tobytes() for r in rows],
            )

    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        for _ in range(repeats):  # interleaved: the machine's drift touches each alike
            lib = with_library(d / "lib.mcap", msgs)
            sdk = with_sdk(d / "sdk.mcap", msgs)
            one = ours(d / "each.mcap", each)
            block = ours(d / "blocks.mcap", blocks)
            print(
                f"{3 * STEPS:,} messages: mcap {lib * 1e3:.0f} ms ({lib / STEPS * 1e6:.2f} us/step), "
                f"foxglove-sdk {sdk * 1e3:.0f} ms "
                f"({sdk / STEPS * 1e6:.2f} us/step), ChunkWriter.add {one * 1e3:.0f} ms "
                f"({one / STEPS * 1e6:.2f} us/step), blocks {block * 1e3:.0f} ms "
                f"({block / STEPS * 1e6:.2f} us/step)",
                flush=True,
            )
        files = [read(d / f"{n}.mcap") for n in ("lib", "sdk", "each", "blocks")]
        same = all(f == files[0] for f in files)
        print(f"the four files hold the same messages (topic, time, sequence, bytes): {same}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 3)
