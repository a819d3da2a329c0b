"""Ctrl-C (and SIGTERM) in the command line's own process: a KeyboardInterrupt wherever the work
can stop, held back while a recording is being changed.

A recorder takes a batch of steps into several structures at once (the chunk being filled, its
message index, each channel's count); an interrupt between two of them would close the bag with an
index that no longer matches its chunk. The command line's handler (:func:`interrupt`) therefore
raises at once outside a :func:`held` block and at the block's end inside one. Every spin of an
rclpy executor in that process (the launcher's /clock watcher, the player, the stepper:
``ros.transport.spin_once``) is one too: raised inside a callback, a KeyboardInterrupt is logged
by rclpy's executor as a FATAL callback exception with its traceback, and cuts the callback.
Processes that handle signals otherwise (the ROS nodes stop at their spin loop's next turn) are
not affected.
"""

from __future__ import annotations

import contextlib
import signal
from collections.abc import Iterator

__all__ = ["counting", "held", "interrupt"]

_depth = 0  #: held blocks the process is in
_pending = False  #: an interrupt came inside one


def interrupt(signum: int, frame: object) -> None:
    """The command line's SIGINT / SIGTERM handler."""
    global _pending
    if _depth:
        _pending = True
        return
    raise KeyboardInterrupt


@contextlib.contextmanager
def held() -> Iterator[None]:
    """A block an interrupt does not cut: one that came meanwhile is raised when it ends."""
    global _depth, _pending
    _depth += 1
    try:
        yield
    finally:
        _depth -= 1
        if not _depth and _pending:
            _pending = False
            raise KeyboardInterrupt


@contextlib.contextmanager
def counting() -> Iterator[list[int]]:
    """While a stop is under way, a Ctrl-C or SIGTERM is counted (``[n]``), not raised: a press
    at any moment of the stop is a press to act on (end what still runs outright), never an
    escape that loses the stop's summary. The handler only adds one: a signal inside it runs it
    again, harmlessly. Only where handlers can be set (the main thread); elsewhere nothing is
    counted."""
    presses = [0]

    def press(_signum: int, _frame: object) -> None:
        presses[0] += 1

    try:
        previous = {sig: signal.signal(sig, press) for sig in (signal.SIGINT, signal.SIGTERM)}
    except ValueError:  # not the main thread
        yield presses
        return
    try:
        yield presses
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
