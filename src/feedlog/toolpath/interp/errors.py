"""The interpreter's own error, raised deep inside evaluation and turned into a ProgramError (file,
line, call stack) by the interpreter loop, which knows where it is."""

from __future__ import annotations


class InterpError(Exception):
    """A G-code error without its place yet: the interpreter adds file and line."""
