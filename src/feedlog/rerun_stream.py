"""The Rerun recording stream every feedlog export writes to (viz's views, diagnose's diagnose.rrd)."""

from __future__ import annotations

import uuid

import rerun as rr

APPLICATION_ID = "feedlog"


def new_stream(name: str) -> rr.RecordingStream:
    """A recording stream of its own (not the global one), named after the recording; a fresh id per
    export so that two exports sent to one viewer stay two recordings."""
    return rr.RecordingStream(APPLICATION_ID, recording_id=f"feedlog-{name}-{uuid.uuid4().hex[:12]}")
