"""Geometry: the machine's kinematics against the joints it commanded.

A recording that carries both the axis (program frame) positions and the commanded joint positions
shows the kinematics directly: the joints the profile's kinematics make of the recorded axes must be
the recorded joints. On a trunnion machine (`xyzac-trt`) the offsets of Chien's Eq. 10 decide where a
tilted or turned table puts the linear joints: the offset between the A and C axes
(`kinematics.rotary_offset_mm`, LinuxCNC's xyzac-trt-kins y/z-offset; its X component cancels) and the
workpiece origin relative to the rotary centre (`kinematics.workpiece_offset_mm`). A wrong offset leaves
the cycle time alone (LinuxCNC plans in axis coordinates) and moves the joints of every tilted pose by
millimetres. Each offset is one hypothesis on the `geometry` level; an offset the recorded poses cannot
move (no A motion for the A-C offsets) offers none. The joints are linear in the offsets, so the least
squares solution of all of them together is put on each one's search grid (`seeds`).

A recording with commanded and feedback positions shows the rest of the geometry per linear axis, on
the `feedback` level: a scale error (`sim.axis_scale.scale.<axis>`: the feedback grows with the distance
from machine zero) and backlash (`sim.backlash.backlash_mm.<axis>`: the feedback holds after every
reversal until the drive has crossed the play). Both are `feedback` mechanisms of the simulation that
the profile switches on when they are found.
"""

from __future__ import annotations

import numpy as np

from feedlog.diagnose import keys
from feedlog.diagnose.hypothesis import Family, Hypothesis

# (key, what a wrong value does)
OFFSETS = (
    ("kinematics.rotary_offset_mm.1", "tilted poses (A != 0) put the Y and Z joints off by the Y offset times (1 - cos A) and sin A"),
    ("kinematics.rotary_offset_mm.2", "tilted poses (A != 0) put the Y and Z joints off by the Z offset times sin A and (1 - cos A)"),
    ("kinematics.workpiece_offset_mm.0", "every pose's joints shifted by the X offset turned with the table"),
    ("kinematics.workpiece_offset_mm.1", "every pose's joints shifted by the Y offset turned with the table"),
    ("kinematics.workpiece_offset_mm.2", "every pose's joints shifted by the Z offset turned with the table"),
)
SPAN_MM = 100.0       # searched within the profile's value +- this
OBSERVED = 1e-3       # an offset moves the joints by at least this per mm over the recordings, or is not offered


class Geometry(Family):
    """Ranked after every timing family: geometry keys are judged on their own data (joints, feedback),
    so a tie with another family's key can only arise on the feedback level, where a servo's dynamics
    (delay, lag) are the likelier explanation. The evidence (`evidence.py`, no simulation) says nothing
    about the geometry: the joints' own least squares solution is put on the grid by `offsets`."""

    name = "geometry"
    rank = 7

    def candidates(self, profile, cases) -> list[Hypothesis]:
        return offsets(profile, cases) + measuring(profile, cases)

    def describe(self, ev, key, fitted=None) -> str:
        return ""

    def suggest(self, ev, key, baseline) -> tuple[float, ...]:
        return ()

    def contradicts(self, ev, key, profile_value, fitted) -> str | None:
        return None


def measuring(profile, cases) -> list[Hypothesis]:
    """Scale and backlash of each linear axis that moves in a recording with joint feedback."""
    with_fb = [c for c in cases if c.feedback is not None]
    out: list[Hypothesis] = []
    axes = sorted({a for c in with_fb for a in c.feedback.axes if a in ("x", "y", "z")}, key="xyz".index)
    scale_on, play_on = keys.enabled(profile, "axis_scale"), keys.enabled(profile, "backlash")
    for axis in axes:
        if not any(np.ptp(c.feedback.cmd[:, c.feedback.axes.index(axis)]) > 1e-3 for c in with_fb
                   if axis in c.feedback.axes):
            continue
        key = f"sim.axis_scale.scale.{axis}"
        base = float(keys.value(profile, key)) if scale_on else 1.0
        out.append(Hypothesis(key=key, family="geometry", lower=base - 0.01, upper=base + 0.01, scale="linear",
                              baseline=base if scale_on else None, switches_on=not scale_on, level="feedback",
                              predicts=f"{axis.upper()} feedback off its command in proportion to the distance from "
                                       "machine zero"))
        key = f"sim.backlash.backlash_mm.{axis}"
        base = float(keys.value(profile, key)) if play_on else 0.0
        out.append(Hypothesis(key=key, family="geometry", lower=0.0, upper=max(1.0, 2 * base), scale="linear",
                              baseline=base if play_on else None, switches_on=not play_on, level="feedback",
                              predicts=f"{axis.upper()} feedback holds after each reversal until the command has "
                                       "crossed the play, then trails it by half the play"))
    return out


def offsets(profile, cases) -> list[Hypothesis]:
    """The trunnion's offsets the recorded poses can move."""
    with_geo = [c for c in cases if c.geometry is not None]
    if profile.kinematics.type != "xyzac-trt" or not with_geo:
        return []
    from feedlog.diagnose.residuals import geometry_residual

    base = np.concatenate([geometry_residual(c, profile).ravel() for c in with_geo])
    columns, offered = [], []
    for key, predicts in OFFSETS:
        value = float(keys.value(profile, key))
        moved = keys.with_values(profile, {key: value + 1.0})
        col = np.concatenate([geometry_residual(c, moved).ravel() for c in with_geo]) - base  # joints per mm
        if np.sqrt(np.mean(col ** 2)) > OBSERVED:
            columns.append(col)
            offered.append((key, predicts, value))
    if not offered:
        return []
    step, *_ = np.linalg.lstsq(np.column_stack(columns), -base, rcond=None)  # all offsets at once
    return [Hypothesis(key=key, family="geometry", lower=value - SPAN_MM, upper=value + SPAN_MM, scale="linear",
                       baseline=value, level="geometry", predicts=predicts, seeds=(value + float(d),))
            for (key, predicts, value), d in zip(offered, step)]


FAMILY = Geometry()
