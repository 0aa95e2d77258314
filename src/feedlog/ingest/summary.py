"""A short description of a recording: what `feedlog info` prints."""

from __future__ import annotations

from typing import Any

from feedlog.recording import Recording


def stream_rate_hz(t_ns) -> float:
    """Mean sample rate: (samples - 1) / span; 0 for fewer than two samples or a zero span."""
    if len(t_ns) < 2:
        return 0.0
    span = int(t_ns[-1]) - int(t_ns[0])
    return (len(t_ns) - 1) * 1e9 / span if span > 0 else 0.0


def summarize(recording: Recording) -> dict[str, Any]:
    """duration_s, streams (name, samples, rate_hz, columns), dropped_frames, metadata, attachments."""
    streams = []
    for name, table in recording.streams.items():
        t = table["t_ns"].to_numpy()
        streams.append({
            "name": name,
            "samples": int(len(table)),
            "rate_hz": round(stream_rate_hz(t), 3),
            "columns": [str(c) for c in table.columns],
            "t_start_ns": int(t[0]) if len(t) else None,
            "t_end_ns": int(t[-1]) if len(t) else None,
        })
    return {
        "file": recording.source,
        "duration_s": round(recording.duration_s, 6),
        "streams": streams,
        "dropped_frames": int(recording.dropped_frames),
        "metadata": dict(recording.metadata),
        "attachments": {name: len(data) for name, data in recording.attachments.items()},
    }


def format_summary(info: dict[str, Any]) -> str:
    lines = [f"{info['file']}: {info['duration_s']:.3f} s, {len(info['streams'])} streams, "
             f"{info['dropped_frames']} dropped frames"]
    for s in info["streams"]:
        lines.append(f"  {s['name']:<12} {s['samples']:>10} samples {s['rate_hz']:>10.1f} Hz  "
                     f"{', '.join(s['columns'][1:])}")
    for key, value in info["metadata"].items():
        lines.append(f"  {key}: {value}")
    for name, size in info["attachments"].items():
        lines.append(f"  attachment {name} ({size} bytes)")
    return "\n".join(lines)
