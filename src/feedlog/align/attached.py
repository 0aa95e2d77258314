"""The program and the profile a recording is aligned with: the ones given, else the ones it carries.

`attached_program` and `attached_profile` are align's rule, used by `align_recording` and by
`feedlog diagnose` (which aligns the same recordings and must read them the same way).
"""

from __future__ import annotations

from pathlib import Path

from feedlog.errors import AlignmentError
from feedlog.ingest.subroutine_files import load_recorded_program
from feedlog.profile import MachineProfile, load_profile
from feedlog.recording import PROFILE_ATTACHMENT, Recording
from feedlog.toolpath import Program, load_program


def attached_profile(recording: Recording, profile: MachineProfile | str | Path | None) -> MachineProfile | None:
    """`profile` (a profile, a shipped name or a file), else the recording's `profile.toml`, else None."""
    if isinstance(profile, MachineProfile):
        return profile
    if profile is not None:
        return load_profile(profile)
    data = recording.attachments.get(PROFILE_ATTACHMENT)
    if data is not None:
        return MachineProfile.from_toml(data.decode("utf-8"), source=f"{recording.source}:{PROFILE_ATTACHMENT}")
    return None


def attached_program(recording: Recording, program: Program | str | Path | None, lenient: bool,
                     dialect: str = "auto") -> Program:
    """`program` (a parsed program or a file), else the recording's `program.ngc`; AlignmentError without one."""
    if isinstance(program, Program):
        return program
    if program is not None:
        return load_program(Path(program), lenient=lenient, dialect=dialect)
    text = recording.program_text
    if text is None:
        raise AlignmentError(f"{recording.source or 'recording'}: no program given and none attached "
                             "(program.ngc); pass one with --program")
    return load_recorded_program(recording, lenient=lenient, dialect=dialect,
                                 name=f"{Path(recording.source).stem or 'recording'}:program.ngc")
