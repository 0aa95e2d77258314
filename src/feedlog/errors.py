"""One exception tree for everything feedlog raises on purpose.

The CLI turns any `FeedlogError` into one line on stderr: exit code 2 when the input or the arguments
cannot be used (like argparse's usage errors: change them and run again), exit code 1 for
`OutputError`, when the inputs were fine but an output could not be written (a full disk, a missing
permission). Anything else is a bug and keeps its traceback.
"""

from __future__ import annotations


class FeedlogError(Exception):
    """Root of feedlog's errors: bad input, bad configuration, impossible requests."""

    exit_code = 2  # what the CLI exits with: the input or the arguments cannot be used


class LocatedError(FeedlogError):
    """An error that points at a place in a file: a line for text, a record or byte offset otherwise."""

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 position: str | None = None) -> None:
        self.message = message
        self.file = None if file is None else str(file)
        self.line = line
        self.position = position
        super().__init__(self._render())

    def _render(self) -> str:
        where = self.file or ""
        if self.line is not None:
            where = f"{where}:{self.line}" if where else f"line {self.line}"
        if self.position:
            where = f"{where} ({self.position})" if where else self.position
        return f"{where}: {self.message}" if where else self.message


class ProgramError(LocatedError):
    """A part program that cannot be read: names file, line and the offending code."""

    def __init__(self, message: str, *, file: str | None = None, line: int | None = None,
                 code: str | None = None) -> None:
        self.code = code
        if code:
            message = f"{message} [{code}]"
        super().__init__(message, file=file, line=line)


class ProfileError(LocatedError):
    """A machine profile that is missing, malformed or physically impossible."""


class IngestError(LocatedError):
    """A recording or log that cannot be read: names the file and the record or byte position."""


class OutputError(LocatedError):
    """An output that could not be written (disk full, file size limit, permissions): names the file.
    Nothing half-written is left behind, except by the live logger, which keeps what it flushed."""

    exit_code = 1


class AlignmentError(FeedlogError):
    """Measured data that does not match the program within the stated tolerance."""


class SimulationError(FeedlogError):
    """A program the simulation cannot run with the given profile."""


class ModelError(FeedlogError):
    """A model config, checkpoint or input that does not fit."""


class UnitError(FeedlogError):
    """An unknown or incompatible unit."""
