"""MCAP surgery for the fuzz corpus: split a file into its top-level records and damage them on purpose.

Files are built and taken apart with the `mcap` library's own record classes (records.py), so a
mutation is exact: a length field set to 2**40, a chunk whose messages were edited and whose CRC was
computed again (damage the CRC cannot see), two records swapped, a compressed chunk with a flipped bit.
The seed recordings are written here with the plain `mcap` Writer and fixed times, so the same seed
always gives the same bytes whatever feedlog's own writer does.
"""

from __future__ import annotations

import struct
import zlib
from dataclasses import dataclass
from io import BytesIO

import numpy as np
import pyarrow as pa
import zstandard
from mcap.data_stream import RecordBuilder
from mcap.opcode import Opcode
from mcap.records import Chunk, Message, Metadata
from mcap.stream_reader import StreamReader, breakup_chunk
from mcap.writer import CompressionType, IndexType, Writer

MAGIC = b"\x89MCAP0\r\n"


@dataclass
class Record:
    offset: int       # of the opcode byte
    opcode: int
    body: bytes       # the record's content after opcode and length

    @property
    def end(self) -> int:
        return self.offset + 9 + len(self.body)


def records(data: bytes) -> list[Record]:
    """The top-level records of a well-formed MCAP file (after the leading magic)."""
    out, k = [], len(MAGIC)
    while k + 9 <= len(data) - len(MAGIC):
        opcode, length = struct.unpack_from("<BQ", data, k)
        out.append(Record(k, opcode, data[k + 9:k + 9 + length]))
        k += 9 + length
    return out


def join(recs: list[Record]) -> bytes:
    return MAGIC + b"".join(struct.pack("<BQ", r.opcode, len(r.body)) + r.body for r in recs) + MAGIC


def chunk_ends(data: bytes) -> list[int]:
    """Byte offsets right after each chunk (where a logger killed between flushes leaves the file)."""
    return [r.end for r in records(data) if r.opcode == Opcode.CHUNK]


def first(recs: list[Record], opcode: int) -> int:
    return next(i for i, r in enumerate(recs) if r.opcode == opcode)


def set_length(data: bytes, index: int, length: int) -> bytes:
    """Top-level record `index` claims `length` bytes (its bytes stay as they are)."""
    rec = records(data)[index]
    return data[:rec.offset + 1] + struct.pack("<Q", length) + data[rec.offset + 9:]


def set_u32(data: bytes, at: int, value: int) -> bytes:
    return data[:at] + struct.pack("<I", value) + data[at + 4:]


def set_u64(data: bytes, at: int, value: int) -> bytes:
    return data[:at] + struct.pack("<Q", value) + data[at + 8:]


def chunk_fields(rec: Record) -> dict[str, int]:
    """Byte offsets (in the file) of a chunk record's fields."""
    base = rec.offset + 9
    (comp_len,) = struct.unpack_from("<I", rec.body, 28)
    return {"uncompressed_size": base + 16, "crc": base + 24, "compression": base + 28,
            "records_length": base + 32 + comp_len, "records": base + 40 + comp_len}


def read_chunk(rec: Record) -> Chunk:
    return next(StreamReader(BytesIO(struct.pack("<BQ", rec.opcode, len(rec.body)) + rec.body),
                             skip_magic=True, emit_chunks=True).records)


def rebuild_chunk(rec: Record, edit, *, compression: str | None = None) -> Record:
    """The chunk with `edit(list_of_inner_records)` applied, recompressed, with a fresh CRC."""
    chunk = read_chunk(rec)
    inner = edit(breakup_chunk(chunk, validate_crc=False))
    builder = RecordBuilder()
    for r in inner:
        r.write(builder)
    raw = builder.end()
    compression = chunk.compression if compression is None else compression
    data = zstandard.compress(raw) if compression == "zstd" else raw
    out = Chunk(message_start_time=chunk.message_start_time, message_end_time=chunk.message_end_time,
                uncompressed_size=len(raw), uncompressed_crc=zlib.crc32(raw), compression=compression, data=data)
    builder = RecordBuilder()
    out.write(builder)
    body = builder.end()
    return Record(rec.offset, Opcode.CHUNK, body[9:])


def edit_messages(data: bytes, change, *, chunk: int = 0) -> bytes:
    """Apply `change(message) -> bytes` to the data of every message of the `chunk`-th chunk."""
    recs = records(data)
    index = [i for i, r in enumerate(recs) if r.opcode == Opcode.CHUNK][chunk]

    def edit(inner):
        return [Message(channel_id=r.channel_id, sequence=r.sequence, log_time=r.log_time,
                        publish_time=r.publish_time, data=change(r)) if isinstance(r, Message) else r
                for r in inner]

    recs[index] = rebuild_chunk(recs[index], edit)
    return join(recs)


def replace_metadata(data: bytes, name: str, values: dict[str, str]) -> bytes:
    """The file with its metadata record `name` holding `values` instead (lengths written anew)."""
    recs = records(data)
    builder = RecordBuilder()
    Metadata(name=name, metadata=values).write(builder)
    body = builder.end()[9:]
    prefix = struct.pack("<I", len(name.encode())) + name.encode()
    return join([Record(r.offset, r.opcode, body) if r.opcode == Opcode.METADATA and r.body.startswith(prefix)
                 else r for r in recs])


def write_feedlog(streams: dict[str, pa.Table], *, chunk_size: int, compression: str, rows_per_message: int,
                  program: bytes = b"G1 X10 F600\nM2\n") -> bytes:
    """A feedlog recording (format v1) written with the plain mcap Writer, byte for byte reproducible."""
    out = BytesIO()
    writer = Writer(out, chunk_size=chunk_size, compression=CompressionType[compression.upper()],
                    index_types=IndexType.ALL)
    writer.start(profile="feedlog", library="fuzz seed")
    writer.add_metadata("feedlog", {"format_version": "1", "writer": "fuzz seed",
                                    "message_encoding": "arrow.record_batch"})
    writer.add_metadata("session", {"machine": "fuzz", "units": "mm", "nominal_rate_hz": "1000"})
    writer.add_attachment(0, 0, "program.ngc", "text/x-gcode", program)
    channels = {}
    for name, table in streams.items():
        schema = table.schema.with_metadata({"feedlog.stream": name, "feedlog.format_version": "1"})
        sid = writer.register_schema(f"feedlog.{name}", "arrow.schema", schema.serialize().to_pybytes())
        channels[name] = writer.register_channel(name, "arrow.record_batch", sid, {})
    n = max(len(t) for t in streams.values())
    for start in range(0, n, rows_per_message):  # streams interleaved by time, as a logger writes them
        for name, table in streams.items():
            piece = table.slice(start, rows_per_message)
            if piece.num_rows:
                t0 = int(piece.column(0)[0].as_py())
                writer.add_message(channels[name], t0, piece.to_batches()[0].serialize().to_pybytes(), t0)
    writer.add_metadata("feedlog.stats", {"dropped_frames": "0", "closed": "true"})
    writer.finish()
    return out.getvalue()


def seed_streams(n: int = 6000, rate_hz: float = 1000.0) -> dict[str, pa.Table]:
    """A plausible 3-axis session: a circle at 1 kHz, its feed, program line and status."""
    t = np.arange(n, dtype=np.int64) * int(1e9 / rate_hz) + 1_000_000_000
    phase = np.linspace(0, 4 * np.pi, n)
    return {
        "axes": pa.table({"t_ns": t, "x_mm": 10 * np.cos(phase), "y_mm": 10 * np.sin(phase),
                          "z_mm": np.full(n, -1.0)}),
        "feed": pa.table({"t_ns": t, "feed_mm_min": np.full(n, 1500.0)}),
        "line": pa.table({"t_ns": t, "line": (np.arange(n) // 500 + 1).astype(np.int64)}),
        "status": pa.table({"t_ns": t, "in_position": np.zeros(n, dtype=bool),
                            "motion_type": np.full(n, 2, dtype=np.int8)}),
    }
