"""Run a node's ``main`` with its SIGINT/SIGTERM handlers re-entered at every line they execute.

``python reentrant_signals.py MODULE ARGS...`` runs ``predictive_drive.ros.MODULE``'s main. Every
SIGINT / SIGTERM handler the node installs is wrapped: while the first signal is being handled,
each line the handler executes (and every line of whatever it calls) sends the process another
signal, which Python delivers at its next check, nested inside the first handler. A handler that
takes a lock (``threading.Event.set`` does) waits there forever for the lock its outer call holds;
one that only sets a flag returns. Prints ``handlers installed`` when the node's are in.
"""

from __future__ import annotations

import importlib
import os
import signal
import sys
import threading

_real_signal = signal.signal
_handling = [False]


def _tracer(frame, event, arg):  # noqa: ANN001, ANN202 - sys.settrace's signature
    if event == "line" and threading.current_thread() is threading.main_thread():
        os.kill(os.getpid(), signal.SIGTERM)
    return _tracer


def _reentered(handler):  # noqa: ANN001, ANN202
    def handle(signum, frame):  # noqa: ANN001, ANN202
        if _handling[0]:  # a nested delivery: the handler as it is
            return handler(signum, frame)
        _handling[0] = True
        sys.settrace(_tracer)
        try:
            return handler(signum, frame)
        finally:
            sys.settrace(None)

    return handle


def _signal(sig, handler):  # noqa: ANN001, ANN202
    if sig in (signal.SIGINT, signal.SIGTERM) and callable(handler):
        previous = _real_signal(sig, _reentered(handler))
        print("handlers installed", flush=True)
        return previous
    return _real_signal(sig, handler)


if __name__ == "__main__":
    signal.signal = _signal
    module = importlib.import_module(f"predictive_drive.ros.{sys.argv[1]}")
    sys.exit(module.main(sys.argv[1:]))
