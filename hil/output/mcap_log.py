"""run.mcap: the run log's channels (hil/output/channels.py) in an MCAP file, beside the CSV.

Written with the `mcap` library's writer, uncompressed, in chunks of CHUNK_SIZE_BYTES (each
chunk is written to disk when full, so a crash loses at most one chunk; the CSV files are
line-buffered and stay the complete record). The run's metadata and summary are also MCAP
Metadata records ("run_meta", "run_summary": top-level keys, values as JSON text), which
`mcap info` and Foxglove's metadata panel show.

Cost on the tick path: the JSON encoding of the tick's messages (shared with the live view)
and `Writer.add_message` for each; `hil bench log` measures it.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, BinaryIO

from mcap.writer import CompressionType, Writer

from hil.output.channels import Channel
from hil.output.strict_json import dumps

MCAP_NAME = "run.mcap"
# Closing a chunk (its message indexes are built in Python) costs time in proportion to its size,
# on the tick that fills it: measured with the testbed's three messages per tick, 256 KB chunks
# took 1.5 ms (p99.9 of ticks) to 2.4 ms (max), 32 KB chunks 0.28 ms and 1.1 ms.
CHUNK_SIZE_BYTES = 32 * 1024
PROFILE = ""  # JSON messages follow no ROS profile


class McapSink:
    """A MessageSink writing one MCAP file."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._file = open(self.path, "wb")  # noqa: SIM115 - closed in close()
        self._writer = Writer(
            self._file, chunk_size=CHUNK_SIZE_BYTES, compression=CompressionType.NONE
        )
        self._writer.start(profile=PROFILE, library="flexjoint-hil")
        self._ids: dict[int, int] = {}
        self._sequence: dict[int, int] = {}
        self.closed = False

    def add_channel(self, channel: Channel) -> None:
        schema_id = self._writer.register_schema(
            channel.schema_name, channel.schema_encoding, channel.schema_bytes
        )
        self._ids[channel.id] = self._writer.register_channel(
            channel.topic, channel.message_encoding, schema_id, channel.metadata
        )
        self._sequence[channel.id] = 0

    def message(self, channel_id: int, log_time_ns: int, data: bytes) -> None:
        sequence = self._sequence[channel_id]
        self._sequence[channel_id] = sequence + 1
        self._writer.add_message(self._ids[channel_id], log_time_ns, data, log_time_ns, sequence)

    def metadata(self, name: str, document: dict[str, Any]) -> None:
        self._writer.add_metadata(name, {str(k): dumps(v) for k, v in document.items()})

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        finish(self._writer, self._file)


def finish(writer: Writer, file: BinaryIO) -> None:
    """An MCAP file finished (its summary and index written) and closed, even if that fails."""
    try:
        writer.finish()
    finally:
        file.close()
