"""Reading any MCAP file record by record, front to back, without trusting its length fields.

The `mcap` stream reader believes what a file says: a header string that claims 4 GiB makes Python
allocate 4 GiB before the read comes back short, and a chunk's claimed uncompressed size is handed
to zstd as the size of its output. Here the file is read through a wrapper whose `read(n)` never
asks for more than the bytes left, so no length field can make an allocation larger than the file;
a chunk may claim at most what its compression can produce from the bytes it holds (zstd 32 768
times, lz4 256 times: their largest possible ratios) and is decompressed in steps of 1 MiB against
that claim; chunk and attachment CRCs are checked.

Strict by default: damage raises `IngestError` naming the file and the byte offset of the record.
With `recover`, iteration stops at the damage and `recovered` says what and where, so a file cut off
by a killed logger yields every complete chunk before the cut.
"""

from __future__ import annotations

import os
import struct
from pathlib import Path

import lz4.frame
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.exceptions import McapError, RecordLengthLimitExceeded
from mcap.records import Attachment, Chunk, Footer, Header
from mcap.stream_reader import StreamReader, breakup_chunk

from feedlog.errors import IngestError
from feedlog.ingest.bounded import BoundedReader

# what the mcap library, zstd, lz4 and struct raise on damaged bytes
DAMAGE = (McapError, struct.error, ValueError, EOFError, UnicodeDecodeError, RuntimeError, KeyError, OverflowError,
          zstandard.ZstdError)
MAX_RATIO = {"": 1, "zstd": 32768, "lz4": 256}  # most output one compressed byte can give
FRAME_SLACK = 64  # frame headers and trailers on top of the ratio
STEP = 1 << 20


class Damaged(Exception):
    """Bytes that are not what the format says (raised inside this module, reported as IngestError)."""


def inflate(chunk: Chunk) -> bytes:
    """A chunk's records, uncompressed and checked against its claimed size (and its CRC later)."""
    kind, data, size = chunk.compression, chunk.data, chunk.uncompressed_size
    if kind not in MAX_RATIO:
        raise Damaged(f"chunk compression {kind!r} is not one of none, zstd, lz4")
    if size > len(data) * MAX_RATIO[kind] + FRAME_SLACK:
        raise Damaged(f"chunk claims {size} bytes uncompressed from {len(data)} {kind or 'uncompressed'} bytes, "
                      "more than that compression can produce")
    if kind == "":
        out = data
    elif kind == "lz4":
        out = lz4.frame.LZ4FrameDecompressor().decompress(data, max_length=size + 1)
    else:
        pieces, total = [], 0
        with zstandard.ZstdDecompressor().stream_reader(data, read_across_frames=True) as reader:
            while total <= size:
                piece = reader.read(min(STEP, size + 1 - total))
                if not piece:
                    break
                pieces.append(piece)
                total += len(piece)
        out = b"".join(pieces)
    if len(out) != size:
        raise Damaged(f"chunk holds {'more than' if len(out) > size else len(out)} uncompressed bytes, not the "
                      f"{size} it claims")
    return out


def chunk_records(chunk: Chunk) -> list:
    """The records inside a chunk; raises on a bad size, bad compressed data or a CRC mismatch."""
    plain = Chunk(message_start_time=chunk.message_start_time, message_end_time=chunk.message_end_time,
                  uncompressed_size=chunk.uncompressed_size, uncompressed_crc=chunk.uncompressed_crc,
                  compression="", data=inflate(chunk))
    return breakup_chunk(plain, validate_crc=True)


def _attachment_crc_ok(record: Attachment, f, start: int, end: int) -> bool:
    """The attachment's stored CRC (its last 4 bytes) matches its content, or is 0 (not computed)."""
    builder = RecordBuilder()
    record.write(builder)
    expected = builder.end()
    if len(expected) != end - start:  # padded or extended record: its CRC is not where we would look
        return True
    stored = os.pread(f.fileno(), 4, end - 4)
    return stored in (b"\0\0\0\0", expected[-4:])


def read_header(path: Path) -> Header:
    """The file's Header record (the first one), read with the same bounds as a full scan."""
    size = path.stat().st_size
    with BoundedReader(path) as f:
        try:
            record = next(StreamReader(f, record_size_limit=size).records)
        except (StopIteration, *DAMAGE) as exc:
            why = "empty file" if size == 0 else describe(exc, 0, size)
            raise IngestError(f"not an MCAP file ({why})", file=str(path), position="byte 0") from None
    if not isinstance(record, Header):
        raise IngestError("not an MCAP file (no header record)", file=str(path), position="byte 8")
    return record


class RecordScan:
    """Every record of an MCAP file front to back, chunks opened, each with its chunk's byte offset."""

    def __init__(self, path: str | os.PathLike, *, recover: bool = False) -> None:
        self.path = Path(path)
        self.source = str(path)
        self.recover = recover
        self.recovered: str | None = None
        self.end = 0  # byte offset after the last record read
        if not self.path.is_file():
            raise IngestError("no such file", file=self.source)

    def _damaged(self, problem: str, position: int) -> None:
        if position == 0:
            raise IngestError(f"not an MCAP file ({problem})", file=self.source, position="byte 0")
        if not self.recover:
            raise IngestError(f"{problem}; read it with --recover to keep the complete records before this point",
                              file=self.source, position=f"byte {position}")
        self.recovered = f"{problem} at byte {position}"

    def __iter__(self):
        size = self.path.stat().st_size
        with BoundedReader(self.path) as f:
            # chunk CRCs are checked in chunk_records; the whole-stream CRC would only hash everything twice
            records = StreamReader(f, emit_chunks=True, validate_crcs=False, record_size_limit=size).records
            position = 0
            while True:
                try:
                    record = next(records)
                except StopIteration:
                    return
                except DAMAGE as exc:
                    self._damaged(describe(exc, position, size), position)
                    return
                end = f.tell()
                if isinstance(record, Chunk):
                    try:
                        inner = chunk_records(record)
                    except (Damaged, *DAMAGE) as exc:
                        self._damaged(f"corrupt chunk ({exc})", position)
                        return
                    for item in inner:
                        yield position, item
                elif isinstance(record, Attachment) and not _attachment_crc_ok(record, f, position, end):
                    self._damaged(f"attachment {record.name!r} does not match its CRC", position)
                    return
                else:
                    yield position, record
                self.end = position = end
                if isinstance(record, Footer):
                    return


def describe(exc: BaseException, position: int, size: int) -> str:
    if isinstance(exc, RecordLengthLimitExceeded):
        return f"a record at byte {position} claims more bytes than the file holds ({size}): cut short or corrupt"
    if position >= size:
        return f"file is truncated (it ends at byte {size}, where another record should follow)"
    if type(exc).__name__ == "EndOfFile" or isinstance(exc, struct.error):
        return f"file is truncated (it ends at byte {size}, inside the record at byte {position})"
    return f"corrupt record ({type(exc).__name__}: {exc})"
