"""`simulate(program, profile)`: run the mechanism chain on a part program.

Chain: `limits` mechanisms edit the per-block limits, the path is built (one piece per block), the
corner law sets junction speeds (and may insert blend arcs), the interpolator produces motion over
time, `series` mechanisms change the sampled motion. Deterministic: no randomness anywhere here
(the measurement model adds noise with an explicit seed).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from feedlog.profile import MachineProfile, load_profile
from feedlog.sim.cam import cam_block_times
from feedlog.sim.context import Context, Trajectory, one_row_per_block
from feedlog.sim.feedback import feedback_chain, feedback_table
from feedlog.sim.mechanism import Mechanism, MechanismSpec, resolve_mechanisms
from feedlog.sim.path import Blocks, build_pieces, prepare_blocks
from feedlog.toolpath.schema import AXIS_UNITS
from feedlog.errors import SimulationError
from feedlog.units import MAX_TIME_S, seconds_to_ns


class SimResult:
    """Simulated motion.

    `series`: t_ns, axis positions, feed_mm_min, block, line at the interpolation period (sampled on
    first access); `blocks`: block, line, t_start_ns, t_end_ns, duration_s per executed block (built on
    first access; `block_arrays` holds its first four columns as arrays);
    `cycle_time_s` (first motion to end of motion), `cam_time_s` (sum of L / F), `joints` (machine
    joints for five-axis kinematics, else None), `mechanisms` that ran with their parameters.
    """

    def __init__(self, *, ctx: Context, trajectory: Trajectory, mechanisms: list[Mechanism], cam_time_s: float):
        self.profile = ctx.profile
        self.mechanisms = mechanisms
        self.trajectory = trajectory
        self.cycle_time_s = trajectory.cycle_time_s
        self.cam_time_s = cam_time_s
        self.notes = ctx.notes
        self._ctx_blocks = ctx.blocks
        self.block_arrays = _block_arrays(ctx.blocks, trajectory)
        self._blocks: pd.DataFrame | None = None
        self._series: pd.DataFrame | None = None
        self.trajectory_dt_s = ctx.dt_s

    @property
    def blocks(self) -> pd.DataFrame:
        """One row per executed block (built on first access from `block_arrays`, which a caller that
        re-simulates thousands of times, a fit, reads directly)."""
        if self._blocks is None:
            block, line, start_ns, end_ns = self.block_arrays
            self._blocks = pd.DataFrame({"block": block, "line": line, "t_start_ns": start_ns, "t_end_ns": end_ns,
                                         "duration_s": (end_ns - start_ns) / 1e9})
        return self._blocks

    @property
    def series(self) -> pd.DataFrame:
        if self._series is None:
            self._series = _series(self._ctx_blocks, self.trajectory)
        return self._series

    def __getstate__(self) -> dict[str, Any]:
        """Pickled (a result sent back by a worker of feedlog.execution): the series and joints are sampled
        first and the trajectory, whose sampler is a closure, is left out (`trajectory` is None after)."""
        state = self.__dict__.copy()
        state["_series"] = self.series
        state["notes"] = {k: v for k, v in self.notes.items() if not callable(v)}
        if "joints" in self.notes:
            state["notes"]["joints"] = self.joints
        state["trajectory"] = None
        return state

    @property
    def joints(self) -> pd.DataFrame | None:
        joints = self.notes.get("joints")
        if callable(joints):
            joints = self.notes["joints"] = joints()
        return joints if isinstance(joints, pd.DataFrame) else None

    @property
    def feedback(self) -> pd.DataFrame | None:
        """`t_ns`, `jN_pos` (commanded joints: the axes, or the five-axis machine joints) and `jN_pos_fb`
        (through the profile's feedback mechanisms); None when the profile has none."""
        chain = feedback_chain(self.mechanisms)
        if not chain:
            return None
        joints = self.joints
        if joints is not None:
            cols = [c for c in joints.columns if c != "t_ns"]
            t_ns, cmd = joints["t_ns"].to_numpy(np.int64), joints[cols].to_numpy(np.float64)
        else:
            series = self.series
            cols = [f"{a}_{AXIS_UNITS[a]}" for a in self.profile.axis_names]
            t_ns, cmd = series["t_ns"].to_numpy(np.int64), series[cols].to_numpy(np.float64)
        axes = self.profile.axis_names[:cmd.shape[1]]
        return feedback_table(chain, t_ns, axes, cmd, self.trajectory_dt_s)

    @property
    def mechanism_params(self) -> dict[str, dict[str, Any]]:
        """Parameters of the mechanisms that ran (infinite values as None, so the dict is valid JSON)."""
        return mechanism_params(self.mechanisms)

    def summary(self) -> dict[str, Any]:
        return {"profile": self.profile.name, "cycle_time_s": round(self.cycle_time_s, 6),
                "cam_time_s": round(self.cam_time_s, 6), "blocks": int(len(self.blocks)),
                "mechanisms": self.mechanism_params}


def mechanism_params(mechanisms: list[Mechanism]) -> dict[str, dict[str, Any]]:
    """Each mechanism's parameters, infinite values as None (valid JSON)."""
    def clean(v: Any) -> Any:
        return None if isinstance(v, float) and not np.isfinite(v) else v
    return {m.name: {k: clean(v) for k, v in m.params().items()} for m in mechanisms}


def _profile(profile: MachineProfile | str | Path) -> MachineProfile:
    return profile if isinstance(profile, MachineProfile) else load_profile(profile)


def simulate(program, profile: MachineProfile | str | Path, *, mechanisms: MechanismSpec = None,
             dt_s: float | None = None) -> SimResult:
    """Simulate `program` (a toolpath Program, a block table or its `feedlog.sim.path.ProgramArrays`, which a
    caller simulating one program on many profiles builds once) on `profile` (object, name or path).

    `mechanisms` overrides the profile's `[sim]` tables: a list of names (exactly those run) or a
    mapping name -> {param: value} / True / False. `dt_s` is the output period (default: the
    profile's interpolation period).
    """
    profile = _profile(profile)
    if dt_s is not None and not 0 < dt_s <= 1:
        raise SimulationError(f"output period dt_s must be above 0 and at most 1 s, got {dt_s}")
    chain = resolve_mechanisms(profile, mechanisms)
    blocks = prepare_blocks(program, profile)
    cam_time = float(cam_block_times(blocks).sum())
    ctx = Context(profile=profile, blocks=blocks, dt_s=dt_s or profile.interpolator.interpolation_period_s)
    for mech in chain:
        mech.limit(ctx)
    pieces = build_pieces(ctx.blocks)
    keep = (pieces.length > 0) | (pieces.hold_s > 0)
    ctx.pieces = pieces if keep.all() else pieces.take(np.flatnonzero(keep))
    interpolator = next(m for m in chain if m.kind == "interpolator")
    if interpolator.uses_corner_law:
        for mech in chain:
            if mech.kind == "corner":
                mech.corner(ctx)
    trajectory = interpolator.run(ctx)
    for mech in chain:
        trajectory = mech.after(ctx, trajectory)
    if not 0 <= trajectory.cycle_time_s <= MAX_TIME_S:
        raise SimulationError(f"simulated cycle time {trajectory.cycle_time_s:.6g} s is not a time feedlog can count "
                              f"(0 to {MAX_TIME_S:.0e} s)")
    return SimResult(ctx=ctx, trajectory=trajectory, mechanisms=chain, cam_time_s=cam_time)


def _series(blocks: Blocks, traj: Trajectory) -> pd.DataFrame:
    """The samples as a DataFrame. The axis columns are taken without a copy when the positions are
    Fortran-ordered (as the samplers produce them): the frame shares memory with `traj.pos`."""
    t, pos, speed, row = traj.samples
    names = [f"{axis}_{AXIS_UNITS[axis]}" for axis in blocks.axes]
    frame = pd.DataFrame(np.asfortranarray(pos), columns=names, copy=False)
    frame.insert(0, "t_ns", seconds_to_ns(t))
    frame["feed_mm_min"] = speed * 60.0
    if len(blocks):
        frame["block"] = blocks.block.astype(np.int64, copy=False).take(row)
        frame["line"] = blocks.line.astype(np.int64, copy=False).take(row)
    else:
        frame["block"] = frame["line"] = np.zeros(len(t), np.int64)
    return frame


def _block_arrays(blocks: Blocks, traj: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(block, line, t_start_ns, t_end_ns) of every executed block, one row per block."""
    ran = ~np.isnan(traj.block_start_s)
    start_ns = seconds_to_ns(traj.block_start_s[ran])
    end_ns = seconds_to_ns(traj.block_end_s[ran])
    block, line = blocks.block[ran].astype(np.int64), blocks.line[ran].astype(np.int64)
    return one_row_per_block(block, line, start_ns, end_ns)
