"""The Rerun recording stream every feedlog export writes to (viz's views, diagnose's diagnose.rrd)."""

from __future__ import annotations

import uuid

import rerun as rr

APPLICATION_ID = "feedlog"


def new_stream(name: str, *, application_id: str = APPLICATION_ID) -> rr.RecordingStream:
    """A recording stream of its own (not the global one), named after the recording; a fresh id per
    export so that two exports sent to one viewer stay two recordings. A Rerun blueprint belongs to an
    application id: an export with a layout of its own (the demo's) takes an id of its own."""
    return rr.RecordingStream(application_id, recording_id=f"feedlog-{name}-{uuid.uuid4().hex[:12]}")
