"""The recording model, as ingest has always offered it: it lives in the base layer (`feedlog.recording`),
since the simulation's measurement model, align, diagnose and viz build and read recordings too."""

from feedlog.recording import (METADATA_KEYS, PROFILE_ATTACHMENT, PROGRAM_ATTACHMENT, Recording, check_stream,
                               first_bad_value)

__all__ = ["METADATA_KEYS", "PROFILE_ATTACHMENT", "PROGRAM_ATTACHMENT", "Recording", "check_stream",
           "first_bad_value"]
