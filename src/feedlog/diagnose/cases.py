"""A recording prepared for diagnosis: aligned once, with the measured quantities every level compares.

`prepare_case(source, profile)` reads a recording (or takes a `Recording`), parses its program (the
attached `program.ngc` or one given), aligns the two (`feedlog.align`) and keeps what the residuals
need: the measured cycle time and block ends (relative to motion start), the sampling period, the
commanded and feedback joint positions when the recording has them, and the line stream's offset
against the geometry. Everything a simulation is compared with is measured here, once.

Bad input is refused with one clear line (`DiagnoseError`): a recording without a program, without
motion, whose axes the profile's kinematics cannot have produced (a rotary axis moving under a
Cartesian profile, or the other way round).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from feedlog.align.attached import attached_program
from feedlog.align.blocks import NO_TIME
from feedlog.align.holds import find_holds, hold_free
from feedlog.diagnose.progress import block_end_progress, crossing_times, sample_progress
from feedlog.errors import AlignmentError, FeedlogError
from feedlog.profile import LINEAR_AXES, MachineProfile, path_acc_limit
from feedlog.recording import PROFILE_ATTACHMENT, Recording
from feedlog.toolpath.schema import AXIS_UNITS

ROTARY_COLUMNS = {"a": "a_deg", "b": "b_deg", "c": "c_deg"}
MOVE_MM = 1e-3  # an axis that moves less than this (mm or deg) over a recording does not move
SPARSE_S = 0.005  # sampling periods above this are monitoring data (5 Hz), not a servo trace
WIDE_TOL_MM = 1.0  # alignment tolerance for a path that leaves the program's corners (smoothing controllers)
MIN_SIGMA_S = 1e-3  # sparse timing resolution at least this: the simulation's own time step (one servo period)


class DiagnoseError(FeedlogError):
    """Input that cannot be diagnosed: names the recording and what is wrong with it."""


@dataclass
class FeedbackData:
    """Commanded and feedback positions of the machine joints on a regular grid."""

    t_ns: np.ndarray
    cmd: np.ndarray       # (n, k)
    fb: np.ndarray        # (n, k)
    axes: tuple[str, ...]  # the profile axis each joint column belongs to
    dt_s: float

    @property
    def linear(self) -> list[int]:
        return [i for i, a in enumerate(self.axes) if a in LINEAR_AXES]


@dataclass
class GeometryData:
    """Axis (program frame) positions and the commanded joint positions they became, sample by sample."""

    t_ns: np.ndarray
    pos: np.ndarray        # (n, k) axis positions, columns in the profile's axis order
    joints: np.ndarray     # (n, k) commanded joint positions of the same instants
    lag: int               # samples the joints were recorded behind the axes (found from the rotary joints)


@dataclass
class CLPolyline:
    """The program's cutter-location points: program and machine frame, arc length, block, measured time."""

    xyz: np.ndarray            # (m, 3) program frame (what the simulation moves in)
    machine_xyz: np.ndarray    # (m, 3) with the work offsets (what the recording shows)
    s: np.ndarray              # (m,) arc length along the program
    block: np.ndarray          # (m,) block of each point
    t: np.ndarray              # (m,) when the recording passed it, from motion start (interpolated where unmatched)


def cl_polyline(points: pd.DataFrame, t0_ns: int) -> CLPolyline:
    xyz = points[["x_mm", "y_mm", "z_mm"]].to_numpy(np.float64)
    off = (points[["wx_mm", "wy_mm", "wz_mm"]].to_numpy(np.float64) if {"wx_mm", "wy_mm", "wz_mm"} <= set(points.columns)
           else np.zeros_like(xyz))
    s = points["s_mm"].to_numpy(np.float64)
    t_ns = points["t_ns"].to_numpy(np.int64)
    ok = (t_ns != NO_TIME) & np.isfinite(xyz).all(axis=1)
    t = (t_ns - t0_ns) / 1e9
    t = np.interp(s, s[ok], t[ok]) if ok.any() else np.zeros(len(s))
    good = np.isfinite(xyz).all(axis=1)
    return CLPolyline(xyz=xyz[good], machine_xyz=(xyz + np.nan_to_num(off))[good], s=s[good],
                      block=points["block"].to_numpy(np.int64)[good], t=np.maximum.accumulate(t[good]))


@dataclass
class Case:
    """One recording with its program, aligned, and what was measured."""

    name: str
    source: str
    recording: Recording
    program: Any                     # feedlog.toolpath.Program
    alignment: Any                   # feedlog.align.Alignment
    period_s: float                  # sampling period of the positions (median)
    t0_ns: int                       # motion start
    cycle_s: float                   # measured cycle time
    block_end_s: pd.Series           # block -> measured end time relative to motion start
    block_source: str                # 'line', 'geometry', ... (where the block times came from)
    feedback: FeedbackData | None = None
    geometry: GeometryData | None = None
    line_offset_s: float | None = None   # line stream minus geometry, from align (None: no line stream)
    line_offsets: pd.Series | None = None  # per block: line stream's block end minus the geometry's (s)
    machine: dict[str, str] = field(default_factory=dict)
    still_mm: float = 1e-6               # align's rest threshold (noise at rest), for the motion span
    on_path_mm: float = 1e-6             # align's threshold for leaving a line into a blend
    sample_offsets_s: np.ndarray | None = None  # position sample times from motion start (sparse data)
    cl: CLPolyline | None = None         # the program's CL points with their measured times (sparse data)
    notes: list[str] = field(default_factory=list)
    _arrays: Any = field(default=None, repr=False)
    span_acc_mm_s2: float = float("inf")  # acceleration align assumed leaving / reaching rest
    sparse_sigma_s: float | None = None  # sparse data: timing resolution of a mirrored block end (`sampled_sigma`)
    span_samples: tuple[tuple[float, float] | None, tuple[float, float] | None] | None = None
                                         # sparse data: (time from motion start, distance from where the
                                         # motion began / ends) of the first and last moving sample (`moving_samples`)
    holds: pd.DataFrame | None = None    # still stretches inside the motion (`align.holds.find_holds`)
    removed_s: list[tuple[float, float]] = field(default_factory=list)
                                         # feed holds taken out of the comparison: (start, end) s from motion
                                         # start on the recording's clock; cycle_s and block_end_s are without them

    @property
    def sparse(self) -> bool:
        return self.period_s > SPARSE_S

    def compared_s(self, t_s: np.ndarray) -> np.ndarray:
        """Recorded times (s from motion start) on the comparison's clock: the feed holds taken out."""
        return hold_free(t_s, self.removed_s) if self.removed_s else np.asarray(t_s, dtype=np.float64)

    def in_hold(self, t_s: np.ndarray) -> np.ndarray:
        """Recorded times (s from motion start) after a feed hold's start up to its end: samples of the hold."""
        t = np.asarray(t_s, dtype=np.float64)
        out = np.zeros(t.shape, dtype=bool)
        for a, b in self.removed_s:
            out |= (t > a) & (t <= b)
        return out

    @property
    def sim_input(self) -> Any:
        """The program as the simulation reads it, prepared once for the many re-simulations of a fit."""
        if self._arrays is None:
            from feedlog.sim.path import ProgramArrays

            self._arrays = ProgramArrays(self.program)
        return self._arrays

    @property
    def boundary_sigma_s(self) -> float:
        """Timing resolution of one measured block boundary: a uniform error over one sampling period."""
        return self.period_s / np.sqrt(12.0)

    @property
    def segment_sigma_s(self) -> float:
        """Timing resolution of one segment boundary as the timing level compares it. Dense data: the
        boundary's own (`boundary_sigma_s`). Sparse data: the simulation is sampled at the recording's own
        instants and its block ends found from those samples as the recording's were
        (`residuals.mirrored_ends`), so the sampling period cancels; what does not is the timestamps'
        jitter and the position noise over the speed (`sparse_sigma_s`)."""
        if self.sparse and self.sparse_sigma_s is not None:
            return self.sparse_sigma_s
        return self.boundary_sigma_s


def _program(rec: Recording, program: Any, lenient: bool):
    """The given program, or the one the recording carries (align's rule)."""
    try:
        return attached_program(rec, program, lenient)
    except AlignmentError as exc:
        raise DiagnoseError(str(exc)) from None


def _check_axes(rec: Recording, profile: MachineProfile, name: str) -> pd.DataFrame:
    if "axes" not in rec.streams:
        raise DiagnoseError(f"{name}: the recording has no 'axes' stream (positions); "
                            f"it has: {', '.join(rec.streams) or 'nothing'}")
    axes = rec.streams["axes"]
    if len(axes) < 3:
        raise DiagnoseError(f"{name}: the recording has {len(axes)} position sample(s); nothing to diagnose")
    for axis, col in ROTARY_COLUMNS.items():
        if col in axes.columns and axis not in profile.axes:
            values = axes[col].to_numpy(np.float64)
            if np.isfinite(values).any() and np.nanmax(values) - np.nanmin(values) > MOVE_MM:
                raise DiagnoseError(f"{name}: the recording moves the {axis.upper()} axis, which machine profile "
                                    f"{profile.name!r} ({profile.kinematics.type}) does not have; give the profile "
                                    "of the machine that recorded it")
    missing = [a for a in profile.kinematics.rotary_axes if ROTARY_COLUMNS[a] not in axes.columns]
    if missing:
        raise DiagnoseError(f"{name}: profile {profile.name!r} is a {profile.kinematics.type} machine but the "
                            f"recording has no {', '.join(m.upper() for m in missing)} positions; give the profile "
                            "of the machine that recorded it")
    lin = [c for c in ("x_mm", "y_mm", "z_mm") if c in axes.columns]
    if len(lin) < 3:
        raise DiagnoseError(f"{name}: stream 'axes' lacks {', '.join(sorted({'x_mm', 'y_mm', 'z_mm'} - set(lin)))}")
    pos = axes[lin + [ROTARY_COLUMNS[a] for a in profile.kinematics.rotary_axes]].to_numpy(np.float64)
    finite = np.isfinite(pos).all(axis=1)
    if not finite.any() or (np.nanmax(pos[finite], axis=0) - np.nanmin(pos[finite], axis=0)).max() <= MOVE_MM:
        raise DiagnoseError(f"{name}: the recording shows no motion (every axis stays within {MOVE_MM} mm/deg)")
    return axes


def feedback_data(rec: Recording, profile: MachineProfile) -> FeedbackData | None:
    """Joint command and feedback pairs (`jN_pos`, `jN_pos_fb`) of a regularly sampled recording."""
    joints = rec.streams.get("joints")
    if joints is None:
        return None
    axes = profile.axis_names
    pairs = [i for i in range(len(axes)) if f"j{i}_pos" in joints.columns and f"j{i}_pos_fb" in joints.columns]
    if not pairs or len(joints) < 10:
        return None
    t = joints["t_ns"].to_numpy(np.int64)
    step = np.diff(t)
    dt = float(np.median(step))
    if dt <= 0 or np.abs(step - dt).max() > 0.01 * dt:  # a servo trace has a regular grid; anything else is not one
        return None
    cmd = joints[[f"j{i}_pos" for i in pairs]].to_numpy(np.float64)
    fb = joints[[f"j{i}_pos_fb" for i in pairs]].to_numpy(np.float64)
    if not (np.isfinite(cmd).all() and np.isfinite(fb).all()):
        return None
    return FeedbackData(t_ns=t, cmd=cmd, fb=fb, axes=tuple(axes[i] for i in pairs), dt_s=dt / 1e9)


GEOMETRY_LAGS = 5  # the joints may be sampled up to this many samples behind (or ahead of) the axes


def geometry_data(rec: Recording, profile: MachineProfile) -> GeometryData | None:
    """Axis positions and commanded joints (`jN_pos`) sampled together, for a machine whose kinematics
    are not the identity. Where the joints were recorded some samples behind the axes (LinuxCNC's
    `joint.N.pos-cmd` two servo cycles after `axis.L.pos-cmd`), the lag is taken from the rotary
    joints, which equal their axes whatever the offsets."""
    joints, axes = rec.streams.get("joints"), rec.streams.get("axes")
    rotary = [profile.axis_names.index(a) for a in profile.kinematics.rotary_axes]
    if joints is None or axes is None or not rotary:
        return None
    names = profile.axis_names
    cols = [f"j{i}_pos" for i in range(len(names))]
    if not set(cols) <= set(joints.columns):
        return None
    both = axes[["t_ns", *position_columns(profile)]].merge(joints[["t_ns", *cols]], on="t_ns")
    if len(both) < 10 * GEOMETRY_LAGS:
        return None
    pos = both[position_columns(profile)].to_numpy(np.float64)
    q = both[cols].to_numpy(np.float64)
    if not (np.isfinite(pos).all() and np.isfinite(q).all()):
        return None
    n, k = len(both), GEOMETRY_LAGS

    def mismatch(lag: int) -> float:
        a, b = pos[k:n - k, rotary], q[k + lag:n - k + lag, rotary]
        return float(np.abs(a - b).sum())

    lag = min(range(-k, k + 1), key=lambda j: (mismatch(j), abs(j)))
    t = both["t_ns"].to_numpy(np.int64)
    return GeometryData(t_ns=t[k:n - k], pos=pos[k:n - k], joints=q[k + lag:n - k + lag], lag=lag)


def line_offsets(alignment: Any) -> pd.Series | None:
    """Per block seen in the line stream (not the first or last): when the line stream says it ended minus
    when the positions say so (align's line and geometry block tables)."""
    lb, geo = alignment.line_blocks, alignment.geometry_blocks
    if lb is None or geo is None or len(lb) < 4:
        return None
    seen = lb[lb["seen"]] if "seen" in lb.columns else lb
    both = seen[["block", "t_end_ns"]].merge(geo[["block", "t_end_ns"]], on="block", suffixes=("_line", "_geo"))
    both = both.iloc[1:-1]
    if len(both) < 2:
        return None
    return pd.Series((both["t_end_ns_line"] - both["t_end_ns_geo"]).to_numpy(np.float64) / 1e9,
                     index=both["block"].to_numpy(np.int64))


def machine_identity(rec: Recording) -> dict[str, str]:
    """What names the machine a recording came from (compared across the recordings of one diagnosis)."""
    out = {k: rec.metadata[k] for k in ("machine", "controller", "ini", "servo_period_ns") if rec.metadata.get(k)}
    ini = rec.attachments.get("machine.ini")
    if ini is not None:
        import hashlib

        out["machine.ini"] = hashlib.sha256(ini).hexdigest()[:16]
    return out


def attached_profile(rec: Recording, name: str) -> MachineProfile | None:
    data = rec.attachments.get(PROFILE_ATTACHMENT)
    if data is None:
        return None
    return MachineProfile.from_toml(data.decode("utf-8", errors="replace"), source=f"{name}:{PROFILE_ATTACHMENT}")


def prepare_case(source: str | Path | Recording, profile: MachineProfile, *, program: Any = None,
                 lenient: bool = False, align_overrides: dict[str, Any] | None = None) -> Case:
    """Read, check and align one recording for diagnosis on `profile`."""
    from feedlog.align import align_recording
    from feedlog.ingest import read_recording

    rec = source if isinstance(source, Recording) else read_recording(source)
    src = rec.source or (str(source) if not isinstance(source, Recording) else "recording")
    name = Path(src).stem or "recording"
    axes = _check_axes(rec, profile, name)
    prog = _program(rec, program, lenient)
    notes: list[str] = []
    try:
        alignment = align_recording(rec, prog, profile=profile, **(align_overrides or {}))
    except AlignmentError as exc:
        # a machine that smooths its corners leaves the programmed path by more than G64 P: align it with a
        # wider tolerance, and say so (the evidence shows how far the path left the corners)
        if "farther than their tolerance" not in str(exc):
            raise DiagnoseError(f"{name}: cannot align the recording with its program: {exc}") from None
        try:
            alignment = align_recording(rec, prog, profile=profile, **{**(align_overrides or {}), "tol_mm": WIDE_TOL_MM})
        except FeedlogError as again:
            raise DiagnoseError(f"{name}: cannot align the recording with its program: {again}") from None
        notes.append(f"the path leaves the program by more than its tolerance ({str(exc).split('; worst: ')[-1][:120]}); "
                     f"aligned with {WIDE_TOL_MM} mm")
    except FeedlogError as exc:
        raise DiagnoseError(f"{name}: cannot align the recording with its program: {exc}") from None
    if alignment.report.get("lines"):  # part of the program: the simulation runs that part, as the machine did
        alignment, prog, note = partial_case(alignment, prog)
        notes.append(note)
    t = axes["t_ns"].to_numpy(np.int64)
    period = float(np.median(np.diff(t))) / 1e9
    t0 = int(alignment.report["motion"]["t_start_ns"])
    blocks = alignment.blocks
    ends = pd.Series((blocks["t_end_ns"].to_numpy(np.int64) - t0) / 1e9, index=blocks["block"].to_numpy(np.int64))
    source_kind = str(blocks["source"].iloc[0]) if "source" in blocks.columns and len(blocks) else "geometry"
    cl = None
    if period > SPARSE_S:
        # sparse data: when the tool's progress along the program reached each block's end, interpolated
        # between samples, is closer to the truth than the first sample showing the next line
        cl = cl_polyline(alignment.points, t0)
        pos = axes[["x_mm", "y_mm", "z_mm"]].to_numpy(np.float64)
        rel = (t - t0) / 1e9
        s = sample_progress(rel, pos, cl.machine_xyz, cl.s, cl.t)
        ids = blocks["block"].to_numpy(np.int64)
        target = block_end_progress(cl.block, cl.s, ids)
        ends = pd.Series(np.where(np.isfinite(target), crossing_times(rel, s, np.nan_to_num(target)), np.nan), index=ids)
        source_kind = "progress"
    line_info = alignment.report.get("line_stream") or {}
    offset = (line_info.get("offset_vs_geometry") or {}).get("offset_ns")
    cycle = float(alignment.cycle_time_s)
    still = float(alignment.report.get("still_mm", 1e-3))
    holds = find_holds(axes, blocks, prog, span_ns=(t0, t0 + int(round(cycle * 1e9))), still_mm=still)
    removed: list[tuple[float, float]] = []
    timed = axes   # the samples on the comparison's clock (sparse data: the progress timing samples them)
    if holds["removed"].any():
        # feed holds: out of the motion comparison (block ends, cycle and, on sparse data, the sampling
        # instants the simulation is sampled at: a sample inside a hold takes the hold's start)
        removed = [((h["t_start_ns"] - t0) / 1e9, (h["t_end_ns"] - t0) / 1e9)
                   for h in holds[holds["removed"]].to_dict("records")]
        ends = pd.Series(hold_free(ends.to_numpy(np.float64), removed), index=ends.index)
        cycle = float(hold_free(cycle, removed))
        timed = axes.assign(t_ns=t0 + np.rint(hold_free((t - t0) / 1e9, removed) * 1e9).astype(np.int64))
        notes.append("feed hold(s) taken out of the comparison: " + "; ".join(
            f"{h['duration_s']:.2f} s at line {h['line']} ({(h['t_start_ns'] - t0) / 1e9:.2f} s into the motion)"
            for h in holds[holds["removed"]].to_dict("records")))
    else:
        holds = holds.assign(removed=False)
    return Case(name=name, source=src, recording=rec, program=prog, alignment=alignment, period_s=period, t0_ns=t0,
                cycle_s=cycle, block_end_s=ends, holds=holds, removed_s=removed, block_source=source_kind,
                feedback=feedback_data(rec, profile), geometry=geometry_data(rec, profile), line_offset_s=None if offset is None else offset / 1e9,
                line_offsets=line_offsets(alignment),
                machine=machine_identity(rec), still_mm=float(alignment.report.get("still_mm", 1e-6)),
                on_path_mm=_on_path(alignment, axes),
                sample_offsets_s=(timed["t_ns"].to_numpy(np.int64) - t0) / 1e9 if period > SPARSE_S else None,
                cl=cl, notes=notes,
                span_acc_mm_s2=span_acceleration(profile),
                sparse_sigma_s=sampled_sigma(axes, t0, float(alignment.cycle_time_s),
                                             float(alignment.report.get("still_mm", 1e-3))) if cl is not None else None,
                span_samples=None if cl is None else moving_samples(timed, t0, cycle,
                                                                    cl.machine_xyz[0], cl.machine_xyz[-1]))


def sampled_sigma(axes: pd.DataFrame, t0_ns: int, cycle_s: float, still_mm: float) -> float:
    """How well a sparse recording times the tool passing a point, once the sampling instants are shared
    with the simulation: the timestamps' jitter (robust spread of the sampling intervals) and the
    position noise (align's still threshold) over the median moving speed; at least `MIN_SIGMA_S`."""
    t = axes["t_ns"].to_numpy(np.int64)
    dt = np.diff(t) / 1e9
    if len(dt) < 2:
        return MIN_SIGMA_S
    jitter = 1.4826 * float(np.median(np.abs(dt - np.median(dt)))) / np.sqrt(2.0)
    pos = axes[[c for c in ("x_mm", "y_mm", "z_mm") if c in axes.columns]].to_numpy(np.float64)
    rel = (t[1:] - t0_ns) / 1e9
    step = np.linalg.norm(np.diff(pos, axis=0), axis=1)
    moving = (rel > 0) & (rel <= cycle_s) & (dt > 0) & np.isfinite(step) & (step > still_mm)
    speed = float(np.median(step[moving] / dt[moving])) if moving.any() else 0.0
    noise = still_mm / speed if speed > 0 else 0.0
    return max(float(np.hypot(jitter, noise)), MIN_SIGMA_S)


def moving_samples(axes: pd.DataFrame, t0_ns: int, cycle_s: float, start_xyz: np.ndarray | None = None,
                   end_xyz: np.ndarray | None = None):
    """The first and the last sample that show the tool moving, each as (time from motion start, distance
    from where the motion began / ends): on sparse data the facts about motion start and end no model
    placed. The distance is from the sample at rest before / after it; where the recording has none (it
    began or ended in motion, or a logger stopped with the program) from the program's first / last
    point in the machine frame (`start_xyz`, `end_xyz`); None where neither is known."""
    rel = (axes["t_ns"].to_numpy(np.int64) - t0_ns) / 1e9
    pos = axes[[c for c in ("x_mm", "y_mm", "z_mm") if c in axes.columns]].to_numpy(np.float64)
    first = int(np.searchsorted(rel, 0.0, side="right"))        # first sample after motion start
    last = int(np.searchsorted(rel, cycle_s, side="left")) - 1  # last sample before motion end
    if not first <= last:
        return None

    def away(i: int, rest: int, point: np.ndarray | None) -> float | None:
        if 0 <= rest < len(rel) and (rel[rest] < 0 if rest < i else rel[rest] > cycle_s):
            ref = pos[rest]                                        # a sample at rest on that side
        elif point is not None and len(point) == pos.shape[1] and np.isfinite(point).all():
            ref = point
        else:
            return None
        d = float(np.linalg.norm(pos[i] - ref))
        return d if np.isfinite(d) else None

    d0, d1 = away(first, first - 1, start_xyz), away(last, last + 1, end_xyz)
    start = (float(rel[first]), d0) if d0 is not None and d0 > 0 else None
    end = (float(rel[last]), d1) if d1 is not None and d1 > 0 else None
    return start, end


def partial_case(alignment: Any, prog: Any) -> tuple[Any, Any, str]:
    """A recording of some program lines: the program cut to them. Lines found from the line stream start
    with one that may have been under way when the recording began (align leaves it unchecked): the case
    then starts where that line ends, in the recording and in the program."""
    from dataclasses import replace

    from feedlog.align.partial import slice_program

    lines = alignment.report["lines"]
    first, last = int(lines["first"]), int(lines["last"])
    blocks = alignment.blocks
    under = blocks["line"].to_numpy() == first
    note = f"the recording covers program lines {first}:{last} (from the {lines['from']}): only those are simulated"
    cut = int(blocks.loc[under, "t_end_ns"].max()) if under.any() else NO_TIME
    motion = alignment.report["motion"]
    if lines["from"] == "config" or under.all() or cut == NO_TIME or not motion["t_start_ns"] < cut < motion["t_end_ns"]:
        return alignment, slice_program(prog, (first, last)), note
    report = {**alignment.report, "motion": {**motion, "t_start_ns": cut,
                                             "cycle_time_s": (motion["t_end_ns"] - cut) / 1e9}}
    trimmed = replace(alignment, blocks=blocks[~under].reset_index(drop=True),
                      points=alignment.points[alignment.points["line"].to_numpy() > first].reset_index(drop=True),
                      cycle_time_s=(motion["t_end_ns"] - cut) / 1e9, report=report)
    note += f"; line {first} was under way when it began, so the comparison starts where it ends"
    return trimmed, slice_program(prog, (first + 1, last)), note


def _on_path(alignment: Any, axes: pd.DataFrame) -> float:
    """The distance from a line at which align saw the tool leave it (as align_recording computes it)."""
    from feedlog.align.pipeline import position_quantum

    cfg = alignment.report.get("config", {})
    pos = axes[[c for c in ("x_mm", "y_mm", "z_mm") if c in axes.columns]].to_numpy(np.float64)
    return max(float(cfg.get("on_path_mm", 1e-6)), 2 * position_quantum(pos), float(alignment.report.get("still_mm", 1e-6)))


def span_acceleration(profile: MachineProfile) -> float:
    """The acceleration align assumes when it places motion start and end between rest samples."""
    return path_acc_limit(profile)


def check_same_machine(cases: list[Case]) -> None:
    """Recordings of one diagnosis must come from one machine."""
    if len(cases) < 2:
        return
    first = cases[0]
    for case in cases[1:]:
        for key in ("machine.ini", "servo_period_ns", "machine"):
            a, b = first.machine.get(key), case.machine.get(key)
            if a is not None and b is not None and a != b:
                what = "machine INI" if key == "machine.ini" else key
                raise DiagnoseError(f"{case.name}: recorded on another machine than {first.name} ({what} "
                                    f"{b!r} vs {a!r}); diagnose recordings of one machine together")


def position_columns(profile: MachineProfile) -> list[str]:
    return [f"{a}_{AXIS_UNITS[a]}" for a in profile.axis_names]
