"""feedlog.toolpath.interp: the RS274/NGC interpreter layer (LinuxCNC 2.9 semantics).

    program = interpret("part.ngc", search_path=["subs/"], tool_table="tools.tbl")
    program.blocks      # the block table (toolpath.schema), one row per executed block and per move,
                        # with `file`, `line` and the call `stack` it came from

Parameters, expressions, O-word control flow and subroutines (in the file or found along the search
path), canned cycles, polar coordinates, work offsets (G10, G92, G52, G54-G59.3, rotation), tool
length offsets and units run as LinuxCNC runs them; `tests/toolpath/test_interp_reference.py` compares
the motion with LinuxCNC's own interpreter.
"""

from feedlog.toolpath.interp.run import InterpOptions, interpret, needs_interpreter

__all__ = ["InterpOptions", "interpret", "needs_interpreter"]
