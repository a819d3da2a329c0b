"""A small client of the Foxglove WebSocket protocol (subprotocol ``foxglove.sdk.v1``), as the
Foxglove and Lichtblick apps speak it: channels advertised as JSON, messages and time as binary
frames, parameters as JSON requests."""

from __future__ import annotations

import json
import struct
import time
from dataclasses import dataclass, field

import websocket  # websocket-client

MESSAGE_DATA, TIME = 1, 2


@dataclass
class Received:
    channels: dict[int, dict] = field(default_factory=dict)  #: id → advertised channel
    messages: dict[str, list[tuple[int, bytes]]] = field(
        default_factory=dict
    )  #: topic → (ns, data)
    times: list[int] = field(default_factory=list)
    parameters: list[dict] = field(default_factory=list)  #: parameterValues replies and updates
    statuses: list[dict] = field(default_factory=list)
    server_info: dict = field(default_factory=dict)


class FoxgloveClient:
    def __init__(self, url: str, timeout: float = 10.0) -> None:
        deadline = time.monotonic() + timeout
        while True:
            try:
                self.ws = websocket.create_connection(
                    url, subprotocols=["foxglove.sdk.v1"], timeout=timeout
                )
                break
            except OSError:
                if time.monotonic() > deadline:
                    raise
                time.sleep(0.1)
        self.got = Received()
        self._subs: dict[int, str] = {}  #: subscription id → topic

    def pump(self, seconds: float, until=None) -> Received:
        """Read frames until ``until(received)`` is true (failing if it is not within
        ``seconds``), or for ``seconds``."""
        end = time.monotonic() + seconds
        self.ws.settimeout(0.2)
        while time.monotonic() < end and not (until and until(self.got)):
            try:
                op, data = self.ws.recv_data()
            except websocket.WebSocketTimeoutException:
                continue
            except websocket.WebSocketConnectionClosedException:
                break
            if op == websocket.ABNF.OPCODE_TEXT:
                self._text(json.loads(data))
            elif op == websocket.ABNF.OPCODE_BINARY:
                self._binary(data)
        assert until is None or until(self.got), f"not received within {seconds} s"
        return self.got

    def _text(self, msg: dict) -> None:
        op = msg.get("op")
        if op == "serverInfo":
            self.got.server_info = msg
        elif op == "advertise":
            for ch in msg["channels"]:
                self.got.channels[ch["id"]] = ch
        elif op == "parameterValues":
            self.got.parameters.append(msg)
        elif op == "status":
            self.got.statuses.append(msg)

    def _binary(self, data: bytes) -> None:
        if data[0] == MESSAGE_DATA:
            sub, ns = struct.unpack_from("<IQ", data, 1)
            self.got.messages.setdefault(self._subs[sub], []).append((ns, bytes(data[13:])))
        elif data[0] == TIME:
            self.got.times.append(struct.unpack_from("<Q", data, 1)[0])

    def subscribe(self, topics: list[str]) -> None:
        subs = []
        for cid, ch in self.got.channels.items():
            if ch["topic"] in topics:
                sid = len(self._subs) + 1
                self._subs[sid] = ch["topic"]
                subs.append({"id": sid, "channelId": cid})
        self.ws.send(json.dumps({"op": "subscribe", "subscriptions": subs}))

    def get_parameters(self, names: list[str], request_id: str) -> None:
        self.ws.send(json.dumps({"op": "getParameters", "parameterNames": names, "id": request_id}))

    def set_parameters(self, params: dict[str, object], request_id: str) -> None:
        self.ws.send(
            json.dumps(
                {
                    "op": "setParameters",
                    "parameters": [{"name": k, "value": v} for k, v in params.items()],
                    "id": request_id,
                }
            )
        )

    def subscribe_parameters(self, names: list[str]) -> None:
        self.ws.send(json.dumps({"op": "subscribeParameterUpdates", "parameterNames": names}))

    def close(self) -> None:
        self.ws.close()
