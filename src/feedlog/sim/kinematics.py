"""Five-axis AC trunnion kinematics: machine joints from program axes, and the feed drop they cause.

Source: Chien et al. (2024) §2.2-2.3. Tool orientation O = [Oi, Oj, Ok] to rotary axes (Eq. 7):
A = acos(Ok), C = atan2(Oi, Oj); near the singularity sin(A) -> 0 the C axis must turn fast for a
small orientation change (Eq. 9, dC/dt = (1 / sin A) d(theta_h)/dt), so its velocity and
acceleration limits pull the feed down. Cartesian machine positions of a workpiece point P on the
table (Eq. 10, the table rotating the workpiece):

    [X_M, Y_M, Z_M] = Rot(X, A) . (Rot(Z, C) . (P + W) + R) - R

with W the workpiece offset from the rotary centre ([Xo, Yo, Zo]) and R the offset between the A
and C axes (LinuxCNC xyzac-trt-kins y/z-offset). A larger |W| makes the same rotation sweep the
linear joints further, so the feed drops further (the trend of Chien Tables 4 and 9).

With `limit_joints` the per-joint velocity and acceleration limits of the profile (x, y, z, a, c)
cap every block's feed, using the joint motion per unit path length sampled at `samples_per_block`
points along the block. LinuxCNC plans in program (axis) coordinates and does not do this (its
profile sets `[sim.trunnion] limit_joints = false`). Blocks that carry tool orientation vectors (ori_i/j/k, CL data)
get their A/C from Eq. 7 when `orientation_from_vectors` is set.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from feedlog.profile import MachineProfile
from feedlog.sim.context import Context, Trajectory
from feedlog.sim.mechanism import Mechanism
from feedlog.sim.path import projected_limits
from feedlog.units import seconds_to_ns


def rotary_from_orientation(ori: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Chien Eq. 7: A = acos(Ok), C = atan2(Oi, Oj) in degrees; C unwrapped, held through A = 0."""
    a, c, _ = rotary_carried(ori)
    return a, c


def rotary_carried(ori: np.ndarray, before: dict | None = None,
                   last: bool = True) -> tuple[np.ndarray, np.ndarray, dict | None]:
    """`rotary_from_orientation` for a window of vectors: `before` continues the rows of an earlier window (its `after`: the last filled C in rad and the
    unwrap correction so far). Returns (A, C, after); after is None while every vector so far is at the
    singularity and more rows may come (`last` False): their C waits for the first defined one."""
    o = ori / np.linalg.norm(ori, axis=1, keepdims=True)
    a = np.degrees(np.arccos(np.clip(o[:, 2], -1.0, 1.0)))
    c = np.arctan2(o[:, 0], o[:, 1])
    singular = np.hypot(o[:, 0], o[:, 1]) < 1e-9
    if before is None and singular.all():
        return a, np.zeros(len(a)), (None if not last else {"c": None})
    if before is not None and before.get("c") is None:   # the program's vectors were all singular so far
        return a, np.zeros(len(a)), before
    held = None if before is None else before["c"]
    c = pd.Series(np.where(singular, np.nan, c)).ffill().fillna(np.nan if held is None else held).bfill().to_numpy()
    if before is None:
        dd = np.diff(c)
        correction0, head = 0.0, c[:1]
    else:
        dd = np.diff(np.concatenate(([held], c)))
        correction0, head = before["correction"], c[:0]
    # np.unwrap's operations, continuing its running correction
    ddmod = np.mod(dd + np.pi, 2 * np.pi) - np.pi
    np.copyto(ddmod, np.pi, where=(ddmod == -np.pi) & (dd > 0))
    ph_correct = ddmod - dd
    np.copyto(ph_correct, 0, where=np.abs(dd) < np.pi)
    correction = np.cumsum(np.concatenate(([correction0], ph_correct)))[1:]
    rest = c[len(head):]
    up = np.concatenate([head, rest + correction])
    after = {"c": float(c[-1]), "correction": float(correction[-1]) if len(correction) else correction0,
             "c_rows": c, "correction_rows": np.concatenate([[correction0] * len(head), correction])}
    return a, np.degrees(up), after


def trunnion_joints(xyz: np.ndarray, a_deg: np.ndarray, c_deg: np.ndarray, *, workpiece_offset_mm,
                    rotary_offset_mm) -> np.ndarray:
    """Machine X, Y, Z (n, 3) of workpiece points xyz at table angles A, C (Chien Eq. 10)."""
    return np.column_stack(trunnion_columns(xyz[:, 0], xyz[:, 1], xyz[:, 2], a_deg, c_deg,
                                            workpiece_offset_mm=workpiece_offset_mm,
                                            rotary_offset_mm=rotary_offset_mm))


def trunnion_columns(x: np.ndarray, y: np.ndarray, z: np.ndarray, a_deg: np.ndarray, c_deg: np.ndarray, *,
                     workpiece_offset_mm, rotary_offset_mm) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`trunnion_joints` on separate coordinate arrays of any (equal) shape: machine X, Y, Z."""
    w = [float(v) for v in workpiece_offset_mm]
    r = [float(v) for v in rotary_offset_mm]
    a = np.radians(a_deg)
    c = np.radians(c_deg)
    px, py, pz = x + w[0], y + w[1], z + w[2]
    cc, sc = np.cos(c), np.sin(c)
    q0 = (cc * px - sc * py) + r[0]
    q1 = (sc * px + cc * py) + r[1]
    q2 = pz + r[2]
    ca, sa = np.cos(a), np.sin(a)
    return q0 - r[0], (ca * q1 - sa * q2) - r[1], (sa * q1 + ca * q2) - r[2]


def machine_joints(profile: MachineProfile, pos: np.ndarray) -> np.ndarray:
    """The machine joints (n, k) of axis positions `pos` (n, k), columns in `profile.axis_names` order,
    through the profile's kinematics: the trunnion's Eq. 10 (with the offsets in force) for a trunnion
    machine, the positions themselves for a Cartesian one."""
    from feedlog.sim.mechanism import resolve_mechanisms

    pos = np.asarray(pos, dtype=np.float64)
    names = profile.axis_names
    for mech in resolve_mechanisms(profile):
        if isinstance(mech, TrunnionKinematics):
            ia, ic = names.index("a"), names.index("c")
            out = pos.copy()
            out[:, :3] = trunnion_joints(pos[:, :3], pos[:, ia], pos[:, ic], workpiece_offset_mm=mech.workpiece_offset_mm,
                                         rotary_offset_mm=mech.rotary_offset_mm)
            return out
    return pos.copy()


@dataclass
class TrunnionKinematics(Mechanism):
    name = "trunnion"
    kind = "limits"
    order = 30
    windowed = True

    workpiece_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rotary_offset_mm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    limit_joints: bool = True
    samples_per_block: int = 4
    orientation_from_vectors: bool = True

    def __post_init__(self) -> None:
        self.workpiece_offset_mm = tuple(float(v) for v in self.workpiece_offset_mm)
        self.rotary_offset_mm = tuple(float(v) for v in self.rotary_offset_mm)
        if len(self.workpiece_offset_mm) != 3 or len(self.rotary_offset_mm) != 3:
            raise ValueError("workpiece_offset_mm and rotary_offset_mm need three values")
        self.check_positive(samples_per_block=self.samples_per_block)

    @classmethod
    def default_enabled(cls, profile: MachineProfile) -> bool:
        return profile.kinematics.type == "xyzac-trt"

    @classmethod
    def defaults(cls, profile: MachineProfile) -> dict:
        k = profile.kinematics
        return {"workpiece_offset_mm": k.workpiece_offset_mm, "rotary_offset_mm": k.rotary_offset_mm}

    def _axes(self, ctx: Context) -> tuple[int, int]:
        axes = ctx.blocks.axes
        return axes.index("a"), axes.index("c")

    def joints(self, pos: np.ndarray, ctx: Context) -> np.ndarray:
        ia, ic = self._axes(ctx)
        xyz = trunnion_joints(pos[:, :3], pos[:, ia], pos[:, ic], workpiece_offset_mm=self.workpiece_offset_mm,
                              rotary_offset_mm=self.rotary_offset_mm)
        return np.column_stack([xyz, pos[:, ia], pos[:, ic]])

    def limit(self, ctx: Context) -> None:
        b = ctx.blocks
        ia, ic = self._axes(ctx)
        ori = b.extra.get("ori")
        window = ctx.window
        if window is not None:
            self._window_orientation(ctx, ia, ic)
        elif self.orientation_from_vectors and ori is not None and len(b):
            have = ~np.isnan(ori).any(axis=1) & (np.linalg.norm(np.nan_to_num(ori), axis=1) > 0)
            if have.any():
                a_end, c_end = rotary_from_orientation(ori[have])
                b.p1[have, ia], b.p1[have, ic] = a_end, c_end
                # each block starts where the previous one ended
                b.p0[1:, ia], b.p0[1:, ic] = b.p1[:-1, ia], b.p1[:-1, ic]
                self._rotary_limits(ctx)
        if not self.limit_joints or not len(b):
            return
        k = self.samples_per_block
        delta = b.p1 - b.p0
        ds = b.length / k
        names = ("x", "y", "z", "a", "c")
        rate = [np.zeros(len(b)) for _ in names]
        # table angles at the k + 1 sample points of each block: cos/sin at the start, then rotated by
        # the per-step angle (two multiply-adds per step instead of trigonometry at every point)
        a_rad, c_rad = np.radians(b.p0[:, ia]), np.radians(b.p0[:, ic])
        step_a, step_c = np.radians(delta[:, ia]) / k, np.radians(delta[:, ic]) / k
        ca, sa, cc, sc = np.cos(a_rad), np.sin(a_rad), np.cos(c_rad), np.sin(c_rad)
        cda, sda, cdc, sdc = np.cos(step_a), np.sin(step_a), np.cos(step_c), np.sin(step_c)
        w = self.workpiece_offset_mm
        r = self.rotary_offset_mm
        prev = None
        with np.errstate(divide="ignore", invalid="ignore"):
            for j in range(k + 1):
                f = j / k
                if j:
                    ca, sa = ca * cda - sa * sda, sa * cda + ca * sda
                    cc, sc = cc * cdc - sc * sdc, sc * cdc + cc * sdc
                px, py, pz = (b.p0[:, i] + f * delta[:, i] + w[i] for i in range(3))
                q0 = cc * px - sc * py + r[0]
                q1 = sc * px + cc * py + r[1]
                q2 = pz + r[2]
                cur = (q0 - r[0], (ca * q1 - sa * q2) - r[1], (sa * q1 + ca * q2) - r[2])
                if prev is not None:
                    for out, q, q_prev in zip(rate, cur, prev):
                        step = np.abs(q - q_prev) / ds       # joint travel per unit path length
                        step[~np.isfinite(step)] = 0.0
                        np.maximum(out, step, out=out)
                prev = cur
            # the rotary joints turn uniformly along a block: travel per unit path length |dA| / L
            for out, i in ((rate[3], ia), (rate[4], ic)):
                out[:] = np.abs(delta[:, i]) / b.length
                out[~np.isfinite(out)] = 0.0
        v_joint = np.full(len(b), np.inf)
        a_joint = np.full(len(b), np.inf)
        with np.errstate(divide="ignore"):
            for name, q_rate in zip(names, rate):
                fast = q_rate > 1e-12
                axis = ctx.profile.axes[name]
                np.minimum(v_joint, np.where(fast, axis.vel_max / q_rate, np.inf), out=v_joint)
                np.minimum(a_joint, np.where(fast, axis.acc_max / q_rate, np.inf), out=a_joint)
        b.v_limit = np.minimum(b.v_limit, v_joint)
        b.v_axis = np.minimum(b.v_axis, v_joint)
        b.a_max = np.minimum(b.a_max, a_joint)
        ctx.notes["joint_feed_limit"] = v_joint

    def _rotary_limits(self, ctx: Context) -> None:
        b = ctx.blocks
        ia, ic = self._axes(ctx)
        b.rotary = (np.abs(b.p1[:, [ia, ic]] - b.p0[:, [ia, ic]]) > 1e-9).any(axis=1)
        vel = np.array([ctx.profile.axes[a].vel_max for a in b.axes])
        acc = np.array([ctx.profile.axes[a].acc_max for a in b.axes])
        v_axis, a_axis = projected_limits(b.p1 - b.p0, b.length, vel, acc)
        b.v_limit = np.minimum(b.v_limit, v_axis)
        b.v_axis = np.minimum(b.v_axis, v_axis)
        b.a_max = np.minimum(b.a_max, a_axis)

    def _window_orientation(self, ctx: Context, ia: int, ic: int) -> None:
        """The orientation vectors of a window (feedlog.sim.window): C continues the window before,
        and rows whose C still waits for a defined vector stay pending."""
        b = ctx.blocks
        window = ctx.window
        mine = window.mine(self.name)
        ori = b.extra.get("ori")
        first = b.extra["first_block"].copy()
        have = np.zeros(len(b), bool)
        if self.orientation_from_vectors and ori is not None and len(b):
            have = ~np.isnan(ori).any(axis=1) & (np.linalg.norm(np.nan_to_num(ori), axis=1) > 0)
        before = mine.get("rotary")
        after = before
        chained = bool(mine.get("chained", False))
        if have.any():
            a_end, c_end, after = rotary_carried(ori[have], before, last=window.last)
            if after is None:        # all singular so far: C is unknown until a defined vector comes
                window.pending(self.name, int(first[np.flatnonzero(have)[0]]))
            else:
                b.p1[have, ia], b.p1[have, ic] = a_end, c_end
            chained = True
        if chained and len(b):
            b.p0[1:, ia], b.p0[1:, ic] = b.p1[:-1, ia], b.p1[:-1, ic]
            if "p1" in mine:
                b.p0[0, ia], b.p0[0, ic] = mine["p1"]
            self._rotary_limits(ctx)
        rows_have = np.flatnonzero(have)
        p1 = b.p1[:, [ia, ic]].copy()

        def state_at(block: int) -> dict:
            r = int(np.searchsorted(first, block))            # rows before the restart
            k = int(np.searchsorted(rows_have, r))            # vectors before it
            out: dict = {"chained": chained if r else bool(mine.get("chained", False))}
            if r:
                out["p1"] = tuple(float(v) for v in p1[r - 1])
            elif "p1" in mine:
                out["p1"] = mine["p1"]
            if k == 0 or after is None or after.get("c_rows") is None:
                out["rotary"] = before
            else:
                out["rotary"] = {"c": float(after["c_rows"][k - 1]), "correction": float(after["correction_rows"][k - 1])}
            return out

        window.carry(self.name, state_at)

    def after(self, ctx: Context, trajectory: Trajectory) -> Trajectory:
        def joints() -> pd.DataFrame:
            q = self.joints(trajectory.pos, ctx)
            table = {"t_ns": seconds_to_ns(trajectory.t_s)}
            table.update({f"j{i}_pos": q[:, i] for i in range(5)})
            return pd.DataFrame(table)

        ctx.notes["joints"] = joints  # evaluated when SimResult.joints is read
        return trajectory
