"""`python -m app recording repair FILE`: give a recording whose tail was torn (a kill inside the one write of
a flush, a power cut) its summary and footer again, so indexed MCAP readers open it.

Every complete record is copied, in order, into a new file through the `mcap` writer (which writes the
chunk indexes and the summary), and that file replaces the old one atomically; what follows the last
complete record could not be read by anything and is reported as dropped. A file that already ends with a
footer is left as it is.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

from mcap.exceptions import McapError
from mcap.records import Channel, Chunk, DataEnd, Footer, Message, Metadata, Schema
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import MCAP0_MAGIC, CompressionType, Writer

from core.atomic_file import fsync_dir


def _records(f):
    """Each complete record in order (a chunk as its records, then None), then the error that ended the
    reading, if one did."""
    records = StreamReader(f, emit_chunks=True, validate_crcs=True, record_size_limit=1 << 31).records
    while True:
        try:
            record = next(records)
            inner = [*breakup_chunk(record, validate_crc=True), None] if isinstance(record, Chunk) else [record]
        except StopIteration:
            return
        except (McapError, ValueError, struct.error, EOFError, OSError) as err:
            yield err
            return
        yield from inner


def repair(path: Path) -> str:
    """Rewrite `path` with a summary if its tail is torn; returns one line saying what was done."""
    path = Path(path)
    with open(path, "rb") as f:
        if f.read(len(MCAP0_MAGIC)) != MCAP0_MAGIC:
            raise ValueError(f"{path} is not an MCAP file; left as it is")
    temp = path.with_name(path.name + ".repairing")
    kept = 0
    with open(path, "rb") as f, open(temp, "wb") as out:
        writer = Writer(out, compression=CompressionType.ZSTD)
        writer.start(profile="", library="perceptive-htmpc-studio (repaired)")
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        error: BaseException | None = None
        summary = False
        for record in _records(f):
            if isinstance(record, BaseException):
                error = record
            elif isinstance(record, Footer):
                out.close()
                temp.unlink()
                return f"{path.name}: ends with its summary and footer; nothing to repair"
            elif isinstance(record, DataEnd) or summary:
                summary = True  # the summary section repeats schemas and channels: nothing new to copy
            elif isinstance(record, Schema) and record.id not in schemas:
                schemas[record.id] = writer.register_schema(record.name, record.encoding, record.data)
            elif isinstance(record, Channel) and record.id not in channels:
                channels[record.id] = writer.register_channel(record.topic, record.message_encoding,
                                                              schemas.get(record.schema_id, 0), record.metadata)
            elif isinstance(record, Metadata):
                writer.add_metadata(record.name, dict(record.metadata))
            elif isinstance(record, Message):
                writer.add_message(channels[record.channel_id], record.log_time, record.data, record.publish_time,
                                   record.sequence)
                kept += 1
            elif record is None:
                writer.flush()  # keep the recording's chunk boundaries (each holds whole snapshots)
        writer.finish()
        out.flush()
        os.fsync(out.fileno())
    os.replace(temp, path)
    fsync_dir(path.parent)
    why = f", its unreadable tail dropped ({type(error).__name__})" if error is not None else ""
    return f"{path.name}: repaired: {kept} messages kept with a new summary{why}"
