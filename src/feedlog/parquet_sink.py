"""Tables appended to one Parquet file batch by batch (a windowed simulation, a streamed program).

Write to a temporary name (`feedlog.atomic`) and rename when done: a `ParquetSink` only appends.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq


class ParquetSink:
    """Frames appended to one Parquet file; the first frame fixes the schema."""

    def __init__(self, path: Path) -> None:
        self.path = path
        self._writer: pq.ParquetWriter | None = None

    def write(self, frame: pd.DataFrame) -> None:
        table = pa.Table.from_pandas(frame, preserve_index=False)
        if self._writer is None:
            self._writer = pq.ParquetWriter(self.path, table.schema)
        elif not table.schema.equals(self._writer.schema):   # e.g. a column all None in this batch
            table = table.cast(self._writer.schema)
        self._writer.write_table(table)

    def close(self, empty: pd.DataFrame | None = None) -> None:
        """Finish the file; with no frame written, `empty` (the table's columns, no rows) is the file."""
        if self._writer is None and empty is not None:
            self.write(empty)
        if self._writer is not None:
            self._writer.close()
            self._writer = None
