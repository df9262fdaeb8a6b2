"""`hil run --live`: the run log's channels served on Foxglove's WebSocket protocol while the run
goes (the Foxglove SDK's server; open Foxglove, "Open connection", ws://HOST:PORT).

The same encoded messages as run.mcap (hil/output/channels.py), handed to the SDK's channels.
Publishing never blocks the loop: `Channel.log` passes the bytes to the SDK's own threads
(Rust), which keep a bounded backlog per client and drop a slow client's oldest messages
(`message_backlog_size`); with no client subscribed, nothing is sent at all.

The server listens on the loopback address unless the user names another host: a live
robot's signals are nobody else's business. The SDK is imported only here, when asked for.
"""

from __future__ import annotations

from typing import Any

from hil.output.channels import Channel

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8765
BACKLOG_MESSAGES = 1024  # per client; the oldest data message is dropped beyond it


class LivePublisher:
    """A MessageSink serving the channels over WebSocket (one server for a whole session:
    each run re-advertises its channels)."""

    def __init__(self, host: str = DEFAULT_HOST, port: int = DEFAULT_PORT, name: str = "hil"):
        import foxglove

        self._foxglove = foxglove
        self.context = foxglove.Context()
        self.server = foxglove.start_server(
            name=name,
            host=host,
            port=port,
            context=self.context,
            message_backlog_size=BACKLOG_MESSAGES,
        )
        self.host = host
        self._channels: dict[int, Any] = {}

    @property
    def port(self) -> int:
        return int(self.server.port)

    @property
    def url(self) -> str:
        return f"ws://{self.host}:{self.port}"

    def add_channel(self, channel: Channel) -> None:
        old = self._channels.pop(channel.id, None)
        if old is not None:  # a new run: its channels replace the last run's
            old.close()
        schema = self._foxglove.Schema(
            name=channel.schema_name, encoding=channel.schema_encoding, data=channel.schema_bytes
        )
        self._channels[channel.id] = self._foxglove.Channel(
            channel.topic,
            schema=schema,
            message_encoding=channel.message_encoding,
            context=self.context,
            metadata=channel.metadata,
        )

    def message(self, channel_id: int, log_time_ns: int, data: bytes) -> None:
        self._channels[channel_id].log(data, log_time=log_time_ns)

    def close(self) -> None:
        for channel in self._channels.values():
            channel.close()
        self._channels.clear()
        self.server.stop()
