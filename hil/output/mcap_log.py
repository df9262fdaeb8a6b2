"""run.mcap: the run log's channels (hil/output/channels.py) in an MCAP file, beside the CSV.

Written with the `mcap` library's writer, uncompressed, in chunks of CHUNK_SIZE_BYTES (each
chunk is written to disk when full, so a crash loses at most one chunk; the CSV files are
written a line at a time and stay the complete record). A write the disk refuses (it is full)
is cut off again and raises `RecordWriteError`: the file is left as the records before it (an
MCAP file without its index, which `mcap recover` completes and streaming readers read), and
the sink takes nothing more. The run's metadata and summary are also MCAP
Metadata records ("run_meta", "run_summary": top-level keys, values as JSON text), which
`mcap info` and Foxglove's metadata panel show.

Cost on the tick path: the JSON encoding of the tick's messages (shared with the live view)
and `Writer.add_message` for each; `hil bench log` measures it.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any, BinaryIO

from mcap.writer import CompressionType, Writer

from hil.output.channels import Channel
from hil.output.record_files import RecordFile, RecordWriteError
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
        self._file = RecordFile(self.path)  # closed in close()
        self.failed: RecordWriteError | None = None  # a write the disk refused: nothing more
        self._writer = Writer(
            self._file,  # type: ignore[arg-type]  # write, tell and flush are what it uses
            chunk_size=CHUNK_SIZE_BYTES,
            compression=CompressionType.NONE,
        )
        self._whole(lambda: self._writer.start(profile=PROFILE, library="flexjoint-hil"))
        self._ids: dict[int, int] = {}
        self._sequence: dict[int, int] = {}
        self.closed = False

    def _whole(self, call: Callable[[], object]) -> None:
        """One call of the writer, all of its writes or none (see the module docstring)."""
        if self.failed is not None:
            return
        before = self._file.size
        try:
            call()
        except RecordWriteError as exc:
            self._file.cut_to(before)
            self.failed = exc
            raise

    def add_channel(self, channel: Channel) -> None:
        def register() -> None:
            schema_id = self._writer.register_schema(
                channel.schema_name, channel.schema_encoding, channel.schema_bytes
            )
            self._ids[channel.id] = self._writer.register_channel(
                channel.topic, channel.message_encoding, schema_id, channel.metadata
            )
            self._sequence[channel.id] = 0

        self._whole(register)

    def message(self, channel_id: int, log_time_ns: int, data: bytes) -> None:
        if self.failed is not None:
            return
        sequence = self._sequence[channel_id]
        self._sequence[channel_id] = sequence + 1
        before = self._file.size
        try:
            self._writer.add_message(
                self._ids[channel_id], log_time_ns, data, log_time_ns, sequence
            )
        except RecordWriteError as exc:
            self._file.cut_to(before)
            self.failed = exc
            raise

    def metadata(self, name: str, document: dict[str, Any]) -> None:
        text = {str(k): dumps(v) for k, v in document.items()}
        self._whole(lambda: self._writer.add_metadata(name, text))

    def close(self) -> None:
        """The file finished (its index written); one that failed is left as it is."""
        if self.closed:
            return
        self.closed = True
        try:
            self._whole(self._writer.finish)
        finally:
            self._file.close()


def finish(writer: Writer, file: BinaryIO) -> None:
    """An MCAP file finished (its summary and index written) and closed, even if that fails."""
    try:
        writer.finish()
    finally:
        file.close()
