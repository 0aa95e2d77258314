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


def rrd_recordings(path: Path) -> dict[str, object]:
    """recording name (`send_recording_name`) -> Rerun's store entry, for every recording in the file."""
    reader = RrdReader(path)
    names = {}
    for store in reader.recordings():
        for chunk in reader.stream(store=store):
            batch = chunk.to_record_batch()
            if chunk.entity_path == "/__properties" and "RecordingInfo:name" in batch.schema.names:
                names[batch.column("RecordingInfo:name").to_pylist()[0][0]] = store
    return names


def rrd_blueprint_labels(path: Path) -> tuple[int, dict[str, list[str]]]:
    """(number of blueprints in the file, entity path -> the series labels its blueprint overrides give)."""
    reader = RrdReader(path)
    labels: dict[str, list[str]] = {}
    for store in reader.blueprints():
        for chunk in reader.stream(store=store):
            batch = chunk.to_record_batch()
            if "SeriesLines:names" in batch.schema.names and "/overrides/" in chunk.entity_path:
                entity = chunk.entity_path.split("/overrides", 1)[1].split("/visualizers", 1)[0]
                labels[entity] = [n for row in batch.column("SeriesLines:names").to_pylist() for n in row]
    return len(reader.blueprints()), labels


def rrd_content(path: Path, recording: str | None = None) -> dict[str, dict]:
    """entity path -> {"rows": samples over time, "timelines": set, "static": [column names], "chunks": [...]}
    read back with Rerun's own RRD reader (`recording`: the one of that name, else the file's first)."""
    content: dict[str, dict] = {}
    store = None if recording is None else rrd_recordings(path)[recording]
    for chunk in RrdReader(path).stream(store=store):
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
