"""Decoded CAN frames -> recording streams.

Each signal goes to the stream named by the DBC attribute `FeedlogStream` (on the signal, else on its
message, else the message name in lower_snake_case); its column is the signal name with the unit
appended unless already there. A stream fed by several messages (feedlog's `axes`: XY, ZA, BC frames)
takes its times from its lowest frame id and joins the others by their sample counter
`seq` and nearest time (`pandas.merge_asof`); a sample that misses one of its frames is left out and
counted (`Decoded.incomplete`), so no stream ever holds a NaN for a frame that did not come. Frames
shorter than their DBC message are not decoded (their missing bytes would read as zeros) and are
counted (`Decoded.short`). The `seq` signals also count lost samples.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from feedlog.ingest.can_dbc import SEQ_SIGNAL, CanFrames, DbcLayout, MessageLayout

_DTYPES = {"line": np.int64, "motion_type": np.int8}


@dataclass
class Decoded:
    """Per frame id: frame times and decoded signal arrays; plus frames the DBC does not know."""

    times: dict[int, np.ndarray] = field(default_factory=dict)
    values: dict[int, dict[str, np.ndarray]] = field(default_factory=dict)
    unknown: dict[int, int] = field(default_factory=dict)
    short: dict[int, int] = field(default_factory=dict)       # frames shorter than their message, per id
    incomplete: dict[str, int] = field(default_factory=dict)  # samples left out for a missing frame, per stream

    @property
    def short_frames(self) -> int:
        return int(sum(self.short.values()))

    def short_report(self) -> str:
        return f"{self.short_frames} frames shorter than their DBC message, not decoded: " + \
            ", ".join(f"0x{k:X} ({v})" for k, v in sorted(self.short.items()))

    @property
    def unknown_frames(self) -> int:
        return int(sum(self.unknown.values()))

    def unknown_report(self) -> str:
        top = sorted(self.unknown.items(), key=lambda kv: -kv[1])[:10]
        return f"{self.unknown_frames} frames with ids not in the DBC: " + ", ".join(f"0x{k:X} ({v})" for k, v in top)


def decode_frames(frames: CanFrames, layout: DbcLayout) -> Decoded:
    """Decode every frame whose id the DBC knows (vectorised per id); count the others by id."""
    out = Decoded()
    if not len(frames):
        return out
    words = frames.data.view("<u8").ravel()
    known = np.zeros(len(frames), dtype=bool)
    for frame_id, message in layout.messages.items():
        mask = frames.can_id == frame_id
        index = np.flatnonzero(mask)
        if not len(index):
            continue
        known |= mask
        short = frames.dlc[index] < message.length
        if short.any():
            out.short[frame_id] = int(short.sum())
            index = index[~short]
        out.times[frame_id] = frames.t_ns[index]
        out.values[frame_id] = (message.decode_words(words[index]) if message.bulk
                                else message.decode(frames.data[index]))
    if not known.all():
        ids, counts = np.unique(frames.can_id[~known], return_counts=True)
        out.unknown = {int(i): int(c) for i, c in zip(ids, counts)}
    return out


def lost_samples(seq: np.ndarray) -> int:
    """Samples missing from an 8-bit wrapping counter (repeats count as none)."""
    if len(seq) < 2:
        return 0
    step = np.diff(seq.astype(np.int64)) % 256
    return int((step[step > 0] - 1).sum())


def _column(values: np.ndarray, column: str, length: int) -> np.ndarray:
    if column in _DTYPES:
        return values.astype(_DTYPES[column])
    if length == 1 and values.dtype.kind == "i":
        return values != 0
    return values


def _message_table(message: MessageLayout, decoded: Decoded, stream: str) -> pd.DataFrame | None:
    t = decoded.times.get(message.frame_id)
    if t is None:
        return None
    values = decoded.values[message.frame_id]
    cols = {"t_ns": t}
    for s in message.signals:
        if s.stream == stream and s.name != SEQ_SIGNAL:
            cols[s.column] = _column(values[s.name], s.column, s.length)
    if SEQ_SIGNAL in values:
        cols["_seq"] = values[SEQ_SIGNAL]
    table = pd.DataFrame(cols)
    if len(t) > 1 and (np.diff(t) < 0).any():
        table = table.sort_values("t_ns", kind="stable", ignore_index=True)
    return table


def lost_counts(decoded: Decoded) -> dict[int, int]:
    """Frames missing per frame id, from each message's own seq counter."""
    return {fid: lost_samples(v[SEQ_SIGNAL][np.argsort(decoded.times[fid], kind="stable")])
            for fid, v in decoded.values.items() if SEQ_SIGNAL in v}


def assemble_streams(decoded: Decoded, layout: DbcLayout) -> tuple[dict[str, pd.DataFrame], int]:
    """(streams, samples lost: the most frames missing from any one message's seq counter)."""
    members: dict[str, list[MessageLayout]] = {}
    for message in layout.messages.values():
        for stream in dict.fromkeys(s.stream for s in message.signals if s.name != SEQ_SIGNAL):
            members.setdefault(stream, []).append(message)
    streams: dict[str, pd.DataFrame] = {}
    for stream, messages in members.items():
        messages = sorted(messages, key=lambda m: m.frame_id)  # the lowest id with frames gives the times
        tables = [t for m in messages if (t := _message_table(m, decoded, stream)) is not None]
        if not tables:
            continue
        merged = tables[0]
        orphans = 0  # samples whose first frame is missing: frames of the others that found no row
        for other in tables[1:]:
            merged = _join(merged, other)
            added = [c for c in other.columns if c not in ("t_ns", "_seq")]
            matched = int(merged[added].notna().all(axis=1).sum()) if added else len(other)
            orphans = max(orphans, len(other) - matched)
        columns = ["t_ns"] + [s.column for m in messages for s in m.signals
                              if s.stream == stream and s.name != SEQ_SIGNAL and s.column in merged]
        merged = merged[columns]
        complete = merged.notna().all(axis=1).to_numpy()
        left_out = int((~complete).sum()) + orphans
        if left_out:
            decoded.incomplete[stream] = decoded.incomplete.get(stream, 0) + left_out
            merged = merged[complete].reset_index(drop=True)
        streams[stream] = _typed(merged)
    return streams, max(lost_counts(decoded).values(), default=0)


def _typed(table: pd.DataFrame) -> pd.DataFrame:
    """Columns back to their own dtype where a join with missing rows had made them float or object."""
    table = table.infer_objects()
    for column, dtype in _DTYPES.items():
        if column in table and table[column].dtype != dtype:
            table[column] = table[column].astype(dtype)
    return table


def _join(base: pd.DataFrame, other: pd.DataFrame) -> pd.DataFrame:
    """Attach `other`'s columns to `base` rows: same seq (when both have one), nearest time."""
    dt = np.diff(base["t_ns"].to_numpy())
    tolerance = int(max(np.median(dt) // 2, 1_000)) if len(dt) else 1_000_000
    by = "_seq" if "_seq" in base and "_seq" in other else None
    right = other if by else other.drop(columns=["_seq"], errors="ignore")
    return pd.merge_asof(base, right, on="t_ns", by=by, direction="nearest", tolerance=tolerance)
