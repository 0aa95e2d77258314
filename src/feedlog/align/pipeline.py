"""align_recording: one recording + its part program -> measured data in the program's terms.

Steps (each one a module of its own):
1. timing of every stream used (gaps, jitter: `timing`), reported;
2. motion span -> measured cycle time, first motion to end of motion (`blocks.motion_span`);
3. CL points of the program (`toolpath.cl_points`) matched to the measured path under progress and
   distance constraints (`match`); the tolerance per point is `tol_mm` plus the block's own G64 P
   blending tolerance and its G64 Q merge tolerance (Q = P when not given, as in LinuxCNC): a block
   merged into a longer move may sit up to Q off that move's chord, whose corner is then cut by up
   to P;
4. feed at every CL point: the recording's own path feed (`feed` stream) when it has one, interpolated
   at the matched time, else the feed from positions (`feed.feed_at`, centred on the matched time);
   per-axis feeds always from positions;
5. block boundaries from the line stream (ground truth) when there is one, and from geometry always
   (at 1 kHz on a machine whose profile merges like LinuxCNC, `[sim.naive_cam]`, per planner move:
   `moves.geometry_blocks_by_moves`);
   both are compared in the report (`blocks`); the line stream's clock offset against geometry is
   estimated from the block changes (`clock.event_offset`) and removed when `sync_lines` is set;
6. toolpath's paper features joined per block and per point (`toolpath.block_features`).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from feedlog.align.attached import attached_profile, attached_program
from feedlog.align.blocks import (NO_TIME, MotionSpan, blocks_from_geometry, blocks_from_lines, compare_blocks,
                                  leave_times, motion_span, rest_noise, split_merged)
from feedlog.align.clock import event_offset, shift_stream
from feedlog.align.feed import LINEAR, ROTARY, FeedSmoothing, feed_at_checked
from feedlog.align.line_sequence import shares_next_run
from feedlog.align.match import MatchConfig, match_cl_points
from feedlog.align.partial import auto_lines, program_lines, slice_program
from feedlog.align.session_events import events_report
from feedlog.align.subsample import refine_span
from feedlog.align.timing import stream_timing
from feedlog.align.work_offset import estimate_work_offset
from feedlog.errors import AlignmentError, FeedlogError
from feedlog.profile import MachineProfile, load_profile, path_acc_limit
from feedlog.recording import Recording
from feedlog.toolpath import Program, block_features, cl_points, to_machine
from feedlog.toolpath.schema import CONTINUOUS, RAPID

BOUNDARIES = ("auto", "pass", "leave")
NOT_ON_PATH = "never comes within"   # match's error when the program's first points are nowhere on the path
FEED_SOURCES = ("auto", "stream", "positions")
STRAIGHT = ("linear", RAPID)
WORK_OFFSET = ("wx_mm", "wy_mm", "wz_mm")  # toolpath's per-block work offset columns
SPARSE_NS = 5_000_000
REST_NOISE_K = 6.0  # standstill threshold in robust standard deviations of the position noise at rest  # sampling periods above this count as sparse (5 Hz logging, not a servo trace)


@dataclass(frozen=True)
class AlignConfig:
    """How to align. Distances in mm, times in s."""

    tol_mm: float = 0.05             # allowed CL-point distance on top of the block's G64 P tolerance
    unstated_tol_mm: float = 1.0     # allowed distance where the program states no blending tolerance
                                     # (continuous mode without P: LinuxCNC's G64 alone, a dialect's
                                     # smoothing such as Sinumerik G642 whose tolerance is machine data);
                                     # what the path really did there is measured and reported
    check_rapids: bool = False       # rapids may dog-leg on some machines: only reported by default
    chord_tol_mm: float = 0.001      # arcs -> CL points (toolpath.cl_points)
    positions: str = "axes"          # stream with x_mm, y_mm, z_mm (+ a_deg, ...)
    line_stream: str = "line"        # stream with `line`; absent -> geometry only
    feed_stream: str = "feed"        # stream with `feed_mm_min`
    feed_source: str = "auto"        # auto: the feed stream when present, else positions
    boundary: str = "auto"           # geometric block end: pass (closest approach to the end point),
                                     # leave (where the tool leaves a straight block into a blend),
                                     # auto: leave when positions are sampled every <= 5 ms, else pass
    on_path_mm: float = 1e-6         # "on the block's segment" for `leave` (at least still_mm and 2 x the position
                                     # quantum; raise for noisy positions)
    still_mm: float | None = None    # distance from a rest position that counts as motion; None:
                                     # REST_NOISE_K x the noise at rest (blocks.rest_noise), >= 1e-6 mm
    sync_lines: bool = False         # remove the line stream's clock offset (estimated from geometry)
    model_span: bool = True          # sparse data: place motion start/end inside their sampling interval
                                     # with feedlog.sim's trajectory of the program (needs a profile)
    window_mm: float | None = None   # match search window (see MatchConfig)
    smoothing: FeedSmoothing = field(default_factory=FeedSmoothing)
    work_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)  # extra offset of the program origin in
                                     # the measured frame (one set on the machine, not in the program;
                                     # the program's own G10/G54/G92 come from toolpath)
    lenient: bool = False            # parse the program leniently (unsupported codes skipped, reported)
    dialect: str = "auto"            # G-code dialect of the program (toolpath.dialects)
    lines: tuple[int, int] | None = None  # align on program lines FIRST..LAST only (a partial recording)
    auto_lines: bool = True          # a line stream that leaves feed moves out cuts the program to its lines
    estimate_offset: bool = False    # estimate a constant work offset (added to work_offset_mm)
    auto_offset: bool = True         # ... and retry with one when the program does not lie on the measured path
                                     # (unless work_offset_mm was given)
    numbering: str = "auto"          # what recorded block values count, line stream alone (align.line_numbering):
                                     # auto (detected), file-lines, file-lines-no-percent, n-words, counter

    def __post_init__(self) -> None:
        if not self.tol_mm > 0:
            raise AlignmentError(f"tol_mm must be > 0, got {self.tol_mm}")
        if not self.unstated_tol_mm > 0:
            raise AlignmentError(f"unstated_tol_mm must be > 0, got {self.unstated_tol_mm}")
        if self.boundary not in BOUNDARIES:
            raise AlignmentError(f"boundary must be one of {', '.join(BOUNDARIES)}, got {self.boundary!r}")
        if self.feed_source not in FEED_SOURCES:
            raise AlignmentError(f"feed_source must be one of {', '.join(FEED_SOURCES)}, got {self.feed_source!r}")
        if len(self.work_offset_mm) != 3 or not np.isfinite(self.work_offset_mm).all():
            raise AlignmentError(f"work_offset_mm needs three finite values, got {self.work_offset_mm!r}")
        if self.lines is not None and not (len(self.lines) == 2 and 1 <= self.lines[0] <= self.lines[1]):
            raise AlignmentError(f"lines must be (first, last) program lines, 1 <= first <= last; got {self.lines!r}")
        if self.numbering not in ("auto", "file-lines", "file-lines-no-percent", "n-words", "counter"):
            raise AlignmentError(f"numbering must be auto, file-lines, file-lines-no-percent, n-words or counter, "
                                 f"got {self.numbering!r}")
        if not (self.on_path_mm > 0 and (self.still_mm is None or self.still_mm >= 0) and self.chord_tol_mm > 0):
            raise AlignmentError(f"need on_path_mm > 0, still_mm >= 0, chord_tol_mm > 0; got {self.on_path_mm}, "
                                 f"{self.still_mm}, {self.chord_tol_mm}")


@dataclass
class Alignment:
    """The result: per-CL-point and per-block tables in the program's terms, and what happened."""

    points: pd.DataFrame
    blocks: pd.DataFrame
    cycle_time_s: float
    report: dict[str, Any]
    geometry_blocks: pd.DataFrame | None = None
    line_blocks: pd.DataFrame | None = None
    geometry_blocks_base: pd.DataFrame | None = None  # per block, before the planner-move model (when it ran)


def position_quantum(pos: np.ndarray, *, samples: int = 100_000) -> float:
    """The smallest non-zero step of any linear axis (over an evenly strided subset): the encoder or
    fieldbus resolution of quantised positions, ~0 for floating-point commanded positions."""
    step = max(1, len(pos) // samples)
    d = np.abs(np.diff(pos[::step, :3], axis=0)) if step > 1 else np.abs(np.diff(pos[:, :3], axis=0))
    nz = d[d > 0]
    return float(nz.min()) if len(nz) else 0.0


def _positions(recording: Recording, cfg: AlignConfig) -> tuple[pd.DataFrame, list[str], np.ndarray]:
    axes = recording.stream(cfg.positions)
    missing = [c for c in LINEAR if c not in axes.columns]
    if missing:
        raise AlignmentError(f"{recording.source or 'recording'}: stream {cfg.positions!r} lacks {', '.join(missing)}")
    cols = [c for c in (*LINEAR, *ROTARY) if c in axes.columns]
    values = axes[cols].to_numpy(dtype=np.float64)
    if not np.isfinite(values).all():
        bad = int(np.flatnonzero(~np.isfinite(values).all(axis=1))[0])
        raise AlignmentError(f"{recording.source or 'recording'}: stream {cfg.positions!r} sample {bad} "
                             "has a non-finite position")
    return axes, cols, values


def align_recording(recording: Recording, program: Program | str | Path | None = None, *,
                    profile: MachineProfile | str | Path | None = None, config: AlignConfig | None = None,
                    **overrides: Any) -> Alignment:
    """Align one recording with its part program (given, or the attached `program.ngc`).

    Keyword overrides set `AlignConfig` fields, e.g. `align_recording(rec, tol_mm=2.0)`.
    """
    cfg = replace(config or AlignConfig(), **overrides) if overrides else (config or AlignConfig())
    prof = attached_profile(recording, profile)
    prog = attached_program(recording, program, cfg.lenient, cfg.dialect)
    try:
        return _align_or_retry(recording, prog, prof, cfg)
    except AlignmentError as exc:
        jumps = _position_jumps(recording, cfg.positions)   # a failure on data that lies says so
        if jumps:
            raise AlignmentError(f"{exc}; the positions may be why: {jumps}") from None
        raise


def _align_or_retry(recording: Recording, prog: Program, prof: MachineProfile | None, cfg: AlignConfig) -> Alignment:
    """`_align`, and once more with an estimated work offset when the program is not on the path."""
    try:
        return _align(recording, prog, prof, cfg)
    except AlignmentError as exc:
        given = any(cfg.work_offset_mm)   # a work offset the user gave is trusted, not second-guessed
        if not cfg.auto_offset or cfg.estimate_offset or given or NOT_ON_PATH not in str(exc):
            raise
        try:
            out = _align(recording, prog, prof, replace(cfg, estimate_offset=True))
        except AlignmentError:
            raise exc from None
    est = out.report["work_offset_estimate"]["offset_mm"]
    out.report["warnings"].append(f"the program did not lie on the measured path: aligned with an estimated work "
                                  f"offset ({', '.join(f'{v:.3f}' for v in est)}) mm; give it with --work-offset, "
                                  "or turn this off with --no-auto-offset")
    return out


def _lines_beyond_program(recording: Recording, prog: Program, stream: str) -> str | None:
    """Data that lies: recorded lines past the program's last block (the program is not what ran)."""
    from feedlog.ingest.data_checks import lines_beyond

    table = recording.streams.get(stream)
    if table is None or "line" not in table.columns or not len(table) or not len(prog.blocks):
        return None
    last = int(prog.blocks["line"].max())
    t = table["t_ns"].to_numpy(dtype=np.int64)
    return lines_beyond(t - recording.t_range_ns[0], table["line"].to_numpy(), last,
                        f"the program's last block (line {last})")


def _position_jumps(recording: Recording, positions: str) -> str | None:
    """Data that lies: position steps faster than the recording's own feeds allow (ingest.data_checks)."""
    from feedlog.ingest.data_checks import position_jumps

    if positions != "axes":     # the check reads the standard stream; another one is the user's choice
        return None
    return position_jumps(recording)


def _unstated_rounding(dist: np.ndarray, where: np.ndarray, cfg: AlignConfig, warnings: list[str]) -> dict | None:
    """How far the path left the program's points where the program states no blending tolerance, beyond
    what a sampled chord cuts off (the machine's own rounding, measured), with a warning when that is
    beyond `tol_mm`."""
    d = np.maximum(dist[where & np.isfinite(dist)], 0.0)
    if not len(d):
        return None
    out = {"points": int(len(d)), "allowed_mm": max(cfg.tol_mm, cfg.unstated_tol_mm),
           "dist_max_mm": float(d.max()), "dist_p95_mm": float(np.percentile(d, 95))}
    if out["dist_max_mm"] > cfg.tol_mm:
        warnings.append(f"the program states no blending tolerance on {len(d)} point(s) (G64 without P, or a "
                        f"controller's smoothing set in machine data): beyond what the sampled chords cut off, "
                        f"the path leaves them by up to "
                        f"{out['dist_max_mm']:.3f} mm (95 % within {out['dist_p95_mm']:.3f} mm); allowed up to "
                        f"{out['allowed_mm']:g} mm (--unstated-tol-mm)")
    return out


def _align(recording: Recording, prog: Program, prof: MachineProfile | None, cfg: AlignConfig) -> Alignment:
    lap = _Laps()
    recording = program_lines(recording, prog, stream=cfg.line_stream)
    lines = cfg.lines or (auto_lines(recording, prog, stream=cfg.line_stream) if cfg.auto_lines else None)
    if lines is not None:
        prog = slice_program(prog, lines)
    report: dict[str, Any] = {"recording": recording.source, "program": prog.name, "config": _config_dict(cfg),
                              "warnings": [f"program: {w}" for w in prog.warnings],
                              "lines": None if lines is None else {"first": lines[0], "last": lines[1],
                                                                   "from": "config" if cfg.lines else "line stream"}}
    if "line_from" in recording.metadata:
        report["line_from"] = recording.metadata["line_from"]
    beyond = _lines_beyond_program(recording, prog, cfg.line_stream)
    if beyond:
        report["warnings"].append(beyond)
    jumps = _position_jumps(recording, cfg.positions)
    if jumps:
        report["warnings"].append(jumps)
    if cfg.positions not in recording.streams:
        from feedlog.align.line_only import align_on_lines  # line_only imports this module
        return align_on_lines(recording, prog, prof, cfg, report)
    axes, cols, pos = _positions(recording, cfg)
    t = axes["t_ns"].to_numpy(dtype=np.int64)
    xyz = pos[:, :3]
    lap("inputs")
    timing = stream_timing(t, name=cfg.positions)
    report["timing"] = {cfg.positions: timing.as_dict()}
    if timing.gaps:
        report["warnings"].append(f"{cfg.positions}: {timing.gaps} gap(s), largest {timing.largest_gap_ns / 1e6:.1f} ms; "
                                  "matches and feeds across a gap use the straight chord over it")

    probe_s = max(0.1, 20 * timing.period_ns / 1e9)  # enough samples at rest at both ends (cut where motion starts)
    still = cfg.still_mm if cfg.still_mm is not None else min(0.05, max(1e-6, REST_NOISE_K * rest_noise(
        t, pos, probe_s=probe_s)))
    report["still_mm"] = still
    span = motion_span(t, pos, still_mm=still, acc_mm_s2=path_acc_limit(prof))
    refined = None
    if timing.period_ns > SPARSE_NS and prof is not None and cfg.model_span and lines is None \
            and not cfg.estimate_offset:  # the model runs the whole program in the program's own frame
        span, refined = _refine_with_sim(span, t, pos, cols, prog, prof, np.asarray(cfg.work_offset_mm, float),
                                         report)
    report["motion"] = {"t_start_ns": span.t_start_ns, "t_end_ns": span.t_end_ns, "cycle_time_s": span.duration_s,
                        "sub_sample_model": refined}

    lap("motion_span")
    # --- CL points and the constrained match -------------------------------------------------------
    cl = cl_points(prog, chord_tol_mm=cfg.chord_tol_mm).reset_index(drop=True)
    # program (work) coordinates -> the measured (machine) frame: the program's own work offsets
    # (G10 L2/G54..., toolpath's wx_mm..) plus `work_offset_mm` set on the machine outside the program
    offset = np.asarray(cfg.work_offset_mm, dtype=np.float64)
    cl_xyz = cl[list(LINEAR)].to_numpy(dtype=np.float64) + offset
    if set(WORK_OFFSET) <= set(cl.columns):
        cl_xyz = cl_xyz + np.nan_to_num(cl[list(WORK_OFFSET)].to_numpy(dtype=np.float64))
    if cfg.estimate_offset:
        estimate = estimate_work_offset(cl_xyz, xyz[span.first_index:span.last_index + 1])
        offset = offset + np.asarray(estimate.offset_mm)
        cl_xyz = cl_xyz + np.asarray(estimate.offset_mm)
        report["work_offset_estimate"] = estimate.as_dict()
    lap("cl_points")
    if len(cl) < 2:
        raise AlignmentError(f"{prog.name}: the program has no motion to align")
    blocks_tab = prog.blocks.set_index("block")
    blk = cl["block"].to_numpy()
    p_tol = blocks_tab["tol_mm"].reindex(blk).to_numpy(dtype=np.float64)
    q_tol = blocks_tab["merge_tol_mm"].reindex(blk).to_numpy(dtype=np.float64)
    q_tol = np.where(np.isnan(q_tol), p_tol, q_tol)  # LinuxCNC: Q defaults to P
    tolerance = cfg.tol_mm + np.nan_to_num(p_tol, nan=0.0) + np.nan_to_num(q_tol, nan=0.0)
    # continuous mode with no P: the program does not bound how far the machine rounds its corners
    unstated = np.isnan(p_tol) & (blocks_tab["path_mode"].astype(str).reindex(blk).to_numpy() == CONTINUOUS)
    tolerance = np.where(unstated, max(cfg.tol_mm, cfg.unstated_tol_mm), tolerance)
    kind = cl["kind"].astype(str).to_numpy()
    check = np.ones(len(cl), dtype=bool) if cfg.check_rapids else (kind != RAPID)
    check &= kind != "start"  # the parser's assumed initial position is not a programmed point
    if lines is not None and not cfg.lines:  # found from the line stream: its first block may have been
        check &= cl["line"].to_numpy() != lines[0]  # under way when the recording began (not checked)
    labels = _PointLabels(blk, cl["line"].to_numpy())
    mcfg = MatchConfig(tol_mm=float(tolerance.max()), window_mm=cfg.window_mm, still_mm=still)
    rapid_mm_min = prof.rapid_mm_min if prof is not None else np.nan
    speed = np.where(kind == RAPID, rapid_mm_min, cl["feed_mm_min"].to_numpy(dtype=np.float64)) / 60.0
    match = match_cl_points(cl_xyz, t, xyz, s_mm=cl["s_mm"].to_numpy(),
                            config=mcfg, tolerance=tolerance, check=check, labels=labels, speed_mm_s=speed,
                            period_ns=timing.period_ns)
    lap("match")
    d = match.dist_mm[np.isfinite(match.dist_mm)]
    report["match"] = {"cl_points": len(cl), "measured_samples": len(t), "matched": int(match.matched.sum()),
                       "dist_median_mm": float(np.median(d)) if len(d) else None,
                       "dist_max_mm": float(d.max()) if len(d) else None,
                       "rapid_dist_max_mm": float(np.nanmax(np.where(kind == RAPID, match.dist_mm, np.nan)))
                       if (kind == RAPID).any() and np.isfinite(match.dist_mm[kind == RAPID]).any() else None}
    beyond_chord = match.dist_mm - (match.chord_mm if match.chord_mm is not None else 0.0)
    report["unstated_tolerance"] = _unstated_rounding(beyond_chord, unstated & check, cfg, report["warnings"])

    # --- feeds (at the matched times only) ---------------------------------------------------------------
    ok = match.matched
    tq = np.where(ok, match.t_ns, t[0])
    feeds = feed_at_checked(t, pos, cols, tq, period_ns=timing.period_ns, smoothing=cfg.smoothing)
    path_feed, feed_from = _path_feed(recording, cfg, feeds, tq)
    report["feed_source"] = feed_from
    points = _points_table(cl, match, feeds, path_feed, span)
    lap("feeds")

    # --- blocks -------------------------------------------------------------------------------------
    motion = prog.motion.reset_index(drop=True)
    end_idx = _last_rows(blk, motion["block"].to_numpy())
    if (end_idx < 0).any():
        raise AlignmentError(f"{prog.name}: some motion blocks have no CL point")
    boundary = cfg.boundary
    if boundary == "auto":
        boundary = "leave" if timing.period_ns <= SPARSE_NS else "pass"
    leave = None
    if boundary == "leave":
        straight = motion["kind"].astype(str).isin(STRAIGHT).to_numpy()[:, None]
        in_machine = to_machine(motion)
        p0 = in_machine[["x0_mm", "y0_mm", "z0_mm"]].to_numpy(dtype=np.float64) + offset
        p1 = in_machine[["x_mm", "y_mm", "z_mm"]].to_numpy(dtype=np.float64) + offset
        leave = leave_times(t, xyz, np.where(straight, p0, np.nan), np.where(straight, p1, np.nan),
                            match.index[end_idx], on_path_mm=max(cfg.on_path_mm, 2 * position_quantum(pos), still))
    geo = blocks_from_geometry(motion, match.t_ns[end_idx], match.t_depart_ns[end_idx], span=span,
                               end_leave_ns=leave)
    geo["source"] = "geometry"
    report["boundary"] = boundary
    base = None
    if boundary == "leave" and prof is not None and prof.mechanism("naive_cam").get("enabled", False):
        from feedlog.align.moves import moves_from_blocks  # moves imports this module
        base = geo
        geo = moves_from_blocks(recording, geo, points, report, program=prog, profile=prof, positions=cfg.positions)
    report["geometry_model"] = "per block" if base is None else "planner moves"
    lap("geometry_blocks")
    line_blocks = _line_blocks(recording, cfg, motion, span, geo, report)
    lap("line_blocks")
    report["events"] = events_report(recording, cfg.line_stream, prog, (span.t_start_ns, span.t_end_ns))
    lap("events")
    primary = line_blocks if line_blocks is not None else geo

    feats = block_features(prog, prof)
    blocks_out = join_by_block(primary, feats, exclude=("line",))
    points = join_by_block(points, feats, exclude=("line", "kind", "feed_mm_min"))
    report["blocks"] = {"motion_blocks": len(primary), "source": str(primary["source"].iloc[0]) if len(primary) else None,
                        "unseen_in_line_stream": int((~line_blocks["seen"]).sum()) if line_blocks is not None else None,
                        "sum_duration_s": float(primary["duration_s"].sum())}
    report["cycle_time_s"] = span.duration_s
    lap("features")
    report["timings_s"] = lap.laps
    return Alignment(points=points, blocks=blocks_out, cycle_time_s=span.duration_s, report=report,
                     geometry_blocks=geo, line_blocks=line_blocks, geometry_blocks_base=base)


def _refine_with_sim(span: MotionSpan, t: np.ndarray, pos: np.ndarray, cols: list[str], prog: Program,
                     prof: MachineProfile, offset: np.ndarray, report: dict[str, Any]) -> tuple[MotionSpan, str | None]:
    model = _model_profile(prof)
    try:
        from feedlog.sim import simulate  # only sparse recordings need the model
        sim = simulate(prog, model)
    except (ImportError, FeedlogError) as exc:
        report["warnings"].append(f"no model for sub-sample motion start/end ({exc}); kinematic estimate used")
        return span, None
    series = sim.series
    shared = [c for c in cols if c in series.columns]  # x/y/z, and the rotary axes both have
    model_pos = series[shared].to_numpy(dtype=np.float64, copy=True)
    model_pos[:, :3] += offset
    if set(WORK_OFFSET) <= set(prog.blocks.columns) and "block" in series.columns:  # program -> machine frame
        w = prog.blocks.set_index("block")[list(WORK_OFFSET)].reindex(series["block"].to_numpy())
        model_pos[:, :3] += np.nan_to_num(w.to_numpy(dtype=np.float64))
    source = f"sim:{model.name}" + ("" if model is prof else " (shipped profile's sim settings)")
    measured = pos[:, [cols.index(c) for c in shared]]
    return refine_span(span, t, measured, series["t_ns"].to_numpy(), model_pos), source


def _model_profile(prof: MachineProfile) -> MachineProfile:
    """The profile to simulate with: `prof`, or, when it carries no `[sim]` settings (e.g. a profile
    attached by an older recorder), the shipped profile of the same name with the same axes, whose
    `[sim]` tables hold feedlog's fitted mechanism settings for that machine."""
    if prof.sim:
        return prof
    try:
        shipped = load_profile(prof.name)
    except FeedlogError:
        return prof
    if shipped.sim and shipped.axes == prof.axes and shipped.kinematics == prof.kinematics:
        return shipped
    return prof


class _Laps:
    """Wall time per pipeline step, for the report."""

    def __init__(self) -> None:
        self.laps: dict[str, float] = {}
        self._t = time.perf_counter()

    def __call__(self, name: str) -> None:
        now = time.perf_counter()
        self.laps[name] = round(now - self._t, 6)
        self._t = now


def _config_dict(cfg: AlignConfig) -> dict[str, Any]:
    d = asdict(cfg)
    d["smoothing"] = asdict(cfg.smoothing)
    return d


def _path_feed(recording: Recording, cfg: AlignConfig, feeds: pd.DataFrame, tq: np.ndarray) -> tuple[np.ndarray, str]:
    """Path feed at the query times: the recording's own feed stream (interpolated) or from positions."""
    stream = recording.streams.get(cfg.feed_stream)
    has = stream is not None and "feed_mm_min" in stream.columns and len(stream) >= 2
    if cfg.feed_source == "stream" and not has:
        raise AlignmentError(f"{recording.source or 'recording'}: feed_source='stream' but there is no "
                             f"{cfg.feed_stream!r} stream with feed_mm_min")
    if has and cfg.feed_source in ("auto", "stream"):
        ft = stream["t_ns"].to_numpy(dtype=np.int64)
        v = np.interp((tq - ft[0]).astype(np.float64), (ft - ft[0]).astype(np.float64),
                      stream["feed_mm_min"].to_numpy(dtype=np.float64))
        return v, f"stream:{cfg.feed_stream}"
    return feeds["feed_mm_min"].to_numpy(), "positions"


def _points_table(cl: pd.DataFrame, match, feeds: pd.DataFrame, path_feed: np.ndarray,
                  span: MotionSpan) -> pd.DataFrame:
    # built as one dict of columns: one DataFrame construction instead of a dozen insertions
    data: dict[str, Any] = {"point": np.arange(len(cl), dtype=np.int64)}
    for c in cl.columns:
        data["programmed_feed_mm_min" if c == "feed_mm_min" else c] = _column(cl, c)
    ok = match.matched
    tm = np.where(ok, match.t_ns, 0)
    data["t_ns"] = np.where(ok, match.t_ns, NO_TIME)
    data["t_rel_s"] = np.where(ok, (tm - span.t_start_ns) / 1e9, np.nan)
    data["dist_mm"] = match.dist_mm
    data["sample"] = match.nearest
    data["feed_meas_mm_min"] = np.where(ok, path_feed, np.nan)
    for c in feeds.columns:
        if c.startswith("v"):  # vx_mm_min -> vx_meas_mm_min
            axis, rest = c.split("_", 1)
            data[f"{axis}_meas_{rest}"] = np.where(ok, feeds[c].to_numpy(), np.nan)
    return pd.DataFrame(data, copy=False)


def _column(frame: pd.DataFrame, c: str) -> Any:
    """A writable copy of column `c` as an array: numpy for numpy dtypes, the extension array (category,
    string) otherwise (a copy: columns read from a copy-on-write frame are read-only views)."""
    col = frame[c]
    return col.to_numpy(copy=True) if isinstance(col.dtype, np.dtype) else col.array.copy()


def join_by_block(left: pd.DataFrame, right: pd.DataFrame, *, exclude: tuple[str, ...] = ()) -> pd.DataFrame:
    """`left.merge(right.drop(columns=exclude), on="block", how="left")` for the common case of a unique
    `block` key in `right` and no other shared column: the new columns gathered by position into one
    DataFrame built from arrays, without the merge machinery's fixed cost. Rows of `left` whose block
    `right` lacks (the CL start point) get NaN, as from the merge, when every new column is a float
    (or extension) column; anything else goes through `merge`."""
    cols = [c for c in right.columns if c != "block" and c not in exclude]
    keys = pd.Index(right["block"].to_numpy())
    if set(left.columns) & set(cols) or not keys.is_unique or not len(keys):
        return left.merge(right[["block", *cols]], on="block", how="left")
    pos = keys.get_indexer(left["block"].to_numpy())
    missing = pos < 0
    new = {c: right[c] for c in cols}
    if missing.any() and any(isinstance(v.dtype, np.dtype) and v.dtype.kind != "f" for v in new.values()):
        return left.merge(right[["block", *cols]], on="block", how="left")
    data = {c: _column(left, c) for c in left.columns}
    hole = missing.any()
    for c, col in new.items():
        if isinstance(col.dtype, np.dtype):
            v = col.to_numpy().take(pos if not hole else np.where(missing, 0, pos))  # a new array
            if hole:
                v[missing] = np.nan
        else:
            v = col.array.take(pos, allow_fill=True)
        data[c] = v
    return pd.DataFrame(data, copy=False)


def _last_rows(block: np.ndarray, wanted: np.ndarray) -> np.ndarray:
    """Index of the last row of `block` (per CL point) holding each of the `wanted` blocks, -1 if none."""
    rev = np.asarray(block)[::-1]
    keys, first_rev = np.unique(rev, return_index=True)
    last = len(rev) - 1 - first_rev
    at = np.clip(np.searchsorted(keys, wanted), 0, max(len(keys) - 1, 0))
    found = (keys[at] == wanted) if len(keys) else np.zeros(len(wanted), dtype=bool)
    return np.where(found, last[at] if len(keys) else -1, -1).astype(np.int64)


class _PointLabels:
    """ "block B (line L)" per CL point, formatted only for the few points an error message names."""

    def __init__(self, block: np.ndarray, line: np.ndarray) -> None:
        self.block, self.line = block, line

    def __len__(self) -> int:
        return len(self.block)

    def __getitem__(self, k: int) -> str:
        return f"block {self.block[k]} (line {self.line[k]})"


def _line_blocks(recording: Recording, cfg: AlignConfig, motion: pd.DataFrame, span: MotionSpan,
                 geo: pd.DataFrame, report: dict[str, Any]) -> pd.DataFrame | None:
    stream = recording.streams.get(cfg.line_stream)
    if stream is None or "line" not in stream.columns or len(stream) < 2:
        report["line_stream"] = None
        return None
    report["timing"][cfg.line_stream] = stream_timing(stream["t_ns"].to_numpy(), name=cfg.line_stream).as_dict()
    try:
        lb = blocks_from_lines(stream["t_ns"].to_numpy(), stream["line"].to_numpy(), motion, span=span)
    except FeedlogError as exc:
        report["warnings"].append(f"line stream unusable ({exc}); block times from geometry")
        report["line_stream"] = None
        return None
    seen = lb["seen"].to_numpy()
    inner = seen.copy()
    inner[0] = False  # the first block's start is motion start in both
    off = event_offset(geo["t_end_ns"].to_numpy()[inner], lb["t_end_ns"].to_numpy()[inner]) if inner.any() else None
    info: dict[str, Any] = {"offset_vs_geometry": None if off is None else off.as_dict(), "shifted_ns": 0}
    if cfg.sync_lines and off is not None and off.offset_ns != 0:
        shifted = shift_stream(stream, -off.offset_ns)
        lb = blocks_from_lines(shifted["t_ns"].to_numpy(), shifted["line"].to_numpy(), motion, span=span)
        info["shifted_ns"] = -off.offset_ns
    lb["source"] = "line"
    groups = geo["move"].to_numpy() if "move" in geo.columns else None  # merged moves compared as one
    shared = shares_next_run(motion)
    if groups is not None and shared.any():  # and the moves of one line (a canned cycle), timed as one run
        groups = np.cumsum(np.r_[True, (groups[1:] != groups[:-1]) & ~shared[:-1]]) - 1
    info["geometry_vs_line"] = compare_blocks(lb, geo, servo_period_s=_period_s(recording), groups=groups)
    report["line_stream"] = info
    return split_merged(lb, geo)


def _period_s(recording: Recording) -> float | None:
    v = recording.metadata.get("servo_period_ns")
    try:
        return float(v) / 1e9 if v else None
    except ValueError:
        return None
