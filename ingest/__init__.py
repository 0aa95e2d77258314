"""feedlog.ingest: the recording model, feedlog's MCAP recording format, readers and the live logger."""

from feedlog.ingest.reader import read_recording
from feedlog.ingest.recording import PROFILE_ATTACHMENT, PROGRAM_ATTACHMENT, Recording, check_stream
from feedlog.ingest.writer import RecordingWriter, write_recording

__all__ = ["PROFILE_ATTACHMENT", "PROGRAM_ATTACHMENT", "Recording", "RecordingWriter", "check_stream",
           "read_recording", "write_recording"]
