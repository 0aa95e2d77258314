"""feedlog.toolpath: part programs as typed block tables, their geometry features and CL points."""

from feedlog.toolpath.parser import parse_program
from feedlog.toolpath.program import Program, Unsupported

__all__ = ["Program", "Unsupported", "parse_program"]
