"""The block table: the typed, one-row-per-block form of a part program that every stage reads.

One row per program line that holds a block (motion or not). Positions are absolute, in mm and
degrees, in program (work) coordinates, after unit (G20/G21) and distance-mode (G90/G91) handling.
Start and end of every motion are explicit so that consumers never need the modal state.

Contract (column -> dtype); parsers may add columns, never drop or rename these.
"""

from __future__ import annotations

import numpy as np

# motion kinds, in the `kind` column
RAPID, LINEAR, ARC_CW, ARC_CCW, DWELL, NONE = "rapid", "linear", "arc_cw", "arc_ccw", "dwell", "none"
MOTION_KINDS = (RAPID, LINEAR, ARC_CW, ARC_CCW)
KINDS = MOTION_KINDS + (DWELL, NONE)

# path control modes, in the `path_mode` column (LinuxCNC names)
EXACT_PATH, EXACT_STOP, CONTINUOUS = "exact_path", "exact_stop", "continuous"  # G61, G61.1, G64
PATH_MODES = (EXACT_PATH, EXACT_STOP, CONTINUOUS)

AXES = ("x", "y", "z", "a", "b", "c")
AXIS_UNITS = {"x": "mm", "y": "mm", "z": "mm", "a": "deg", "b": "deg", "c": "deg"}
START_COLUMNS = tuple(f"{a}0_{AXIS_UNITS[a]}" for a in AXES)  # x0_mm ... c0_deg
END_COLUMNS = tuple(f"{a}_{AXIS_UNITS[a]}" for a in AXES)     # x_mm ... c_deg

BLOCK_COLUMNS: dict[str, object] = {
    "file": "string",          # source file name (or "<string>")
    "line": np.int32,          # 1-based line number in the source file
    "block": np.int32,         # 0-based row index in this table
    "kind": "category",        # one of KINDS
    **{c: np.float64 for c in START_COLUMNS},
    **{c: np.float64 for c in END_COLUMNS},
    "plane": np.int8,          # 17, 18 or 19 (G17/G18/G19), modal
    "cx_mm": np.float64,       # arc centre, absolute (NaN for non-arcs); the plane-normal
    "cy_mm": np.float64,       #   coordinate equals the arc's start
    "cz_mm": np.float64,
    "turns": np.int16,         # arc: full turns + 1 (P word, default 1); 0 for non-arcs
    "feed_mm_min": np.float64, # effective programmed feed (G93: derived from the block time)
    "inverse_time": np.bool_,  # G93 active for this block
    "dwell_s": np.float64,     # G4 P (s); 0 otherwise
    "path_mode": "category",   # one of PATH_MODES, modal
    "tol_mm": np.float64,      # G64 P tolerance; NaN when G64 has no P; 0 in G61/G61.1
    "merge_tol_mm": np.float64,  # G64 Q tolerance (LinuxCNC: Q defaults to P); NaN when none
    "ori_i": np.float64,       # tool orientation vector of five-axis CL data (NaN where absent)
    "ori_j": np.float64,
    "ori_k": np.float64,
    "units": "category",       # program units of the source line: "mm" or "in"
    "spindle_rpm": np.float64, # modal S
    "mcodes": "string",        # M codes on the line, e.g. "M3 M8" ("" when none)
    "comment": "string",       # comment text on the line ("" when none)
}

# work offsets (toolpath.offsets): machine position = program position + offset, per row. The parser
# writes them right after BLOCK_COLUMNS; hand-built tables may leave them out (read as 0).
OFFSET_COLUMNS: dict[str, object] = {
    "wx_mm": np.float64,       # active work offset (G54-G59.3 system + G92), 0 when none
    "wy_mm": np.float64,
    "wz_mm": np.float64,
    "wa_deg": np.float64,
    "wb_deg": np.float64,
    "wc_deg": np.float64,
    "coord_system": np.int8,   # active coordinate system: 1 = G54 ... 6 = G59, 7-9 = G59.1-G59.3,
                               # 10-57 = Fanuc's G54.1 P1-P48
}

# per-block geometry features (toolpath.features), one row per motion block
FEATURE_COLUMNS = (
    "block", "line", "kind",
    "length_mm",            # L_k, TCP path length (arcs: true arc length, helical included)
    "ori_arc_deg",          # theta_k, orientation arc length (Chien Eq. 2)
    "corner_start_deg",     # theta_TCP,k: TCP direction change entering the block (0 = collinear)
    "corner_end_deg",       # theta_TCP,k+1: TCP direction change leaving the block
    "ori_corner_start_deg", # theta_ORI,k
    "ori_corner_end_deg",   # theta_ORI,k+1
    "sin_rot",              # sin(A) (AC) or sin(B) (BC) at the block end (Chien Eq. 7-9); 0 for 3-axis
    "feed_mm_min", "tol_mm",
    "nominal_time_s",       # L / F (rapids at the profile's rapid rate when one is given)
    "vx_nom_mm_min", "vy_nom_mm_min", "vz_nom_mm_min",        # nominal axis feeds (Sun Eq. 5-6)
    "ax_nom_mm_s2", "ay_nom_mm_s2", "az_nom_mm_s2",           # nominal axis accelerations (Sun Eq. 7)
)
# appended by block_features after `corner_cos_end`: the workpiece offset [Xo, Yo, Zo] of Chien Eq. 10
# (Table 1 "WP translation distance to the rotary axis' origin"), i.e. the active work offset
OFFSET_FEATURE_COLUMNS = ("xo_mm", "yo_mm", "zo_mm")
