"""Align a recording without positions on its program-line stream alone.

Some logs hold only what the controller executes (the line, or the block number mapped to lines by
`align.partial.program_lines`) and a few events, no axis positions. The block times then come from the
line stream (`blocks.blocks_from_lines`): a block starts when its line first shows and ends when the
next line shows; the cycle time is the first motion block's start to the last one's end. Nothing is
matched geometrically, so the points table has the program's CL points with no measured time, distance
or feed (the same columns as a full alignment, so the dataset keeps one schema), and the report says
`"mode": "line stream only"`.
"""

from __future__ import annotations

from types import SimpleNamespace
from typing import Any

import numpy as np
import pandas as pd

from feedlog.align.blocks import NO_TIME, MotionSpan, blocks_from_lines
from feedlog.align.pipeline import Alignment, AlignConfig, _points_table, join_by_block
from feedlog.align.line_session import session_lines
from feedlog.align.timing import stream_timing
from feedlog.errors import AlignmentError
from feedlog.recording import Recording
from feedlog.profile import MachineProfile
from feedlog.toolpath import Program, block_features, cl_points


def align_on_lines(recording: Recording, prog: Program, prof: MachineProfile | None, cfg: AlignConfig,
                   report: dict[str, Any]) -> Alignment:
    """Block times and cycle time of `prog` from the recording's line stream (no positions)."""
    stream = recording.streams.get(cfg.line_stream)
    if stream is None or "line" not in stream.columns or len(stream) < 2:
        raise AlignmentError(f"{recording.source or 'recording'}: no {cfg.positions!r} stream with positions and "
                             f"no {cfg.line_stream!r} stream with program lines or block numbers: nothing to align on")
    t = stream["t_ns"].to_numpy(dtype=np.int64)
    motion = prog.motion.reset_index(drop=True)
    t, lines, session = session_lines(recording, prog, prof, t, stream["line"].to_numpy(), cfg.numbering)
    report.update(session.report)
    report["warnings"].extend(session.warnings)
    lb = blocks_from_lines(t, lines, motion)
    seen = lb["seen"].to_numpy()
    first, last = np.flatnonzero(seen)[[0, -1]]
    span = MotionSpan(t_start_ns=int(lb["t_start_ns"].iloc[first]), t_end_ns=int(lb["t_end_ns"].iloc[last]),
                      first_index=0, last_index=len(t) - 1)
    lb["source"] = "line"
    cl = cl_points(prog, chord_tol_mm=cfg.chord_tol_mm).reset_index(drop=True)
    n = len(cl)
    nothing = SimpleNamespace(matched=np.zeros(n, dtype=bool), t_ns=np.full(n, NO_TIME, dtype=np.int64),
                              dist_mm=np.full(n, np.nan), nearest=np.full(n, -1, dtype=np.int64))
    feeds = pd.DataFrame({f"v{axis}_mm_min": np.full(n, np.nan) for axis in "xyz"})  # no measured feeds
    points = _points_table(cl, nothing, feeds, np.full(n, np.nan), span)
    feats = block_features(prog, prof)
    blocks_out = join_by_block(lb, feats, exclude=("line",))
    points = join_by_block(points, feats, exclude=("line", "kind", "feed_mm_min"))
    timing = stream_timing(t, name=cfg.line_stream)
    report["timing"] = {cfg.line_stream: timing.as_dict()}
    report["mode"] = "line stream only"
    report["warnings"].append("no positions: block times from the line stream alone (a block starts when its line "
                              "shows); nothing matched geometrically")
    report["motion"] = {"t_start_ns": span.t_start_ns, "t_end_ns": span.t_end_ns, "cycle_time_s": span.duration_s,
                        "sub_sample_model": None}
    report["match"] = {"cl_points": n, "measured_samples": len(t), "matched": 0, "dist_median_mm": None,
                       "dist_max_mm": None, "rapid_dist_max_mm": None}
    report["feed_source"] = None
    report["line_stream"] = {"offset_vs_geometry": None, "shifted_ns": 0}
    report["blocks"] = {"motion_blocks": len(lb), "source": "line", "unseen_in_line_stream": int((~seen).sum()),
                        "sum_duration_s": float(lb["duration_s"].sum())}
    report["cycle_time_s"] = span.duration_s
    return Alignment(points=points, blocks=blocks_out, cycle_time_s=span.duration_s, report=report,
                     geometry_blocks=None, line_blocks=lb)
