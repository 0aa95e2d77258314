"""feedlog.align: measured data in the program's terms.

    alignment = align_recording(recording, program, profile=profile, tol_mm=0.05)
    alignment.points   # one row per CL point: matched time, distance, measured feed, per-axis feeds, features
    alignment.blocks   # one row per motion block: block, line, t_start_ns, t_end_ns, duration_s, features
    alignment.cycle_time_s, alignment.report

Building blocks: `resample` (interpolate/hold, anti-alias, gaps), `estimate_offset`/`event_offset`
(clock offsets), `feed_from_positions`, `match_cl_points`, `motion_span`, `blocks_from_lines`,
`blocks_from_geometry`; `align_many` runs many recordings in parallel. See docs/align.md.
"""

from feedlog.align.blocks import blocks_from_geometry, blocks_from_lines, compare_blocks, motion_span
from feedlog.align.clock import ClockOffset, estimate_offset, event_offset, shift_stream
from feedlog.align.feed import FeedSmoothing, feed_from_positions
from feedlog.align.match import Match, MatchConfig, match_cl_points
from feedlog.align.pipeline import AlignConfig, Alignment, align_recording
from feedlog.align.resample import Resampled, common_timebase, resample
from feedlog.align.timing import StreamTiming, stream_timing

__all__ = ["AlignConfig", "Alignment", "ClockOffset", "FeedSmoothing", "Match", "MatchConfig", "Resampled",
           "StreamTiming", "align_recording", "blocks_from_geometry", "blocks_from_lines", "common_timebase",
           "compare_blocks", "estimate_offset", "event_offset", "feed_from_positions", "match_cl_points",
           "motion_span", "resample", "shift_stream", "stream_timing"]
