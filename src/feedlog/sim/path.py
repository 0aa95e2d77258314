"""Motion blocks and path pieces: the block table turned into arrays the planner can work on.

`Blocks` holds one row per motion (or dwell) block with its geometry, programmed feed and the
limits that the `limits` mechanisms adjust. `Pieces` is the executed path: one piece per block
(lines and G2/G3 arcs), plus the blend arcs a corner law inserts. A piece is parameterised by its
length `sigma` in [0, length]:

    position(sigma) = p0 + dir * sigma + radius * ((cos(omega sigma) - 1) e1 + sin(omega sigma) e2)

(lines: radius = 0). Path length is the TCP (x, y, z) length; a move of rotary axes alone is measured
in degrees, as LinuxCNC and RS274 do.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
import pandas as pd

from feedlog.errors import SimulationError
from feedlog.profile import LINEAR_AXES, MachineProfile
from feedlog.sim.queue_sync import m_code_rows, syncs_after
from feedlog.toolpath import schema
from feedlog.toolpath.limits import check_axes

KIND_RAPID, KIND_LINEAR, KIND_ARC, KIND_DWELL = 0, 1, 2, 3
_KIND_CODES = {schema.RAPID: KIND_RAPID, schema.LINEAR: KIND_LINEAR, schema.ARC_CW: KIND_ARC,
               schema.ARC_CCW: KIND_ARC, schema.DWELL: KIND_DWELL}
_PLANES = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}  # plane axis 1, plane axis 2, normal (x=0)
_PLANE_AXES = np.array([_PLANES[17], _PLANES[18], _PLANES[19]])
EPS_LEN = 1e-9


def rows(values: np.ndarray, index: np.ndarray) -> np.ndarray:
    """values[index] along the first axis (np.take: several times faster than fancy indexing for
    (n, k) arrays)."""
    return values.take(index, axis=0)


def linear_columns(lin: list[int]) -> slice | list[int]:
    """The linear axis columns as a slice when they are the leading ones (a view, no copy)."""
    return slice(0, len(lin)) if lin == list(range(len(lin))) else lin


@dataclass
class Blocks:
    """Per-block arrays (n rows). Positions have one column per profile axis (`axes`)."""

    axes: tuple[str, ...]
    block: np.ndarray        # block index in the program's block table
    line: np.ndarray         # source line
    kind: np.ndarray         # KIND_* codes
    p0: np.ndarray           # (n, k) start positions
    p1: np.ndarray           # (n, k) end positions
    length: np.ndarray       # path length (mm; deg for rotary-only moves)
    feed: np.ndarray         # programmed feed in length units per second (rapids: rapid rate)
    v_limit: np.ndarray      # speed limit from axis and path velocity limits (the feed may be lower)
    v_axis: np.ndarray       # the axis velocity limits alone (projected on the block; LinuxCNC canon's limit)
    a_max: np.ndarray        # along-path acceleration limit from axis limits
    stop_after: np.ndarray   # exact stop at the end of the block (G61, G61.1, dwell, program end)
    exact_path: np.ndarray   # G61: the stop may be skipped where the next block continues tangentially
    tol: np.ndarray          # G64 P tolerance (NaN: none given)
    merge_tol: np.ndarray    # G64 Q tolerance for merging nearly collinear lines (NaN: none)
    hold_s: np.ndarray       # standstill after the block (G4 dwell, reversal dwell)
    min_time_s: np.ndarray   # lower bound of the block's duration (block processing time)
    rotary: np.ndarray       # block moves a rotary axis
    # arcs (NaN / 0 elsewhere)
    center: np.ndarray       # (n, 3)
    normal_axis: np.ndarray  # index of the plane normal among x, y, z
    sweep: np.ndarray        # signed sweep angle (rad), CCW positive about the plane normal
    radius: np.ndarray
    extra: dict[str, np.ndarray] = field(default_factory=dict)  # mechanisms may add columns

    def __len__(self) -> int:
        return len(self.block)

    def take(self, index: np.ndarray) -> Blocks:
        """The rows `index` (arrays and `extra` columns alike)."""
        fields = {k: getattr(self, k) for k in self.__dataclass_fields__ if k not in ("axes", "extra")}
        return Blocks(axes=self.axes, extra={k: rows(v, index) for k, v in self.extra.items()},
                      **{k: rows(v, index) for k, v in fields.items()})

    @staticmethod
    def concat(parts: list[Blocks]) -> Blocks:
        """The rows of `parts` one after the other; an `extra` column some parts lack is NaN there."""
        parts = [p for p in parts if p is not None]
        if len(parts) == 1:
            return parts[0]
        first = parts[0]
        fields = [k for k in first.__dataclass_fields__ if k not in ("axes", "extra")]
        names = list(dict.fromkeys(k for p in parts for k in p.extra))
        extra = {}
        for k in names:
            like = next(p.extra[k] for p in parts if k in p.extra)
            extra[k] = np.concatenate([p.extra[k] if k in p.extra else np.full((len(p),) + like.shape[1:], np.nan)
                                       for p in parts])
        return Blocks(axes=first.axes, extra=extra,
                      **{k: np.concatenate([getattr(p, k) for p in parts]) for k in fields})

    @property
    def v_max(self) -> np.ndarray:
        """Cruise speed: programmed feed capped by the velocity limits."""
        return np.minimum(self.feed, self.v_limit)

    @property
    def linear_index(self) -> list[int]:
        return [i for i, a in enumerate(self.axes) if a in LINEAR_AXES]


@dataclass
class Pieces:
    """The executed path, in order. Arrays of m pieces; `block` indexes `Blocks` rows."""

    block: np.ndarray
    length: np.ndarray
    p0: np.ndarray
    dir: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    radius: np.ndarray
    omega: np.ndarray
    v_max: np.ndarray
    a_max: np.ndarray
    v_end: np.ndarray        # speed limit at the junction after the piece (0 = stop)
    hold_s: np.ndarray       # standstill after the piece
    blend: np.ndarray        # piece was inserted by a corner law
    overlap: np.ndarray      # parabolic blend with the next piece (LinuxCNC fallback)
    clamp_len: np.ndarray    # length that must last >= one servo cycle (a consumed line adds to its arc)
    open_end: np.ndarray | None = None  # nothing is queued after the piece (a word run at rest, a dwell follows)

    def __post_init__(self) -> None:
        if self.open_end is None:
            self.open_end = np.zeros(len(self.block), bool)

    def __len__(self) -> int:
        return len(self.block)

    def take(self, index: np.ndarray) -> Pieces:
        return Pieces(**{k: rows(getattr(self, k), index) for k in self.__dataclass_fields__})

    def slice(self, lo: int, hi: int) -> Pieces:
        """Pieces lo..hi - 1 (views)."""
        return Pieces(**{k: getattr(self, k)[lo:hi] for k in self.__dataclass_fields__})

    @staticmethod
    def concat(parts: list[Pieces]) -> Pieces:
        parts = [p for p in parts if p is not None]
        if len(parts) == 1:
            return parts[0]
        return Pieces(**{k: np.concatenate([getattr(p, k) for p in parts]) for k in Pieces.__dataclass_fields__})

    def position(self, index: np.ndarray, sigma: np.ndarray) -> np.ndarray:
        """Axis positions (len(index), k) at path parameter sigma within the given pieces."""
        sigma = np.asarray(sigma, dtype=np.float64)
        pos = self.p0[index] + self.dir[index] * sigma[:, None]
        curved = self.radius[index] > 0
        if curved.any():
            idx = index[curved]
            ang = self.omega[idx] * sigma[curved]
            pos[curved] += self.radius[idx, None] * ((np.cos(ang) - 1.0)[:, None] * self.e1[idx]
                                                     + np.sin(ang)[:, None] * self.e2[idx])
        return pos

    def tangent_xyz(self, index: np.ndarray, sigma: np.ndarray, lin: list[int]) -> np.ndarray:
        """Unit TCP tangent (len(index), 3) at sigma (zeros where the TCP does not move)."""
        d = rows(self.dir[:, linear_columns(lin)], index)
        curved = rows(self.radius, index) > 0
        if curved.any():  # arcs: add the circular part's derivative
            idx = index[curved]
            ang = self.omega[idx] * np.broadcast_to(sigma, index.shape)[curved]
            d[curved] += (self.radius[idx, None] * self.omega[idx, None]
                          * (-np.sin(ang)[:, None] * self.e1[idx] + np.cos(ang)[:, None] * self.e2[idx]))[:, lin]
        norm = np.sqrt(np.einsum("ij,ij->i", d, d))
        moving = norm > EPS_LEN
        if moving.all():
            return d / norm[:, None]
        return np.divide(d, norm[:, None], out=np.zeros_like(d), where=moving[:, None])


def block_table(program) -> pd.DataFrame:
    """The block table of a `Program` (anything with `.blocks`) or a DataFrame."""
    table = getattr(program, "blocks", program)
    if not isinstance(table, pd.DataFrame):
        raise SimulationError(f"expected a Program or a block table DataFrame, got {type(program).__name__}")
    missing = [c for c in ("block", "line", "kind", "feed_mm_min", "path_mode") if c not in table.columns]
    if missing:
        raise SimulationError(f"block table lacks column(s) {', '.join(missing)} (see feedlog/toolpath/schema.py)")
    return table


def _codes(column: pd.Series, mapping: dict[str, int]) -> np.ndarray:
    """Integer codes of a (usually categorical) label column via its categories (-1: not mapped)."""
    cat = column if isinstance(column.dtype, pd.CategoricalDtype) else column.astype("category")
    lookup = np.array([mapping.get(str(c), -1) for c in cat.cat.categories] + [-1], dtype=np.int8)
    return lookup[cat.cat.codes.to_numpy()]


def _where(table: pd.DataFrame, i: int) -> str:
    """'file:line' of row i of a block table (for error messages)."""
    line = int(table["line"].iloc[i])
    file = str(table["file"].iloc[i]) if "file" in table.columns else ""
    return f"{file}:{line}" if file else f"line {line}"


def projected_limits(delta: np.ndarray, length: np.ndarray, vel: np.ndarray, acc: np.ndarray):
    """Path speed and acceleration at which the first axis reaches its limit, per straight move
    (RS274 canon: each axis' time d_i / v_i, the slowest one sets the move's limit)."""
    safe = np.where(length > EPS_LEN, length, 1.0)
    v_axis = np.full(len(length), np.inf)
    a_axis = np.full(len(length), np.inf)
    # one column at a time: reductions over a short second axis are slow in numpy
    with np.errstate(divide="ignore", over="ignore"):
        for i in range(delta.shape[1]):
            ratio = np.abs(delta[:, i]) / safe
            moves = ratio > 1e-12
            np.minimum(v_axis, np.where(moves, vel[i] / ratio, np.inf), out=v_axis)
            np.minimum(a_axis, np.where(moves, acc[i] / ratio, np.inf), out=a_axis)
    return v_axis, a_axis


class ProgramArrays:
    """The motion and dwell rows of a block table as arrays, read once: what `prepare_blocks` needs of
    the program whatever the profile. Re-simulating one program on many profiles (a fit) passes this
    to `simulate` instead of the program, so the table's columns are not read again every time."""

    def __init__(self, program) -> None:
        table = block_table(program)
        self.table = table
        code = _codes(table["kind"], _KIND_CODES)
        self.sel = np.flatnonzero(code >= 0)  # motion and dwell rows
        self.code = code[self.sel]
        self.ccw = _codes(table["kind"], {schema.ARC_CCW: 1})[self.sel] == 1
        self.mode = _codes(table["path_mode"], {schema.CONTINUOUS: 1, schema.EXACT_PATH: 2})[self.sel]
        self.block = table["block"].to_numpy(np.int64)[self.sel]
        self.line = table["line"].to_numpy(np.int64)[self.sel]
        self.tool_changes = _tool_changes_after(table, self.sel)
        self.syncs = syncs_after(table, self.sel)
        self._cols: dict[str, np.ndarray | None] = {}
        self._checked: set[tuple[str, ...]] = set()

    def col(self, name: str, default: float) -> np.ndarray:
        """Rows of a numeric column as float64 (a new array each call; `default` where it is missing)."""
        if name not in self._cols:
            self._cols[name] = (self.table[name].to_numpy(dtype=np.float64, na_value=np.nan).take(self.sel)
                                if name in self.table.columns else None)
        values = self._cols[name]
        return np.full(len(self.sel), default, dtype=np.float64) if values is None else values.copy()

    def has(self, name: str) -> bool:
        return name in self.table.columns

    def check_axes(self, axes: tuple[str, ...], profile_name: str) -> None:
        """No block may move an axis the machine lacks (`toolpath.limits.check_axes`), once per axis set."""
        if axes not in self._checked:
            check_axes(self.table, axes, profile_name)
            self._checked.add(axes)

    def where(self, i: int) -> str:
        return _where(self.table, int(self.sel[i]))


def m6_rows(table: pd.DataFrame) -> np.ndarray:
    """Row positions of the block table's tool changes (an M6 among a row's M codes)."""
    return m_code_rows(table, {6})


def _tool_changes_after(table: pd.DataFrame, sel: np.ndarray) -> np.ndarray:
    """Per motion/dwell row: the M6 blocks between it and the next such row (a tool change before the
    first motion is not counted: the machine starts with the tool in the spindle)."""
    out = np.zeros(len(sel))
    if not len(sel):
        return out
    row = np.searchsorted(sel, m6_rows(table), side="right") - 1   # the motion row each M6 follows
    np.add.at(out, row[row >= 0], 1.0)
    return out


def prepare_blocks(program, profile: MachineProfile, *, last: bool = True) -> Blocks:
    """Motion and dwell rows of the block table as `Blocks`, with axis-projected limits. `program` is a
    Program, a block table or its `ProgramArrays`. `last`: its last row is the program's last (which
    stops); a windowed simulation (feedlog.sim.window) passes False for all but the last batch."""
    arrays = program if isinstance(program, ProgramArrays) else ProgramArrays(program)
    code = arrays.code
    col = arrays.col
    where = arrays.where

    axes = profile.axis_names
    units = schema.AXIS_UNITS
    arrays.check_axes(axes, profile.name)  # an axis the machine does not have must not move
    p1 = np.column_stack([col(f"{a}_{units[a]}", np.nan) for a in axes])
    p0 = np.column_stack([col(f"{a}0_{units[a]}", np.nan) for a in axes])
    # unknown start (first move of a program): no motion on that axis
    p0 = np.where(np.isnan(p0), p1, p0)
    bad = np.isnan(p1).any(axis=1) & (code != KIND_DWELL)
    if bad.any():
        i = int(np.flatnonzero(bad)[0])
        raise SimulationError(f"{where(i)}: motion block without an end position "
                              f"for axes {', '.join(axes)}")
    p1 = np.where(np.isnan(p1), p0, p1)
    n, k = p0.shape
    lin = [i for i, a in enumerate(axes) if a in LINEAR_AXES]
    rot = [i for i, a in enumerate(axes) if a not in LINEAR_AXES]
    delta = p1 - p0
    lin_len = np.linalg.norm(delta[:, lin], axis=1)
    rot_len = np.linalg.norm(delta[:, rot], axis=1) if rot else np.zeros(n)

    # arcs: centre, plane, signed sweep, helix
    center = np.column_stack([col(c, np.nan) for c in ("cx_mm", "cy_mm", "cz_mm")])
    plane = col("plane", 17).astype(int)
    turns = np.maximum(col("turns", 1), 1)
    sweep = np.zeros(n)
    radius = np.zeros(n)
    normal_axis = np.full(n, 2, dtype=np.int8)
    is_arc = code == KIND_ARC
    ccw = arrays.ccw
    length = np.where(lin_len > EPS_LEN, lin_len, rot_len)
    ia = np.flatnonzero(is_arc)
    if len(ia):  # all arcs at once: plane axes, signed sweep (full circles, turns), helix length
        bad_arc = ~np.isin(plane[ia], list(_PLANES)) | np.isnan(center[ia]).any(axis=1)
        if bad_arc.any():
            raise SimulationError(f"{where(int(ia[np.flatnonzero(bad_arc)[0]]))}: arc without a centre or plane")
        a1, a2, nrm = _PLANE_AXES[plane[ia] - 17].T
        rows_a = np.arange(len(ia))
        xyz0, xyz1, c_a = p0[ia][:, lin], p1[ia][:, lin], center[ia]
        r0 = (xyz0[rows_a, a1] - c_a[rows_a, a1], xyz0[rows_a, a2] - c_a[rows_a, a2])
        r1 = (xyz1[rows_a, a1] - c_a[rows_a, a1], xyz1[rows_a, a2] - c_a[rows_a, a2])
        th0, th1 = np.arctan2(r0[1], r0[0]), np.arctan2(r1[1], r1[0])
        ccw_a = ccw[ia]
        d = np.where(ccw_a, (th1 - th0) % (2 * np.pi), -((th0 - th1) % (2 * np.pi)))
        d = np.where(np.abs(d) < 1e-9, np.where(ccw_a, 2 * np.pi, -2 * np.pi), d)
        d += np.sign(d) * 2 * np.pi * (turns[ia] - 1)
        radius[ia] = np.hypot(r0[0], r0[1])
        sweep[ia] = d
        normal_axis[ia] = nrm
        length[ia] = np.hypot(radius[ia] * d, xyz1[rows_a, nrm] - xyz0[rows_a, nrm])

    feed = col("feed_mm_min", np.nan) / 60.0
    rapid = code == KIND_RAPID
    feed = np.where(rapid, profile.rapid_mm_min / 60.0, feed)
    moving = (length > EPS_LEN) & (code != KIND_DWELL)
    feed = np.where(moving, feed, np.nan_to_num(feed, nan=0.0))
    bad_feed = moving & ~(feed > 0)
    if bad_feed.any():
        i = int(np.flatnonzero(bad_feed)[0])
        raise SimulationError(f"{where(i)}: feed move with no feed rate (F)")

    # axis limits projected on the block direction (lines: exact; arcs: the plane axes)
    vel = np.array([profile.axes[a].vel_max for a in axes])
    acc = np.array([profile.axes[a].acc_max for a in axes])
    v_axis, a_axis = projected_limits(delta, length, vel, acc)
    if len(ia):  # arcs: the slower of the two plane axes
        lin_arr = np.asarray(lin)
        pa, pb = lin_arr[a1], lin_arr[a2]
        v_axis[ia] = np.minimum(v_axis[ia], np.minimum(vel[pa], vel[pb]))
        a_axis[ia] = np.minimum(a_axis[ia], np.minimum(acc[pa], acc[pb]))
    interp = profile.interpolator
    is_lin = lin_len > EPS_LEN
    v_path = np.where(is_lin, interp.path_vel_max_mm_s, np.inf)
    v_limit = np.minimum(v_axis, v_path)
    a_max = np.where(np.isfinite(a_axis), a_axis, acc.min())

    extra: dict[str, np.ndarray] = {}
    mode = arrays.mode
    stop_after = (mode != 1) | (code == KIND_DWELL)
    exact_path = (mode == 2) & (code != KIND_DWELL)
    extra["continuous"] = mode == 1
    extra["tool_changes"] = arrays.tool_changes.copy()
    extra["syncs"] = arrays.syncs.copy()
    if n and last:
        stop_after[-1] = True
        exact_path[-1] = False
    hold = np.where(code == KIND_DWELL, np.nan_to_num(col("dwell_s", 0.0)), 0.0)
    length = np.where(moving, length, 0.0)
    if all(arrays.has(c) for c in ("ori_i", "ori_j", "ori_k")):
        ori = np.column_stack([col(c, np.nan) for c in ("ori_i", "ori_j", "ori_k")])
        if not np.isnan(ori).all():
            extra["ori"] = ori
    return Blocks(axes=axes, block=arrays.block.copy(), line=arrays.line.copy(),
                  kind=code, p0=p0, p1=p1, length=length, feed=feed, v_limit=v_limit, v_axis=v_axis, a_max=a_max,
                  stop_after=stop_after, exact_path=exact_path, tol=col("tol_mm", np.nan),
                  merge_tol=col("merge_tol_mm", np.nan), hold_s=hold,
                  min_time_s=np.zeros(n), rotary=rot_len > 1e-9, center=center, normal_axis=normal_axis,
                  sweep=sweep, radius=radius, extra=extra)


def feed_scale(blocks: Blocks) -> np.ndarray:
    """Per block, the factor the feed override dial applied to its programmed feed (1: none)."""
    scale = blocks.extra.get("feed_scale")
    return np.ones(len(blocks)) if scale is None else scale


def apply_feed_scale(blocks: Blocks, scale: np.ndarray) -> None:
    """Record a dial's per-block factor on top of any applied before (`feed_scale` reads the product)."""
    blocks.extra["feed_scale"] = feed_scale(blocks) * scale


def build_pieces(blocks: Blocks) -> Pieces:
    """One piece per block. Junction speeds start at 0 (stop); a corner law raises them."""
    n, k = blocks.p0.shape
    lin = blocks.linear_index
    length = blocks.length
    safe = np.where(length > 0, length, 1.0)
    direction = (blocks.p1 - blocks.p0) / safe[:, None]
    direction[length <= 0] = 0.0
    e1 = np.zeros((n, k))
    e2 = np.zeros((n, k))
    omega = np.zeros(n)
    radius = blocks.radius.copy()
    ia = np.flatnonzero(blocks.kind == KIND_ARC)
    if len(ia):  # all arcs at once
        rows_a = np.arange(len(ia))
        lin_arr = np.asarray(lin)
        nrm = blocks.normal_axis[ia].astype(np.int64)
        start = blocks.p0[ia][:, lin]
        c = blocks.center[ia].copy()
        c[rows_a, nrm] = start[rows_a, nrm]
        r0 = start - c
        u1 = r0 / np.linalg.norm(r0, axis=1)[:, None]
        nvec = np.zeros((len(ia), 3))
        nvec[rows_a, nrm] = 1.0
        e1[np.ix_(ia, lin_arr)] = u1
        e2[np.ix_(ia, lin_arr)] = np.cross(nvec, u1) * np.sign(blocks.sweep[ia])[:, None]
        omega[ia] = np.abs(blocks.sweep[ia]) / safe[ia]
        # the straight part of an arc: helix along the normal and the rotary axes
        col_n = lin_arr[nrm]
        helix = (blocks.p1[ia, col_n] - blocks.p0[ia, col_n]) / safe[ia]
        direction[np.ix_(ia, lin_arr)] = 0.0
        direction[ia, col_n] = helix
    v_max = blocks.v_max.copy()
    with np.errstate(divide="ignore", invalid="ignore"):
        v_max = np.where(blocks.min_time_s > 0, np.minimum(v_max, length / blocks.min_time_s), v_max)
    zero = np.zeros(n)
    return Pieces(block=np.arange(n), length=length.copy(), p0=blocks.p0.copy(), dir=direction, e1=e1, e2=e2,
                  radius=radius, omega=omega, v_max=v_max, a_max=blocks.a_max.copy(), v_end=zero.copy(),
                  hold_s=blocks.hold_s.copy(), blend=np.zeros(n, bool), overlap=np.zeros(n, bool),
                  clamp_len=length.copy())


def with_columns(pieces: Pieces, **changes) -> Pieces:
    return replace(pieces, **changes)
