"""Live view: the record channels on a Foxglove WebSocket server (foxglove-sdk).

Imported only when ``gyrotherm record --foxglove-port`` is given (the optional
``foxglove`` extra); the daemon never imports it. The server binds 127.0.0.1 by
default (``--foxglove-host`` to change it: it has no authentication) and speaks the
``foxglove.sdk.v1`` subprotocol, the only one foxglove-sdk 0.30's server accepts: the
new name of ``foxglove.websocket.v1``, with the same messages. A client receives
``serverInfo`` and ``advertise`` (one channel per topic, with its schema), subscribes,
and then gets binary message-data frames (opcode 1, subscription id, log time in ns,
payload). Current Foxglove offers ``foxglove.sdk.v1``; a client offering only
``foxglove.websocket.v1`` (older Lichtblick releases) gets HTTP 400, as from
foxglove_bridge ≥ 3 (the SDK has no option to accept the old name). The channels and
payloads are those of the MCAP file (:mod:`gyrotherm.client._channels`: all ROS 2
CDR).

The server has its own :class:`foxglove.Context`, so nothing else logged through
the SDK's global context in the same process reaches it.
"""

from __future__ import annotations

import foxglove

from gyrotherm.client._channels import ChannelSpec


class FoxgloveSink:
    """A Foxglove WebSocket server on ``host:port`` (port 0: a free one, see :attr:`port`)."""

    def __init__(self, *, host: str = "127.0.0.1", port: int = 8765,
                 name: str = "gyrotherm") -> None:  # fmt: skip
        self._context = foxglove.Context()
        self._server = foxglove.start_server(name=name, host=host, port=port,
                                             context=self._context)  # fmt: skip
        self.port: int = self._server.port
        self._channels: list[foxglove.Channel] = []

    def add_channel(self, spec: ChannelSpec) -> foxglove.Channel:
        schema = foxglove.Schema(name=spec.schema_name, encoding=spec.schema_encoding,
                                 data=spec.schema_text.encode())  # fmt: skip
        ch = foxglove.Channel(spec.topic, schema=schema, message_encoding=spec.message_encoding,
                              context=self._context)  # fmt: skip
        self._channels.append(ch)
        return ch

    def write(self, channel: foxglove.Channel, log_time_ns: int, data: bytes) -> None:
        channel.log(data, log_time=log_time_ns)

    def close(self) -> None:
        for ch in self._channels:
            ch.close()
        self._server.stop()
