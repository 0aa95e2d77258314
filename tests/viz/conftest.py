"""Shared viz test helpers: strict Rerun logging and a reader that summarises a saved .rrd."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pyarrow as pa
import pytest
import rerun as rr
from rerun.chunk import RrdReader


@pytest.fixture(autouse=True)
def strict_rerun():
    """Logging mistakes raise instead of warning."""
    rr.set_strict_mode(True)
    yield


def rrd_content(path: Path) -> dict[str, dict]:
    """entity path -> {"rows": samples over time, "timelines": set, "static": [column names], "chunks": [...]}
    read back with Rerun's own RRD reader."""
    content: dict[str, dict] = {}
    for chunk in RrdReader(path).stream():
        entry = content.setdefault(chunk.entity_path, {"rows": 0, "timelines": set(), "static": [], "chunks": []})
        if chunk.is_static:
            entry["static"].extend(chunk.to_record_batch().schema.names)
        else:
            entry["rows"] += chunk.num_rows
            entry["timelines"].update(chunk.timeline_names)
        entry["chunks"].append(chunk)
    return content


def column_values(entry: dict, name: str) -> np.ndarray:
    """All values of one column (a timeline or a component) across an entity's temporal chunks."""
    parts = []
    for chunk in entry["chunks"]:
        if chunk.is_static:
            continue
        batch = chunk.to_record_batch()
        col = batch.column(batch.schema.get_field_index(name))
        if pa.types.is_list(col.type) or pa.types.is_large_list(col.type):
            col = col.flatten()  # one value per row for the series viz logs
        if pa.types.is_duration(col.type):
            col = col.cast(pa.int64())
        parts.append(col.to_numpy(zero_copy_only=False))
    return np.concatenate(parts) if parts else np.zeros(0)
