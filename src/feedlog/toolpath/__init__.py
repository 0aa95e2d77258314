"""feedlog.toolpath: part programs as typed block tables, their geometry features and CL points.

    program = parse_program("part.ngc")          # Program: .blocks, .motion, .warnings, ...
    program = load_program("part.mpf")           # any dialect (Fanuc/Hurco, Sinumerik): translated, then parsed
    features = block_features(program, "linuxcnc-xyz")
    points = cl_points(program, chord_tol_mm=0.001)                    # program (work) coordinates
    measured_frame = cl_points(program, chord_tol_mm=0.001, frame="machine")  # + work offsets
    machine_blocks = to_machine(program.blocks)  # block table in machine coordinates
    work_offsets(program)                        # [{coord_system, offset, blocks}] in force on motion
    segments = linearize(program, 0.001)         # arcs as G1 chords
    summary = summarize(program, load_profile("linuxcnc-xyz"))  # what `feedlog program` prints
"""

from feedlog.toolpath.features import block_features
from feedlog.toolpath.linearize import cl_points, linearize
from feedlog.toolpath.load import load_program
from feedlog.toolpath.offsets import to_machine
from feedlog.toolpath.parser import parse_program
from feedlog.toolpath.program import Program, Unsupported
from feedlog.toolpath.summary import extents, summarize, work_offsets

__all__ = ["Program", "Unsupported", "block_features", "cl_points", "extents", "linearize", "load_program",
           "parse_program",
           "summarize", "to_machine", "work_offsets"]
