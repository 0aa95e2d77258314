"""Model inputs: derived columns, neighbour context, the presence check and normalisation.

Models read align's block tables, whose feature columns are `feedlog.toolpath.schema.FEATURE_COLUMNS`
(plus `duration_s`, the measured block time). A few inputs are derived here:

- `feed_eff_mm_min`: the feed the block is commanded at; rapids (and blocks without F) take
  `length_mm / nominal_time_s`, i.e. the rapid rate the toolpath stage used for CAM time.
- `tol_eff_mm`: `tol_mm` with "no tolerance" (NaN, G64 without P) as -1 so the net can tell it apart.
- `rot_dist_deg`: the largest rotary axis move of the block (|dA|, |dB|, |dC|, deg; 0 for 3-axis):
  near A = 0 a small orientation change can need a large C turn, which the rotary axis' speed limits.
  From the program (`with_program_columns`); 0 when a table lacks it.
- `limited_time_s`: the block's nominal time respecting the axes' speed limits,
  max(L / F, max over axes |d axis| / vel_max) (`axis_time_s` from `with_program_columns` with the
  machine profile; L / F when a table lacks it): where a rotary axis turns far for a short TCP move
  (near A = 0) this, not L / F, is the time scale. `log_limited_time_s` its log, `limit_ratio` its
  ratio to L / F (1 where L / F is 0).
- `exact_stop`: 1 in G61 (`tol_mm` = 0: the machine stops at every block end), else 0. The tolerance
  alone would put G61 (0) and G64 P0.01 one hundredth of a millimetre apart, under a tenth of a standard
  deviation after z-scoring, although one stops at every corner and the other blends.
- `merge_tol_eff_mm`: the G64 Q tolerance LinuxCNC's interpreter merges nearly collinear lines within
  (`merge_tol_mm` of toolpath's program table, attached by `with_program_columns`; Q0 = never merge);
  0 in G61, -1 for G64 without P. A table without `merge_tol_mm` takes Q = P (LinuxCNC's default).
- `ori_tol_deg`, `xo_mm`, `yo_mm`, `zo_mm`: machine constants from the profile (Chien Table 1:
  epsilon_ORI and the workpiece offset [Xo, Yo, Zo]); profile defaults when no profile is given.
- `log_length_mm`, `log_nominal_time_s`: log(L + 1 um), log(L/F + 0.1 ms).
- `kin_time_s`: the block's kinematic time (`feedlog.train.kinematic`: one trapezoid per block at
  the axes' acceleration and speed limits, stopping or blending at its corners, joined by
  look-ahead, blend arcs run as pieces of their own), at least `limited_time_s`; `log_kin_time_s` its log, `kin_ratio` its ratio to
  `limited_time_s`. The path limits come from the program and profile (`path_acc_mm_s2`,
  `path_vel_mm_s`; without them the profile's smallest linear acceleration and the feed).
- `<col>_prev` / `<col>_next`: the value at block n-1 / n+1 of the same program (0 beyond its ends,
  where the machine is at rest), for Sun Table 1's n-1, n, n+1 context.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import asdict, dataclass

import numpy as np
import pandas as pd

from feedlog.errors import ModelError
from feedlog.profile import MachineProfile
from feedlog.train import kinematic

AXES3 = ("x", "y", "z")
PROFILE_COLUMNS = ("ori_tol_deg", "xo_mm", "yo_mm", "zo_mm")
KIN_COLUMNS = ("length_mm", "feed_mm_min", "nominal_time_s", "tol_mm", "corner_end_deg")
NO_TOLERANCE_MM = -1.0

# derived column -> raw columns it is computed from
DERIVED: dict[str, tuple[str, ...]] = {
    "feed_eff_mm_min": ("feed_mm_min", "length_mm", "nominal_time_s"),
    "tol_eff_mm": ("tol_mm",),
    "exact_stop": ("tol_mm",),
    "merge_tol_eff_mm": ("tol_mm",),  # + merge_tol_mm when present (else Q = P)
    "rot_dist_deg": (),                 # from the program when present (else 0)
    "limited_time_s": ("nominal_time_s",),  # + axis_time_s when present
    "log_limited_time_s": ("nominal_time_s",),
    "limit_ratio": ("nominal_time_s",),
    "log_length_mm": ("length_mm",),
    "log_nominal_time_s": ("nominal_time_s",),
    "log_sim_duration_s": ("sim_duration_s",),
    # + kind, axis_time_s, rot_dist_deg, path_acc_mm_s2, path_vel_mm_s when present
    **{c: KIN_COLUMNS for c in ("kin_time_s", "log_kin_time_s", "kin_ratio")},
    **{c: () for c in PROFILE_COLUMNS},
}

# Chien Table 1 (F, L, theta_TCP,k, theta_TCP,k+1, eps_TCP, theta_k, theta_ORI,k, theta_ORI,k+1,
# eps_ORI, sin(A), [Xo, Yo, Zo]) plus the CAM time L/F of the block and the logarithms of L and L/F
# (block lengths and times span four decades: 0.01 mm segments next to 100 mm lines).
CHIEN_INPUTS = ("feed_eff_mm_min", "length_mm", "corner_start_deg", "corner_end_deg", "tol_eff_mm",
                "ori_arc_deg", "ori_corner_start_deg", "ori_corner_end_deg", "ori_tol_deg", "sin_rot",
                "xo_mm", "yo_mm", "zo_mm", "nominal_time_s", "log_length_mm", "log_nominal_time_s",
                "merge_tol_eff_mm", "rot_dist_deg", "log_limited_time_s", "exact_stop")
# program-table columns align's block tables do not carry: G64 Q, the largest rotary axis move and the
# time the slowest axis needs at its speed limit (with a profile)
PROGRAM_COLUMNS = ("merge_tol_mm", "rot_dist_deg", "axis_time_s", "path_acc_mm_s2", "path_vel_mm_s", "kink_s2_mm")
ROTARY = kinematic.ROTARY
LOG_FLOOR = {"log_length_mm": 1e-3, "log_nominal_time_s": 1e-4, "log_sim_duration_s": 1e-4,
             "log_limited_time_s": 1e-4, "log_kin_time_s": 1e-4}  # added before the log (mm, s)


def sun_inputs(axis: str) -> tuple[str, ...]:
    """Sun Table 1 for one axis: corner angles, nominal axis feed and acceleration at n-1, n, n+1.

    The corner at CL point n-1 is the block's `corner_start_deg`, at n its `corner_end_deg`, at n+1
    the next block's `corner_end_deg`.
    """
    feed, acc = f"v{axis}_nom_mm_min", f"a{axis}_nom_mm_s2"
    return ("corner_start_deg", "corner_end_deg", "corner_end_deg_next",
            f"{feed}_prev", feed, f"{feed}_next", f"{acc}_prev", acc, f"{acc}_next")


def raw_columns(inputs: Iterable[str]) -> list[str]:
    """The columns an input table must hold so that `inputs` can be built."""
    out: list[str] = []
    for name in inputs:
        base = _context_base(name)
        for col in DERIVED.get(base, (base,)):
            if col not in out:
                out.append(col)
    return out


def require(table: pd.DataFrame, columns: Iterable[str], *, what: str, source: str = "") -> None:
    """Raise ModelError naming every missing column."""
    missing = [c for c in columns if c not in table.columns]
    if missing:
        where = f"{source}: " if source else ""
        raise ModelError(f"{where}input lacks column(s) {', '.join(missing)} needed by {what}; "
                         f"it has: {', '.join(map(str, table.columns))}")


def profile_constants(profile: MachineProfile | None) -> dict[str, float]:
    """Machine constants used as inputs (Chien's eps_ORI and workpiece offset) and by `kin_time_s`
    (servo period; the smallest linear axis acceleration where a table lacks `path_acc_mm_s2`)."""
    if profile is None:
        from feedlog.profile import Interpolator, Kinematics
        interp, offset, accs = Interpolator(), Kinematics().workpiece_offset_mm, []
    else:
        interp, offset = profile.interpolator, profile.kinematics.workpiece_offset_mm
        accs = [a.acc_max for name, a in profile.axes.items() if name not in ROTARY and a.acc_max > 0]
    return {"ori_tol_deg": float(interp.orientation_tolerance_deg), "xo_mm": float(offset[0]),
            "yo_mm": float(offset[1]), "zo_mm": float(offset[2]),
            "servo_period_s": float(interp.servo_period_s), "acc_mm_s2": float(min(accs)) if accs else kinematic.BIG}


def planner_inputs(profile: MachineProfile | None) -> dict[str, float]:
    """The planner constants of `profile` (`kinematic.planner_constants`) as `kin_time_s` reads them from
    the constants it gets. They come from the table's profile every time (`Model.table_constants`), so
    they are not part of the constants a model saves."""
    return asdict(kinematic.planner_constants(profile))


def planner_of(constants: dict[str, float]) -> kinematic.PlannerConstants:
    """The planner constants in `constants` (`planner_inputs`); the mechanisms' defaults for any it lacks."""
    default = asdict(kinematic.planner_constants(None))
    return kinematic.PlannerConstants(**{key: float(constants.get(key, value)) for key, value in default.items()})


def build_inputs(table: pd.DataFrame, inputs: Sequence[str], *, constants: dict[str, float] | None = None,
                 what: str = "the model", source: str = "") -> np.ndarray:
    """The float32 matrix (rows x inputs) of one program's block table, in `inputs` order."""
    require(table, raw_columns(inputs), what=what, source=source)
    cols: dict[str, np.ndarray] = {}
    for name in inputs:
        base = _context_base(name)
        if base not in cols:
            cols[base] = _base_column(table, base, constants or {})
        values = cols[base]
        if name.endswith("_prev"):
            values = np.concatenate([[0.0], values[:-1]]) if len(values) else values
        elif name.endswith("_next"):
            values = np.concatenate([values[1:], [0.0]]) if len(values) else values
        cols[name] = values
    matrix = np.empty((len(table), len(inputs)), np.float64)
    for j, n in enumerate(inputs):
        matrix[:, j] = cols[n]
    bad = ~np.isfinite(matrix)
    if bad.any():
        row, col = np.argwhere(bad)[0]
        where = f"{source}: " if source else ""
        raise ModelError(f"{where}input column {inputs[col]!r} is not finite at row {row} "
                         f"(block {table['block'].iloc[row] if 'block' in table else row}); "
                         f"{int(bad.sum())} bad value(s) in all")
    return matrix.astype(np.float32)


def _context_base(name: str) -> str:
    for suffix in ("_prev", "_next"):
        if name.endswith(suffix):
            return name[: -len(suffix)]
    return name


def _base_column(table: pd.DataFrame, name: str, constants: dict[str, float]) -> np.ndarray:
    n = len(table)
    if name in PROFILE_COLUMNS:
        if name in table.columns:
            return table[name].to_numpy(np.float64)
        return np.full(n, constants.get(name, 0.0))
    if name == "feed_eff_mm_min":
        return effective_feed(table)
    if name in ("kin_time_s", "log_kin_time_s", "kin_ratio"):
        limited = limited_time(table)
        kin = np.maximum(_kinematic_time(table, constants), limited)
        if name == "kin_ratio":
            return np.where(limited > 0, kin / np.where(limited > 0, limited, 1.0), 1.0)
        return kin if name == "kin_time_s" else np.log(kin + LOG_FLOOR[name])
    if name in ("limited_time_s", "log_limited_time_s", "limit_ratio"):
        nominal = np.nan_to_num(table["nominal_time_s"].to_numpy(np.float64))
        limited = limited_time(table)
        if name == "limit_ratio":
            with np.errstate(divide="ignore", invalid="ignore"):
                return np.where(nominal > 0, limited / nominal, 1.0)
        return limited if name == "limited_time_s" else np.log(limited + LOG_FLOOR[name])
    if name in LOG_FLOOR:
        raw = table[DERIVED[name][0]].to_numpy(np.float64)
        return np.log(np.maximum(raw, 0.0) + LOG_FLOOR[name])
    if name == "tol_eff_mm":
        tol = table["tol_mm"].to_numpy(np.float64)
        return np.where(np.isnan(tol), NO_TOLERANCE_MM, tol)
    if name == "rot_dist_deg":
        return table[name].to_numpy(np.float64) if name in table else np.zeros(n)
    if name == "exact_stop":
        return (table["tol_mm"].to_numpy(np.float64) == 0).astype(np.float64)
    if name == "merge_tol_eff_mm":
        tol = table["tol_mm"].to_numpy(np.float64)
        merge = table["merge_tol_mm"].to_numpy(np.float64) if "merge_tol_mm" in table else tol
        merge = np.where(np.isnan(merge) & (tol == 0), 0.0, merge)  # G61: exact stop, nothing merged
        return np.where(np.isnan(merge), NO_TOLERANCE_MM, merge)
    col = table[name]
    if not pd.api.types.is_numeric_dtype(col):
        col = pd.to_numeric(col, errors="coerce")
    return col.to_numpy(np.float64)


def limited_time(table: pd.DataFrame, *, name: str = "", needed_by: str = "") -> np.ndarray:
    """Per block max(L / F, axis_time_s): the nominal time with the axes' speed limits (s).

    A table without `nominal_time_s` raises ModelError naming the table and the model that needs it.
    """
    if "nominal_time_s" not in table.columns:
        raise ModelError(f"{name}: input lacks column 'nominal_time_s' (CAM time) needed by {needed_by or 'this model'}")
    nominal = np.nan_to_num(table["nominal_time_s"].to_numpy(np.float64))
    if "axis_time_s" not in table:
        return nominal
    return np.maximum(nominal, np.nan_to_num(table["axis_time_s"].to_numpy(np.float64)))


def kin_time(table: pd.DataFrame, constants: dict[str, float] | None = None) -> np.ndarray:
    """Per block `kinematic.kinematic_time`, at least `limited_time` (s); `constants` from `profile_constants`."""
    return np.maximum(_kinematic_time(table, constants or {}), limited_time(table))


def _kinematic_time(table: pd.DataFrame, constants: dict[str, float]) -> np.ndarray:
    """`kinematic.kinematic_time` of a block table: path limits from its columns, else the constants."""
    n = len(table)
    acc = (table["path_acc_mm_s2"].to_numpy(np.float64) if "path_acc_mm_s2" in table
           else np.full(n, constants.get("acc_mm_s2", kinematic.BIG)))
    vel = table["path_vel_mm_s"].to_numpy(np.float64) if "path_vel_mm_s" in table else np.full(n, kinematic.BIG)
    rapid = (table["kind"] == "rapid").to_numpy(bool) if "kind" in table else np.zeros(n, bool)
    rotary = table["rot_dist_deg"].to_numpy(np.float64) > 0 if "rot_dist_deg" in table else None
    arc_acc = constants.get("acc_mm_s2", kinematic.BIG)  # without a profile: the blocks' own path limits
    merge = np.nan_to_num(table["merge_tol_mm"].to_numpy(np.float64)) > 0 if "merge_tol_mm" in table else None
    kink = table["kink_s2_mm"].to_numpy(np.float64) if "kink_s2_mm" in table else None
    return kinematic.kinematic_time(table["length_mm"].to_numpy(np.float64), effective_feed(table), acc, vel,
                                    table["tol_mm"].to_numpy(np.float64), table["corner_end_deg"].to_numpy(np.float64),
                                    rapid, constants.get("servo_period_s", 0.0), rotary=rotary,
                                    arc_acc=arc_acc if arc_acc < kinematic.BIG else None, merge=merge,
                                    kink=kink, planner=planner_of(constants))


def base_time(table, base: str, constants: dict[str, float], *, needed_by: str = "") -> np.ndarray:
    """The time a model's output is a factor on: "cam" (`limited_time`) or "kinematic" (`kin_time`).

    `table` is a ProgramTable; a table without `nominal_time_s` raises ModelError naming it.
    """
    if base == "cam":
        return limited_time(table.blocks, name=table.name, needed_by=needed_by)
    require(table.blocks, KIN_COLUMNS, what=f"{needed_by or 'this model'} (kinematic base time)", source=table.name)
    return kin_time(table.blocks, constants)


def with_program_columns(blocks: pd.DataFrame, program: object, profile: MachineProfile | None = None
                         ) -> pd.DataFrame:
    """`blocks` plus the program-table columns it lacks (`PROGRAM_COLUMNS`), matched on `block`.

    `program` is a parsed toolpath Program (its `.blocks` table has one row per program block);
    `axis_time_s` (max over axes of |d axis| / vel_max, program frame) needs the machine `profile`.
    """
    source = getattr(program, "blocks", None)
    if source is None or "block" not in blocks.columns:
        return blocks
    source = source.copy()
    rot = [a for a in ROTARY if f"{a}_deg" in source and f"{a}0_deg" in source]
    if rot:
        moves = np.column_stack([(source[f"{a}_deg"] - source[f"{a}0_deg"]).abs().to_numpy(np.float64) for a in rot])
        source["rot_dist_deg"] = np.nan_to_num(moves).max(axis=1)
    if profile is not None:
        times = [np.zeros(len(source))]
        for axis, limits in profile.axes.items():
            unit = "deg" if axis in ROTARY else "mm"
            end, start = f"{axis}_{unit}", f"{axis}0_{unit}"
            if end in source and start in source and limits.vel_max > 0:
                times.append(np.nan_to_num((source[end] - source[start]).abs().to_numpy(np.float64)) / limits.vel_max)
        source["axis_time_s"] = np.max(np.column_stack(times), axis=1)
        source["path_acc_mm_s2"], source["path_vel_mm_s"] = kinematic.path_limits(source, profile)
        source["kink_s2_mm"] = kinematic.junction_kink(source, profile)
    missing = [c for c in PROGRAM_COLUMNS if c not in blocks.columns and c in source]
    if not missing:
        return blocks
    extra = source[["block", *missing]].drop_duplicates("block")
    out = blocks.merge(extra, on="block", how="left")
    out.index = blocks.index
    return out


def effective_feed(table: pd.DataFrame) -> np.ndarray:
    """Commanded feed (mm/min); L / nominal time where F is absent or zero (rapids)."""
    feed = table["feed_mm_min"].to_numpy(np.float64)
    length = table["length_mm"].to_numpy(np.float64)
    nominal = table["nominal_time_s"].to_numpy(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        from_time = np.where(nominal > 0, length / nominal * 60.0, np.nan)
    rapid = (table["kind"] == "rapid").to_numpy(bool) if "kind" in table else np.zeros(len(table), bool)
    use_time = rapid | ~np.isfinite(feed) | (feed <= 0)
    out = np.where(use_time & np.isfinite(from_time), from_time, feed)
    return np.where(np.isfinite(out), out, 0.0)


@dataclass(frozen=True)
class Normaliser:
    """Per-column z-score: (x - mean) / std, std floored so constant columns map to 0.

    `apply` first clips each column to the range seen in training (`lo`, `hi`), so a program far
    outside the training data (0.01 mm segments after training on 1 mm ones) is not extrapolated
    by the network but treated like the nearest training example.
    """

    mean: tuple[float, ...]
    std: tuple[float, ...]
    lo: tuple[float, ...] | None = None
    hi: tuple[float, ...] | None = None

    @classmethod
    def fit(cls, matrix: np.ndarray, *, bounds: bool = True) -> Normaliser:
        matrix = np.asarray(matrix, np.float64)
        if matrix.ndim == 1:
            matrix = matrix[:, None]
        if len(matrix) == 0:
            raise ModelError("no training rows to compute normalisation statistics from")
        mean = matrix.mean(axis=0)
        std = matrix.std(axis=0)
        std = np.where(std > 1e-9 * np.maximum(1.0, np.abs(mean)), std, 1.0)
        if not bounds:
            return cls(tuple(float(v) for v in mean), tuple(float(v) for v in std))
        return cls(tuple(float(v) for v in mean), tuple(float(v) for v in std),
                   tuple(float(v) for v in matrix.min(axis=0)), tuple(float(v) for v in matrix.max(axis=0)))

    def apply(self, matrix: np.ndarray) -> np.ndarray:
        if self.lo is not None and self.hi is not None:
            matrix = np.clip(matrix, np.asarray(self.lo), np.asarray(self.hi))
        return ((matrix - np.asarray(self.mean, np.float32)) / np.asarray(self.std, np.float32)).astype(np.float32)

    def invert(self, values: np.ndarray) -> np.ndarray:
        return np.asarray(values, np.float64) * np.asarray(self.std) + np.asarray(self.mean)

    def to_dict(self) -> dict[str, list[float]]:
        out = {"mean": list(self.mean), "std": list(self.std)}
        if self.lo is not None and self.hi is not None:
            out |= {"lo": list(self.lo), "hi": list(self.hi)}
        return out

    @classmethod
    def from_dict(cls, data: dict) -> Normaliser:
        try:
            bounds = [tuple(float(v) for v in data[k]) if k in data else None for k in ("lo", "hi")]
            return cls(tuple(float(v) for v in data["mean"]), tuple(float(v) for v in data["std"]), *bounds)
        except (KeyError, TypeError, ValueError) as exc:
            raise ModelError(f"checkpoint normalisation statistics are malformed: {exc}") from None
