"""`diagnose.rrd`: the diagnosis in Rerun.

Per recording, under `diagnose/<recording>/`:
- `path/before`, `path/after`: the measured toolpath coloured by the timing residual of the segment
  each sample lies in (simulated - measured, in ms per second of segment; blue: the simulation is
  too fast there), with the given and with the extended profile;
- `speed/measured`, `speed/before`, `speed/after`: path speed over the time since motion start
  (`time`) and along the program (`path_um`), sent columnar with `rr.send_columns`.
The blueprint shows the paths in 3D beside the speed series.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from feedlog.diagnose.cases import position_columns
from feedlog.diagnose.residuals import sim_span
from feedlog.colors import residual_colors
from feedlog.rerun_stream import new_stream

MAX_POINTS = 200_000
ROOT = "diagnose"


def _segment_rate(case_end_s: np.ndarray, measured_s: np.ndarray, residual_s: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Per sample: residual of its segment per second of the segment (ms/s)."""
    idx = np.clip(np.searchsorted(case_end_s, t), 0, len(case_end_s) - 1)
    return 1e3 * residual_s[idx] / np.maximum(measured_s[idx], 1e-9)


def _send(stream: rr.RecordingStream, entity: str, t_s: np.ndarray, values: np.ndarray, *, label: str,
          s_mm: np.ndarray | None = None) -> None:
    keep = np.isfinite(values) & np.isfinite(t_s)
    if not keep.any():
        return
    stream.log(entity, rr.SeriesLines(names=[label]), static=True)
    indexes = [rr.TimeColumn("time", duration=np.rint(t_s[keep] * 1e9).astype("timedelta64[ns]"))]
    if s_mm is not None:
        indexes.append(rr.TimeColumn("path_um", sequence=np.rint(s_mm[keep] * 1000).astype(np.int64)))
    stream.send_columns(entity, indexes=indexes, columns=rr.Scalars.columns(scalars=values[keep]))


def save_rrd(dx, path: Path) -> Path:
    """Encode the recording in memory, then write its bytes (a write that fails is an ordinary OSError)."""
    stream = new_stream("diagnose")
    blueprint = rrb.Blueprint(rrb.Horizontal(
        rrb.Spatial3DView(origin=ROOT, name="toolpath coloured by timing residual"),
        rrb.Vertical(*[rrb.TimeSeriesView(origin=f"{ROOT}/{c.name}/speed", name=f"{c.name}: path speed (mm/min)")
                       for c in dx.cases[:4]])))
    memory = stream.memory_recording()
    stream.send_blueprint(blueprint)
    try:
        stream.send_recording_name("feedlog diagnose")
        seg = dx.where.get("segments")
        for i, case in enumerate(dx.cases):
            base = f"{ROOT}/{case.name}"
            axes = case.recording.streams["axes"]
            cols = [c for c in position_columns(dx.profile) if c in axes.columns][:3]
            t = case.compared_s((axes["t_ns"].to_numpy(np.int64) - case.t0_ns) / 1e9)  # feed holds out
            xyz = axes[cols].to_numpy(np.float64)
            step = max(1, len(t) // MAX_POINTS)
            if seg is not None and len(seg):
                part = seg[seg["recording"] == f"recording {case.name}"]
                if len(part):
                    ends, meas = part["end_s"].to_numpy(), part["measured_s"].to_numpy()
                    for label in ("before", "after"):
                        rate = _segment_rate(ends, meas, part[f"residual_{label}_s"].to_numpy(), t)
                        stream.log(f"{base}/path/{label}", rr.Points3D(xyz[::step], colors=residual_colors(rate[::step]),
                                                                       radii=[0.08]), static=True)
            curves = dx.where.get("curves", {}).get(case.name)
            feed = case.recording.streams.get("feed")
            if feed is not None and "feed_mm_min" in feed.columns:
                ft = case.compared_s((feed["t_ns"].to_numpy(np.int64) - case.t0_ns) / 1e9)
                _send(stream, f"{base}/speed/measured", ft, feed["feed_mm_min"].to_numpy(np.float64), label="measured")
            elif curves is not None:
                _send(stream, f"{base}/speed/measured", curves["t_measured_s"].to_numpy(),
                      curves["v_measured_mm_min"].to_numpy(), label="measured", s_mm=curves["s_mm"].to_numpy())
            for label in ("before", "after"):
                sims = dx.sims.get(label)
                if not sims:
                    continue
                traj = sims[i].trajectory
                start, _ = sim_span(case, sims[i])
                stride = max(1, len(traj.t_s) // MAX_POINTS)
                _send(stream, f"{base}/speed/{label}", (traj.t_s - start)[::stride], 60.0 * traj.speed[::stride],
                      label="simulated, given profile" if label == "before" else "simulated, extended profile")
    finally:
        stream.flush()
    data = memory.drain_as_bytes()
    stream.disconnect()
    path.write_bytes(data)
    return path
