"""An MCAP file that is complete (summary, footer) after every flush, so a killed recorder leaves a file that
every MCAP reader opens with its index, not only streaming readers.

The `mcap` writer writes the summary once, in `finish()`. Here its output goes to a `RollingSummaryStream`
that holds everything written since the last commit; `commit(writer)` adds what `finish()` writes (DataEnd,
summary with every chunk index so far, footer) and puts chunk and summary on disk in one `pwrite` over the
previous summary, then fsyncs. The next chunk goes where that summary began (the end of the data section).
So the file on disk is always header, chunks, summary, footer; only a kill inside the one `pwrite` (a
millisecond a second) can leave a torn tail, which streaming readers skip and `app.recording.repair` fixes.
"""

from __future__ import annotations

import os
import time

from mcap.writer import Writer


class RollingSummaryStream:
    """The writable stream a `mcap.writer.Writer` writes into (write, tell, flush), backed by a file descriptor."""

    def __init__(self, fd: int) -> None:
        self.fd = fd
        self._base = 0
        """File offset where the pending bytes go: the end of the data section written so far."""
        self._pending = bytearray()
        self.commits = 0
        self.writes: list[tuple[float, int]] = []
        """(seconds, bytes) of each commit's one write: the window in which a kill leaves a torn tail."""

    def write(self, data: bytes | bytearray | memoryview) -> int:
        self._pending += data
        return len(data)

    def tell(self) -> int:
        return self._base + len(self._pending)

    def flush(self) -> None:
        """Nothing: bytes reach the file only with a summary after them (`commit`)."""

    def commit(self, writer: Writer) -> None:
        """Close the chunk in progress, write it with a summary and footer after it in one write, and fsync."""
        writer.flush()
        data_end = self.tell()
        offsets = "_Writer__summary_offsets"  # finish() appends the summary's offsets again each time
        getattr(writer, offsets).clear()
        writer.finish()
        t0 = time.perf_counter()
        written = os.pwrite(self.fd, self._pending, self._base)
        self.writes.append((time.perf_counter() - t0, len(self._pending)))
        if written != len(self._pending):
            raise OSError(f"short write to the recording: {written} of {len(self._pending)} bytes")
        os.ftruncate(self.fd, self._base + len(self._pending))
        os.fsync(self.fd)
        self._base, self._pending = data_end, bytearray()
        self.commits += 1
