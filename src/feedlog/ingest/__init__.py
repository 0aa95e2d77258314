"""feedlog.ingest: the recording model, feedlog's MCAP recording format, readers and the live logger.

Public API: `Recording`, `read_recording(path, *, recover=False)`, `write_recording(path, recording, *,
overwrite=False, compression="none")`, `RecordingWriter(path, *, metadata=, attachments=)`, and
`read_source(path_or_scheme, ImportOptions(...))` for any supported input (MCAP, CSV, CAN logs).
"""

from feedlog.ingest.reader import read_recording
from feedlog.ingest.readers import ImportOptions, read_source
from feedlog.recording import PROFILE_ATTACHMENT, PROGRAM_ATTACHMENT, Recording, check_stream
from feedlog.ingest.writer import RecordingWriter, write_recording

__all__ = ["PROFILE_ATTACHMENT", "PROGRAM_ATTACHMENT", "ImportOptions", "Recording", "RecordingWriter",
           "check_stream", "read_recording", "read_source", "write_recording"]
