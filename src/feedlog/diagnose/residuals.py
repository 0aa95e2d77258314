"""Residuals of a simulation against a prepared recording, at the levels the identification fits.

**Timing.** The program is cut into *segments*: runs of consecutive blocks ending at an *anchor*
block (one both the recording and the simulation time; a group the simulation merges into one move
is anchored on its last block) and lasting at least `min_segment_s` measured (five sampling periods,
at least 20 ms: at 5 Hz a segment spans a second, so its measured duration is good to a few
percent; at 1 kHz most blocks are segments of their own). The last segment ends at motion end. The
residual of a segment is its simulated minus its measured duration, in seconds; they add up to the
cycle-time residual. Segments are fixed once per recording (from the measured blocks and the given
profile's simulation), so every hypothesis is judged on the same pieces. The simulation is measured
as the recording was: its motion span by align's rest rule (`sim_span`), and on sparse data its block
ends where a logger sampling at the recording's instants would have seen the tool pass them
(`mirrored_ends`). There motion start and end were placed inside their sampling interval by a model
of the diagnosed profile, so the first segment starts, on both sides, where the first moving sample
shows the tool (the simulation: when it is as far from its start), and the last ends at the last
moving sample likewise (`moving_samples`, `sample_bounds`): no model's placement is judged, and a slow
approach or retract rapid (often a large share of a monitored cycle) is seen. For the same reason the
simulation is sampled at the recording's instants phased on the first moving sample.

**Feedback.** The recording's own commanded joint positions through the profile's feedback
mechanisms (`feedlog.sim.feedback`) against its feedback positions: the feedback model is judged
independently of the timing.

**Geometry.** The recording's own axis (program frame) positions through the profile's kinematics
against the commanded joint positions it recorded: the machine's geometry (a trunnion's offsets),
judged without any simulation.

**Line.** Per block, when the line stream says it ended minus when the positions say so, against
the same offset of the simulation recorded and aligned alike plus the profile's logger latency.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from feedlog.diagnose.cases import Case
from feedlog.diagnose.progress import block_end_progress, crossing_times, sample_progress
from feedlog.errors import FeedlogError
from feedlog.profile import MachineProfile

MIN_SEGMENT_PERIODS = 5
MIN_SEGMENT_S = 0.02


@dataclass(frozen=True)
class Segments:
    """The timing segments of one recording: anchor block at each segment's end (-1: motion end)."""

    anchors: np.ndarray      # (m,) block ids; the last is -1 (motion end)
    measured_s: np.ndarray   # (m,) measured durations
    end_s: np.ndarray        # (m,) measured time at each segment's end, from motion start
    weight: np.ndarray       # (m,) 1 where a segment counts in the loss, 0 where it does not (sparse data's
                             # model-placed first and last; a segment holding a feed hold)

    def __len__(self) -> int:
        return len(self.anchors)


def sim_span(case: Case, sim) -> tuple[float, float]:
    """Motion start and end of a simulation as the recording's motion span was found: on dense data
    align detects motion where the positions leave `still_mm` of their rest (the noise at rest), and
    corrects by the time to cover it accelerating from rest; the same rule on the simulated positions
    cancels what it does not model (the final move of a program decelerating at half acceleration).
    Sparse data had its span placed by the model itself: the simulation's own start and end."""
    traj = sim.trajectory
    if case.sparse or case.still_mm <= 1e-6:
        return traj.motion_start_s, traj.motion_end_s
    from feedlog.align.blocks import motion_span

    ends = _span_from_ends(case, traj)
    if ends is not None:
        return ends
    t, pos = traj.t_s, traj.pos
    try:
        span = motion_span(np.rint(t * 1e9).astype(np.int64), pos, still_mm=case.still_mm,
                           acc_mm_s2=case.span_acc_mm_s2)
    except FeedlogError:
        return traj.motion_start_s, traj.motion_end_s
    return span.t_start_ns / 1e9, span.t_end_ns / 1e9


SPAN_MARGIN_S = 0.1   # samples kept past the planned motion start (before its end) for `_span_from_ends`


def _span_from_ends(case: Case, traj) -> tuple[float, float] | None:
    """`sim_span` from the head and the tail of the sampled motion only, where the trajectory can sample
    single grid rows (`Trajectory.sample_at`): the rule of `motion_span` reads the leading and trailing
    rest and the first and last sample away from them, so on the grid with the middle left out it finds
    the same times, checked here (each rest run, and the samples the rule reads around the first and
    last motion, lie inside their part); None when they do not (then the whole grid is sampled)."""
    from feedlog.align.blocks import motion_span

    grid = traj.grid
    if grid is None:
        return None
    n, dt = grid
    margin = int(np.ceil(SPAN_MARGIN_S / dt))
    head = min(n, int(traj.motion_start_s / dt) + margin)
    tail = max(head, int(traj.motion_end_s / dt) - margin)
    if n < 2 or tail - head < 4:  # little to leave out: the whole grid
        return None
    t, pos = traj.sample_at(np.r_[np.arange(head), np.arange(tail, n)])
    still = case.still_mm
    for part in (pos[:head], pos[head:][::-1]):  # each rest run ends inside its part
        if not (np.abs(part - part[0]).max(axis=1) > 2 * still).any():
            return None
    try:
        span = motion_span(np.rint(t * 1e9).astype(np.int64), pos, still_mm=still, acc_mm_s2=case.span_acc_mm_s2)
    except FeedlogError:
        return None
    # the rule reads samples first_index .. first_index + 2 and last_index - 2 .. last_index
    if span.first_index + 2 >= head or span.last_index - 2 < head:
        return None
    return span.t_start_ns / 1e9, span.t_end_ns / 1e9


def sim_block_ends(case: Case, sim) -> tuple[np.ndarray, np.ndarray, float]:
    """(block ids ascending, their end times from motion start, cycle time) of a SimResult, its motion
    span taken as the recording's was (`sim_span`)."""
    start, end = sim_span(case, sim)
    arrays = getattr(sim, "block_arrays", None)  # a SimResult's table as arrays: no DataFrame per re-simulation
    if arrays is not None:
        ids, ends = arrays[0].astype(np.int64, copy=False), arrays[3].astype(np.int64, copy=False) / 1e9 - start
    else:
        ids, ends = sim.blocks["block"].to_numpy(np.int64), sim.blocks["t_end_ns"].to_numpy(np.int64) / 1e9 - start
    order = np.argsort(ids, kind="stable")
    return ids[order], np.clip(np.maximum.accumulate(ends[order]), 0.0, end - start), end - start


def make_segments(case: Case, sim, *, min_segment_s: float | None = None) -> Segments:
    """Segments of `case` from its measured block ends and the anchors `sim` (the given profile) runs."""
    floor = min_segment_s if min_segment_s is not None else max(MIN_SEGMENT_PERIODS * case.period_s, MIN_SEGMENT_S)
    ids = np.unique(sim.blocks["block"].to_numpy(np.int64))
    measured = case.block_end_s
    common = np.intersect1d(ids, measured.index.to_numpy(np.int64))
    ends = measured.reindex(common).to_numpy(np.float64)
    ok = np.isfinite(ends) & (ends > 0) & (ends < case.cycle_s)
    common, ends = common[ok], np.maximum.accumulate(ends[ok]) if ok.any() else ends[ok]
    anchors, times, last = [], [], 0.0
    for block, t in zip(common, ends):
        if t - last >= floor and case.cycle_s - t >= floor:  # the last segment must keep its length too
            anchors.append(int(block))
            times.append(float(t))
            last = float(t)
    anchors.append(-1)
    times.append(case.cycle_s)
    end = np.asarray(times)
    weight = np.ones(len(end))
    measured_s = np.diff(end, prepend=0.0)
    for a, _ in case.removed_s:
        # a feed hold is out of the measured time; the slowing down into it and the start after it (motion
        # the program does not ask for) are not: the segment holding it carries no weight
        at = case.compared_s(np.array([a]))[0]
        weight[min(int(np.searchsorted(end, at, side="left")), len(end) - 1)] = 0.0
    if case.sparse and len(end) > 2:
        # motion start and end were placed inside their sampling interval by a model of the profile under
        # diagnosis: the first segment starts at the first moving sample and the last ends at the last one
        # (the simulation is cut alike: simulated_segments); where that sample's distance is not known
        # (no sample at rest, no program point) the segment would judge that model, and carries no weight
        start, stop = case.span_samples or (None, None)
        if start is None:
            weight[0] = 0.0
        else:
            measured_s[0] = end[0] - start[0]
        if stop is None:
            weight[-1] = 0.0
        else:
            measured_s[-1] = stop[0] - end[-2]
    return Segments(anchors=np.asarray(anchors, dtype=np.int64), measured_s=measured_s, end_s=end,
                    weight=weight)


def simulated_segments(case: Case, segments: Segments, sim) -> np.ndarray:
    """Simulated duration of each segment. An anchor the simulation did not run (another profile may
    merge differently) takes the end of the last block before it that ran. On sparse data the anchors'
    times are taken as the recording's were (`mirrored_ends`)."""
    ids, ends, cycle = sim_block_ends(case, sim)
    anchors = segments.anchors[:-1]
    at = np.searchsorted(ids, anchors, side="right") - 1
    t = np.where(at >= 0, ends[np.clip(at, 0, None)], 0.0) if len(ids) else np.zeros(len(anchors))
    bounds = sample_bounds(case, sim) if case.sparse and case.span_samples is not None else None
    if case.sparse and case.sample_offsets_s is not None and len(anchors):
        t = mirrored_ends(case, sim, anchors, t, bounds)
    t = np.minimum(np.append(t, cycle), cycle)
    out = np.diff(np.maximum.accumulate(t), prepend=0.0)
    if bounds is not None and len(out) > 2:
        out[0] -= bounds[0]
        out[-1] -= cycle - bounds[1]
    return out


def sample_bounds(case: Case, sim) -> tuple[float, float]:
    """When the simulated tool is as far from its start as the recording's first moving sample was from
    where motion began, and last as far from its end as the last moving sample was from where it ended
    (s from motion start; motion start and end where the recording has no such sample)."""
    traj = sim.trajectory
    start, end = sim_span(case, sim)
    pos = traj.pos[:, :min(3, traj.pos.shape[1])]
    first, last = case.span_samples
    t_first, t_last = start, end
    if first is not None:
        away = np.linalg.norm(pos - pos[0], axis=1)
        i = int(np.argmax(away >= first[1])) if (away >= first[1]).any() else len(pos) - 1
        t_first = float(np.interp(first[1], [away[i - 1], away[i]], traj.t_s[i - 1:i + 1])) \
            if i > 0 and away[i] > away[i - 1] else float(traj.t_s[i])
    if last is not None:
        left = np.linalg.norm(pos - pos[-1], axis=1)
        j = int(len(pos) - 1 - np.argmax(left[::-1] >= last[1])) if (left >= last[1]).any() else 0
        k = min(j + 1, len(pos) - 1)
        t_last = float(np.interp(-last[1], [-left[j], -left[k]], [traj.t_s[j], traj.t_s[k]])) \
            if left[j] > left[k] else float(traj.t_s[j])
    return t_first - start, t_last - start


def mirrored_ends(case: Case, sim, anchors: np.ndarray, approx: np.ndarray,
                  bounds: tuple[float, float] | None = None) -> np.ndarray:
    """When a sparse logger would have seen the simulated tool reach each anchor block's end.

    The simulation is sampled at the recording's own instants (from motion start), each sample's
    progress along the program found as the recording's was (`progress.sample_progress`) and the
    anchors' times interpolated between samples alike: what the samples do not show (a corner's
    slow-down between two of them) is missed by both. `approx` are the simulation's exact end times;
    `bounds` its `sample_bounds` when the caller has them."""
    traj = sim.trajectory
    start, _ = sim_span(case, sim)
    # the recording's instants, phased on its first moving sample (when the simulation is as far from
    # its start): align placed motion start inside a sampling interval with a model of the profile under
    # diagnosis, and a phase off by that model would move every interpolated block end
    grid = case.sample_offsets_s
    first = case.span_samples[0] if case.span_samples is not None else None
    if first is not None:
        grid = grid + ((bounds or sample_bounds(case, sim))[0] - first[0])
    lin = list(range(min(3, traj.pos.shape[1])))
    q = np.column_stack([np.interp(grid + start, traj.t_s, traj.pos[:, i]) for i in lin])
    cl = case.cl
    target = block_end_progress(cl.block, cl.s, anchors)
    ok = np.isfinite(target) & np.isfinite(approx)
    if ok.sum() < 1:
        return approx
    # when the simulation passed each CL point, roughly: every simulated block's end (not the anchors
    # alone: a prior that is off by a fraction of a block sends the search to the wrong CL points),
    # linearly in arc length between them, and the program's end at motion end
    ids, ends, cycle = sim_block_ends(case, sim)
    s_end = block_end_progress(cl.block, cl.s, ids)
    known = np.isfinite(s_end)
    s_anchor = np.concatenate([[0.0], s_end[known], [float(cl.s[-1])]])
    t_anchor = np.concatenate([[0.0], ends[known], [cycle]])
    order = np.argsort(s_anchor, kind="stable")
    cl_t = np.maximum.accumulate(np.interp(cl.s, s_anchor[order], t_anchor[order]))
    s = sample_progress(grid, q, cl.xyz, cl.s, cl_t)
    out = approx.copy()
    out[ok] = crossing_times(grid, s, target[ok])
    return out


def timing_residual(case: Case, segments: Segments, sim) -> np.ndarray:
    """Simulated minus measured duration of every segment (s)."""
    return simulated_segments(case, segments, sim) - segments.measured_s


def predicted_feedback(case: Case, profile: MachineProfile) -> np.ndarray | None:
    """The feedback positions `profile` predicts from the recording's own commanded joint positions."""
    from feedlog.sim.feedback import feedback_chain, feedback_positions
    from feedlog.sim.mechanism import resolve_mechanisms

    fb = case.feedback
    if fb is None:
        return None
    return feedback_positions(feedback_chain(resolve_mechanisms(profile)), fb.dt_s, fb.axes, fb.cmd)


def geometry_residual(case: Case, profile: MachineProfile) -> np.ndarray | None:
    """The joints `profile`'s kinematics make of the recording's own axis positions, minus the commanded
    joints it recorded: (n, 3), the linear joints (mm; the rotary ones equal their axes)."""
    from feedlog.sim.kinematics import machine_joints

    geo = case.geometry
    if geo is None:
        return None
    return machine_joints(profile, geo.pos)[:, :3] - geo.joints[:, :3]


def feedback_residual(case: Case, profile: MachineProfile) -> np.ndarray | None:
    """Predicted minus measured feedback positions, (n, k) (mm; deg for rotary joints)."""
    pred = predicted_feedback(case, profile)
    return None if pred is None else pred - case.feedback.fb


def rms(values: np.ndarray) -> float:
    values = np.asarray(values, dtype=np.float64)
    return float(np.sqrt(np.mean(values ** 2))) if values.size else 0.0


def line_latency(profile: MachineProfile) -> float:
    """The line stream's latency behind the positions that `profile` declares (`[sim.logger_latency]`)."""
    from feedlog.sim.mechanism import resolve_mechanisms

    return next((float(m.line_s) for m in resolve_mechanisms(profile) if m.name == "logger_latency"), 0.0)


def model_line_offsets(case: Case, profile: MachineProfile) -> tuple[np.ndarray, np.ndarray] | None:
    """(measured, modelled) line-stream-minus-geometry block end offsets on the blocks both have.

    The model's own offset (where a controller reports the next line within a blend, against where the
    positions show the block ending) comes from the simulation recorded as the recording was (its rate,
    no latency) and aligned the same way; a logger latency adds to it."""
    if case.line_offsets is None:
        return None
    from feedlog.align import align_recording
    from feedlog.diagnose.cases import line_offsets
    from feedlog.sim import MeasurementModel, measure, simulate

    try:
        sim = simulate(case.program, profile, mechanisms={"logger_latency": False})
        rec = measure(sim, MeasurementModel(rate_hz=min(1000.0, max(5.0, 1.0 / case.period_s)), rest_s=0.2))
        rec.source = f"{case.name}:simulated"
        # the same thresholds as the recording's alignment: where the tool counts as leaving a line
        # depends on the noise it was judged against; no guessed work offset (a simulated five-axis
        # program with a G54 is not in the program's frame, and an estimated offset, a few um off,
        # moves every modelled block end: no line level then, as before align could guess one)
        model = line_offsets(align_recording(rec, case.program, profile=profile, still_mm=case.still_mm,
                                             on_path_mm=case.on_path_mm, auto_offset=False))
    except FeedlogError:
        return None
    if model is None:
        return None
    both = case.line_offsets.to_frame("measured").join(model.rename("model"), how="inner")
    if len(both) < 2:
        return None
    return both["measured"].to_numpy(np.float64), both["model"].to_numpy(np.float64)
