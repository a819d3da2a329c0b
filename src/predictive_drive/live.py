"""The live view: a running drive served to Foxglove / Lichtblick over the Foxglove WebSocket
protocol (``foxglove-sdk``), as a second sink of what the recorder writes.

The app sees the bag's topics with their ROS types (``ros2msg`` schemas, ``cdr`` messages, the
bytes the recorder writes): the per-step topics decimated to one message per :data:`LIVE_PERIOD`
of simulated time, the tool topics as they come. ``/clock`` is the app's time. The torque
controller's ``strategy`` is a parameter the app can read and set
(``/drive/torque_controller.strategy``); the owner of the view says how a set reaches the
controller, and the view shows each change the controller accepts.
"""

from __future__ import annotations

import socket
import threading
from collections.abc import Callable
from typing import Any

from .dependencies import missing
from .errors import ConfigError
from .interface import BAG_TOPICS, LOSSES_TOPIC, RECORD_TOPICS, node_name
from .schemas import message_definition

__all__ = ["DEFAULT_PORT", "LIVE_PERIOD", "STRATEGY_PARAMETER", "LiveView", "check_port"]

#: the port ``--live`` serves on when none is given (the Foxglove WebSocket default)
DEFAULT_PORT = 8765
#: s of simulated time between two forwarded messages of a per-step topic (1 kHz)
LIVE_PERIOD = 1e-3
#: the strategy as the app names it: the node's fully qualified name, a dot, the parameter
STRATEGY_PARAMETER = f"{node_name('torque_controller')}.strategy"


def _foxglove() -> Any:
    try:
        import foxglove
    except ImportError:
        raise missing("foxglove", "--live") from None
    return foxglove


def check_port(port: int, host: str = "127.0.0.1") -> None:
    """ConfigError unless ``port`` is one the live view can serve on (checked before a run
    starts, with the package it needs)."""
    if not 1 <= port <= 65535:
        raise ConfigError(f"--live {port}: a port is a whole number from 1 to 65535")
    _foxglove()
    with socket.socket() as s:
        try:
            s.bind((host, port))
        except OSError as e:
            raise ConfigError(
                f"--live {port}: cannot serve on {host}:{port} ({e.strerror}); choose another port"
            ) from None


class LiveView:
    """A Foxglove WebSocket server on ``host:port`` fed by :meth:`offer`.

    ``set_strategy(name)``: asks the controller to switch (None: the strategy is read-only, as
    in the in-process engine); it may raise ConfigError with the reason, which the app shows.
    Call :meth:`strategy_changed` when the controller has taken a strategy."""

    def __init__(
        self,
        *,
        port: int,
        ts: float,
        strategy: str,
        strategy_names: tuple[str, ...],
        set_strategy: Callable[[str], None] | None = None,
        host: str = "127.0.0.1",
    ) -> None:
        fg = _foxglove()
        from foxglove.websocket import Capability

        self._fg = fg
        self._ts_ns = round(ts * 1e9)
        self._every = max(1, round(LIVE_PERIOD / ts))
        self._strategy = strategy
        self._names = strategy_names
        self._set = set_strategy
        self._lock = threading.Lock()
        self._ctx = fg.Context()
        self._channels = {
            key: fg.Channel(
                t.name,
                message_encoding="cdr",
                schema=fg.Schema(
                    name=t.type, encoding="ros2msg", data=message_definition(t.type).encode()
                ),
                context=self._ctx,
            )
            for key, t in BAG_TOPICS.items()
        }
        try:
            self.server = fg.start_server(
                name="predictive_drive",
                host=host,
                port=port,
                capabilities=[Capability.Time, Capability.Parameters],
                server_listener=self,
                context=self._ctx,
            )
        except RuntimeError as e:
            raise ConfigError(f"--live {port}: cannot serve on {host}:{port} ({e})") from None
        self.port = self.server.port
        self.sent = 0  #: messages handed to the server

    @property
    def url(self) -> str:
        return f"ws://127.0.0.1:{self.port}"

    def offer(self, key: str, t_ns: int, data: bytes) -> None:
        """A message the recorder writes: forwarded if it is a tool topic or, for a per-step
        topic (the plant's losses too), a step on the live period's grid."""
        per_step = key in RECORD_TOPICS or key == LOSSES_TOPIC
        if per_step and round(t_ns / self._ts_ns) % self._every:
            return
        channel = self._channels.get(key)
        if channel is None:
            return
        channel.log(data, log_time=t_ns)
        self.sent += 1
        if key == "clock":
            self.server.broadcast_time(t_ns)

    def strategy_changed(self, name: str) -> None:
        with self._lock:
            self._strategy = name
        self.server.publish_parameter_values([self._parameter()])

    def rejected(self, reason: str) -> None:
        """The controller refused a set: the app says why."""
        self._status(reason)

    def close(self) -> None:
        self.server.stop()

    def _parameter(self) -> Any:
        with self._lock:
            return self._fg.Parameter(STRATEGY_PARAMETER, value=self._strategy)

    # --- foxglove ServerListener -------------------------------------------------------------

    def on_get_parameters(
        self, client: Any, param_names: list[str], request_id: str | None = None
    ) -> list[Any]:
        if param_names and STRATEGY_PARAMETER not in param_names:
            return []
        return [self._parameter()]

    def on_set_parameters(
        self, client: Any, parameters: list[Any], request_id: str | None = None
    ) -> list[Any]:
        for p in parameters:
            if p.name != STRATEGY_PARAMETER:
                self._status(f"{p.name}: not a parameter of the drive; only {STRATEGY_PARAMETER}")
                continue
            value = p.get_value()
            if value not in self._names:
                self._status(
                    f"{STRATEGY_PARAMETER}: {value!r} is not a strategy; valid: "
                    f"{', '.join(self._names)}"
                )
            elif self._set is None:
                self._status(f"{STRATEGY_PARAMETER} is read-only in this engine")
            else:
                try:
                    self._set(str(value))
                except ConfigError as e:
                    self._status(f"{STRATEGY_PARAMETER}: {e}")
        # the value in force: it changes when the controller has taken the new one
        return [self._parameter()]

    def on_subscribe(self, client: Any, channel: Any) -> None:
        """A client subscribed: the server forwards the channel from now on (nothing to do)."""

    def on_unsubscribe(self, client: Any, channel: Any) -> None:
        """A client unsubscribed (nothing to do)."""

    def on_parameters_subscribe(self, param_names: list[str]) -> None:
        """The server sends parameter updates itself (nothing to do)."""

    def on_parameters_unsubscribe(self, param_names: list[str]) -> None:
        """Nothing to do."""

    def _status(self, message: str) -> None:
        self.server.publish_status(message, self._fg.StatusLevel.Error)
