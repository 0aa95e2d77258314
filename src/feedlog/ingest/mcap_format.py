"""feedlog recording format v1 on MCAP: the constants and the per-message encoding.

One MCAP channel per stream (topic = stream name). The channel's schema is the Arrow schema of the
stream's table serialised as an Arrow IPC schema message (schema encoding `arrow.schema`); every
MCAP message on that channel holds one batch of samples as one Arrow IPC record-batch message
(message encoding `arrow.record_batch`), decodable with `pyarrow.ipc.read_record_batch(data, schema)`.
The full description for readers outside feedlog is docs/recording-format.md.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pyarrow as pa

from feedlog import __version__
from feedlog.errors import IngestError

FORMAT_VERSION = 1
PROFILE = "feedlog"  # MCAP header profile
LIBRARY = f"feedlog {__version__}"
SCHEMA_ENCODING = "arrow.schema"
MESSAGE_ENCODING = "arrow.record_batch"
SCHEMA_PREFIX = "feedlog."  # schema name = "feedlog.<stream>"

# MCAP metadata record names
META_FORMAT = "feedlog"  # {"format_version": "1", "writer": ...}
META_SESSION = "session"  # machine, controller, units, nominal_rate_hz, start_time, notes, ...
META_STATS = "feedlog.stats"  # {"dropped_frames": "N", "closed": "true"|"false"}; the last one counts

MEDIA_TYPES = {".ngc": "text/x-gcode", ".nc": "text/x-gcode", ".toml": "application/toml",
               ".json": "application/json", ".txt": "text/plain", ".csv": "text/csv", ".dbc": "text/plain"}


def media_type(name: str) -> str:
    for suffix, kind in MEDIA_TYPES.items():
        if name.lower().endswith(suffix):
            return kind
    return "application/octet-stream"


def table_to_batch(stream: str, table: pd.DataFrame | pa.Table | pa.RecordBatch | dict,
                   schema: pa.Schema | None = None) -> pa.RecordBatch:
    """Convert one appended table to an Arrow record batch (no pandas metadata), cast to `schema`."""
    if isinstance(table, pa.Table):
        batch = table.combine_chunks().to_batches()
        batch = batch[0] if batch else pa.RecordBatch.from_pylist([], schema=table.schema)
    elif isinstance(table, pa.RecordBatch):
        batch = table
    else:
        if isinstance(table, dict):
            names = list(table)
            columns = [np.asarray(v) for v in table.values()]
        else:
            names = [str(c) for c in table.columns]
            columns = [table[c].to_numpy() if not isinstance(table[c].dtype, pd.CategoricalDtype)
                       else table[c].astype(str).to_numpy() for c in table.columns]
        try:
            batch = pa.RecordBatch.from_arrays([pa.array(c) for c in columns], names=names)
        except (pa.ArrowException, TypeError, ValueError) as exc:
            raise IngestError(f"stream {stream!r}: cannot store columns {names}: {exc}") from None
    if batch.schema.metadata:
        batch = batch.replace_schema_metadata(None)
    if batch.num_columns == 0 or batch.schema.names[0] != "t_ns" or batch.schema.types[0] != pa.int64():
        raise IngestError(f"stream {stream!r}: first column must be t_ns int64, got "
                          f"{list(zip(batch.schema.names, map(str, batch.schema.types)))[:2]}")
    if schema is not None and not batch.schema.equals(schema):
        if batch.schema.names != schema.names:
            raise IngestError(f"stream {stream!r}: columns changed from {schema.names} to {batch.schema.names}")
        try:
            batch = batch.cast(schema)
        except (pa.ArrowException, ValueError) as exc:
            raise IngestError(f"stream {stream!r}: batch does not fit the stream's types: {exc}") from None
    return batch


def schema_bytes(stream: str, schema: pa.Schema) -> bytes:
    schema = schema.with_metadata({"feedlog.stream": stream, "feedlog.format_version": str(FORMAT_VERSION)})
    return schema.serialize().to_pybytes()


def read_schema(data: bytes) -> pa.Schema:
    return pa.ipc.read_schema(pa.py_buffer(data))


def column_summary(schema: pa.Schema) -> str:
    """Human-readable `name:type,...`, stored in the channel metadata for readers without Arrow."""
    return ",".join(f"{f.name}:{f.type}" for f in schema)


def batch_bytes(batch: pa.RecordBatch) -> bytes:
    return batch.serialize().to_pybytes()


def read_batch(data: bytes | memoryview, schema: pa.Schema) -> pa.RecordBatch:
    """Decode one message; its lengths and buffers are validated, so a corrupt batch raises here
    (ArrowInvalid) instead of reading beyond its buffers later."""
    batch = pa.ipc.read_record_batch(pa.py_buffer(data), schema)
    batch.validate(full=True)
    return batch


def batch_to_frame(batches: list[pa.RecordBatch], schema: pa.Schema) -> pd.DataFrame:
    """Concatenate a stream's batches into its DataFrame (numeric columns as numpy dtypes)."""
    table = pa.Table.from_batches(batches, schema=schema.remove_metadata())
    frame = table.to_pandas(split_blocks=True, self_destruct=True)
    frame.columns = list(schema.names)
    return frame
