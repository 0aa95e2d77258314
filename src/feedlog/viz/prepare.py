"""Turn a recording, its program, a simulation and model predictions into plot-ready tables.

Everything viz shows (the Rerun overlays and the PNG plots) is drawn from one `ViewData`, built
here with vectorized numpy/pandas. Time is put on one axis for all sources: nanoseconds since the
program's first motion block started (`t_rel_ns`), so that measured, simulated and learned feeds
overlay even though the recording's clock and the simulation's clock differ.

Inputs are plain tables (the contracts of docs/architecture.md), not stage classes, so viz does not
need the other stages to be importable:
- program blocks: the toolpath block table (`block`, `line`, `kind`, `feed_mm_min`, ...);
- programmed path: `cl_points` (`block`, `x_mm`, `y_mm`, `z_mm`, ...);
- simulation: `SimResult.series` (`t_ns`, axis positions, `feed_mm_min`, `block`) and `.blocks`;
- measured blocks: align's block table (`block`, `t_start_ns`, `t_end_ns`, `duration_s`);
- a model prediction: per-block times (`block`, `duration_s`) and/or a feed series
  (`t_ns` from program start, `feed_mm_min`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from feedlog.errors import FeedlogError
from feedlog.recording import Recording

LINEAR = ("x", "y", "z")
ROTARY = ("a", "b", "c")
AXIS_COLUMNS = {"x": "x_mm", "y": "y_mm", "z": "z_mm", "a": "a_deg", "b": "b_deg", "c": "c_deg"}


@dataclass
class ModelPrediction:
    """What one learned model predicts for the recording's program."""

    name: str
    blocks: pd.DataFrame | None = None   # block, duration_s
    series: pd.DataFrame | None = None   # t_ns (since program start), feed_mm_min
    cycle_time_s: float | None = None

    def __post_init__(self) -> None:
        if not self.name or not self.name.replace("_", "").replace("-", "").isalnum():
            raise FeedlogError(f"model name {self.name!r} must be letters, digits, '-' or '_'")
        if self.blocks is not None and not {"block", "duration_s"} <= set(self.blocks.columns):
            raise FeedlogError(f"model {self.name}: block table needs 'block' and 'duration_s', "
                               f"got {list(self.blocks.columns)}")
        if self.series is not None and not {"t_ns", "feed_mm_min"} <= set(self.series.columns):
            raise FeedlogError(f"model {self.name}: series needs 't_ns' and 'feed_mm_min', "
                               f"got {list(self.series.columns)}")


@dataclass
class ViewInputs:
    """Everything that can be overlaid on one recording; all but the recording are optional."""

    recording: Recording
    name: str = "recording"
    program_blocks: pd.DataFrame | None = None
    program_path: pd.DataFrame | None = None
    sim_series: pd.DataFrame | None = None
    sim_blocks: pd.DataFrame | None = None
    measured_blocks: pd.DataFrame | None = None
    models: list[ModelPrediction] = field(default_factory=list)
    rapid_mm_min: float | None = None
    arrow_every: int = 50

    def __post_init__(self) -> None:
        if self.arrow_every < 1:
            raise FeedlogError(f"arrow_every must be >= 1, got {self.arrow_every}")
        names = [m.name for m in self.models]
        if len(set(names)) != len(names) or "sim" in names or "measured" in names:
            raise FeedlogError(f"model names must be unique and not 'sim'/'measured', got {names}")


@dataclass
class ViewData:
    """Plot-ready tables. Feeds in mm/min, axis velocities in mm/min (deg/min for rotary axes)."""

    name: str
    axes: tuple[str, ...]
    measured: pd.DataFrame            # t_ns, t_rel_ns, <axis cols>, v<axis>, feed_mm_min, s_mm, block, commanded_feed_mm_min
    blocks: pd.DataFrame              # block, measured_s, sim_s?, <model>_s, line?, t_start_rel_ns
    programmed_path: pd.DataFrame | None
    sim: pd.DataFrame | None          # t_rel_ns, <axis cols>, v<axis>, feed_mm_min, s_mm, block
    model_series: dict[str, pd.DataFrame]   # name -> t_rel_ns, feed_mm_min
    residuals: dict[str, np.ndarray]  # predictor name -> measured - predicted feed at measured samples
    orientation: pd.DataFrame | None  # decimated: x_mm, y_mm, z_mm, i, j, k (five-axis only)
    notes: list[str] = field(default_factory=list)

    @property
    def predictors(self) -> list[str]:
        """Names of the feed predictors available, in display order."""
        return (["sim"] if self.sim is not None else []) + list(self.model_series)


def axis_velocities(t_ns: np.ndarray, positions: np.ndarray) -> np.ndarray:
    """Per-axis velocity per minute (positions per minute) by central differences on the real time stamps."""
    if len(t_ns) < 2:
        return np.zeros_like(positions, dtype=np.float64)
    t_s = (np.asarray(t_ns, dtype=np.int64) - int(t_ns[0])) / 1e9
    dt = np.diff(t_s)
    if np.any(dt <= 0):
        # duplicate time stamps: keep the first value, differentiate on the strictly increasing rest
        keep = np.concatenate([[True], dt > 0])
        vel = np.full_like(positions, np.nan, dtype=np.float64)
        vel[keep] = axis_velocities(np.asarray(t_ns)[keep], positions[keep])
        return pd.DataFrame(vel).ffill().to_numpy()
    return np.gradient(positions, t_s, axis=0) * 60.0


def path_length_mm(positions_mm: np.ndarray) -> np.ndarray:
    """Cumulative Cartesian path length along a polyline (first point = 0)."""
    if len(positions_mm) == 0:
        return np.zeros(0)
    steps = np.linalg.norm(np.diff(positions_mm, axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(steps)])


def tool_orientation(a_deg: np.ndarray, c_deg: np.ndarray) -> np.ndarray:
    """Tool orientation (i, j, k) in workpiece coordinates of an AC table machine (Chien 2024, Eq. 7)."""
    a, c = np.radians(a_deg), np.radians(c_deg)
    return np.column_stack([np.sin(a) * np.sin(c), np.sin(a) * np.cos(c), np.cos(a)])


def _measured_table(recording: Recording) -> tuple[pd.DataFrame, tuple[str, ...]]:
    axes_table = recording.stream("axes")
    axes = tuple(a for a in LINEAR + ROTARY if AXIS_COLUMNS[a] in axes_table.columns)
    if not all(a in axes for a in LINEAR):
        raise FeedlogError(f"{recording.source or 'recording'}: stream 'axes' needs x_mm, y_mm and z_mm, "
                           f"has {list(axes_table.columns)}")
    if len(axes_table) < 2:
        raise FeedlogError(f"{recording.source or 'recording'}: stream 'axes' has {len(axes_table)} samples; "
                           "need at least 2 to show motion")
    cols = [AXIS_COLUMNS[a] for a in axes]
    table = axes_table[["t_ns", *cols]].reset_index(drop=True).copy()
    t_ns = table["t_ns"].to_numpy()
    pos = table[cols].to_numpy(dtype=np.float64)
    vel = axis_velocities(t_ns, pos)
    for i, a in enumerate(axes):
        table[f"v{a}"] = vel[:, i]
    derived = np.linalg.norm(vel[:, :3], axis=1)
    feed_stream = recording.streams.get("feed")
    if feed_stream is not None and "feed_mm_min" in feed_stream.columns and len(feed_stream):
        # the controller's own path feed, held to each axis sample
        merged = pd.merge_asof(table[["t_ns"]], feed_stream[["t_ns", "feed_mm_min"]], on="t_ns", direction="nearest")
        table["feed_mm_min"] = merged["feed_mm_min"].to_numpy(dtype=np.float64)
        table["feed_source"] = "feed stream"
    else:
        table["feed_mm_min"] = derived
        table["feed_source"] = "axis positions"
    table["s_mm"] = path_length_mm(pos[:, :3])
    return table, axes


def _attach_blocks(table: pd.DataFrame, recording: Recording, program_blocks: pd.DataFrame | None,
                   measured_blocks: pd.DataFrame | None) -> None:
    """Active block per measured sample: align's block intervals when given, else the `line` stream."""
    t = table["t_ns"].to_numpy()
    block = np.full(len(t), -1, dtype=np.int64)
    if measured_blocks is not None and len(measured_blocks):
        mb = measured_blocks.sort_values("t_start_ns")
        starts = mb["t_start_ns"].to_numpy(dtype=np.int64)
        idx = np.searchsorted(starts, t, side="right") - 1
        inside = (idx >= 0) & (t <= mb["t_end_ns"].to_numpy(dtype=np.int64)[np.clip(idx, 0, None)])
        block[inside] = mb["block"].to_numpy(dtype=np.int64)[idx[inside]]
    elif program_blocks is not None and "line" in recording.streams and len(recording.streams["line"]):
        lines = pd.merge_asof(table[["t_ns"]], recording.streams["line"][["t_ns", "line"]], on="t_ns",
                              direction="backward")["line"]
        line_to_block = program_blocks.drop_duplicates("line").set_index("line")["block"]
        mapped = lines.map(line_to_block)
        ok = mapped.notna().to_numpy()
        block[ok] = mapped[ok].to_numpy(dtype=np.int64)
    table["block"] = block


def measured_block_times(table: pd.DataFrame) -> pd.DataFrame:
    """Block start/end/duration from the per-sample active block (consecutive runs of one block)."""
    b = table["block"].to_numpy()
    t = table["t_ns"].to_numpy()
    if len(b) == 0:
        return pd.DataFrame({"block": [], "t_start_ns": [], "t_end_ns": [], "duration_s": []})
    change = np.flatnonzero(np.diff(b) != 0) + 1
    starts = np.concatenate([[0], change])
    ends = np.concatenate([change, [len(b)]])
    # a block ends where the next one starts (the last one at its last sample)
    t_end = np.where(ends < len(b), t[np.minimum(ends, len(b) - 1)], t[-1])
    runs = pd.DataFrame({"block": b[starts], "t_start_ns": t[starts], "t_end_ns": t_end})
    runs = runs[runs["block"] >= 0]
    runs = runs.groupby("block", as_index=False).agg(t_start_ns=("t_start_ns", "min"), t_end_ns=("t_end_ns", "max"))
    runs["duration_s"] = (runs["t_end_ns"] - runs["t_start_ns"]) / 1e9
    return runs


def _sim_table(sim_series: pd.DataFrame, sim_blocks: pd.DataFrame | None, axes: tuple[str, ...]) -> pd.DataFrame:
    sim = sim_series.reset_index(drop=True).copy()
    if "t_ns" not in sim.columns or "feed_mm_min" not in sim.columns:
        raise FeedlogError(f"simulation series needs 't_ns' and 'feed_mm_min', got {list(sim.columns)}")
    t0 = int(sim["t_ns"].iloc[0])
    if sim_blocks is not None and len(sim_blocks):
        t0 = int(sim_blocks["t_start_ns"].min())
    sim["t_rel_ns"] = sim["t_ns"].to_numpy(dtype=np.int64) - t0
    cols = [AXIS_COLUMNS[a] for a in axes if AXIS_COLUMNS[a] in sim.columns]
    if cols:
        vel = axis_velocities(sim["t_ns"].to_numpy(), sim[cols].to_numpy(dtype=np.float64))
        for i, c in enumerate(cols):
            sim[f"v{c.split('_')[0]}"] = vel[:, i]
    lin = [c for c in ("x_mm", "y_mm", "z_mm") if c in sim.columns]
    sim["s_mm"] = path_length_mm(sim[lin].to_numpy(dtype=np.float64)) if len(lin) == 3 else np.nan
    if "block" not in sim.columns:
        sim["block"] = -1
    return sim


def _commanded_feed(table: pd.DataFrame, program_blocks: pd.DataFrame, rapid_mm_min: float | None) -> np.ndarray:
    pb = program_blocks.set_index("block")
    feed = pb["feed_mm_min"].astype(np.float64).copy()
    if "kind" in pb.columns:
        rapid = (pb["kind"].astype(str) == "rapid").to_numpy()
        feed[rapid] = np.nan if rapid_mm_min is None else rapid_mm_min
    return table["block"].map(feed).to_numpy(dtype=np.float64)


def _block_table(table: pd.DataFrame, inputs: ViewInputs, t_start_ns: int) -> pd.DataFrame:
    measured = (inputs.measured_blocks if inputs.measured_blocks is not None else measured_block_times(table))
    blocks = measured[["block", "duration_s"]].rename(columns={"duration_s": "measured_s"})
    # where each block started, on the common time axis (blocks too short to hold a sample keep theirs)
    blocks["t_start_rel_ns"] = measured["t_start_ns"].to_numpy(dtype=np.int64) - t_start_ns
    if inputs.sim_blocks is not None and len(inputs.sim_blocks):
        blocks = blocks.merge(inputs.sim_blocks[["block", "duration_s"]].rename(columns={"duration_s": "sim_s"}),
                              on="block", how="outer")
    for model in inputs.models:
        if model.blocks is not None:
            blocks = blocks.merge(model.blocks[["block", "duration_s"]]
                                  .rename(columns={"duration_s": f"{model.name}_s"}), on="block", how="outer")
    if inputs.program_blocks is not None:
        blocks = blocks.merge(inputs.program_blocks[["block", "line"]], on="block", how="left")
    blocks = blocks.sort_values("block").reset_index(drop=True)
    blocks = blocks[[c for c in blocks.columns if c != "t_start_rel_ns"] + ["t_start_rel_ns"]]
    blocks["block"] = blocks["block"].astype(np.int64)
    return blocks


def prepare_view(inputs: ViewInputs) -> ViewData:
    """Build every plot-ready table once; both the Rerun overlays and the PNG plots draw from it."""
    notes: list[str] = []
    table, axes = _measured_table(inputs.recording)
    if table["feed_source"].iloc[0] == "axis positions":
        notes.append("measured feed derived from axis positions (the recording has no feed stream)")
    table = table.drop(columns="feed_source")
    _attach_blocks(table, inputs.recording, inputs.program_blocks, inputs.measured_blocks)
    started = table["block"].to_numpy() >= 0
    t_start = int(table["t_ns"].to_numpy()[started][0]) if started.any() else int(table["t_ns"].iloc[0])
    if not started.any():
        notes.append("no block could be matched to the measured samples: time counts from the recording start")
    table["t_rel_ns"] = table["t_ns"].to_numpy(dtype=np.int64) - t_start
    if inputs.program_blocks is not None:
        table["commanded_feed_mm_min"] = _commanded_feed(table, inputs.program_blocks, inputs.rapid_mm_min)

    sim = None
    if inputs.sim_series is not None and len(inputs.sim_series):
        sim = _sim_table(inputs.sim_series, inputs.sim_blocks, axes)

    model_series: dict[str, pd.DataFrame] = {}
    for model in inputs.models:
        if model.series is not None and len(model.series):
            s = model.series.sort_values("t_ns")
            model_series[model.name] = pd.DataFrame({"t_rel_ns": s["t_ns"].to_numpy(dtype=np.int64),
                                                     "feed_mm_min": s["feed_mm_min"].to_numpy(dtype=np.float64)})

    residuals: dict[str, np.ndarray] = {}
    t_rel = table["t_rel_ns"].to_numpy(dtype=np.float64)
    measured_feed = table["feed_mm_min"].to_numpy()
    predictors = ([("sim", sim)] if sim is not None else []) + list(model_series.items())
    for name, pred in predictors:
        tp = pred["t_rel_ns"].to_numpy(dtype=np.float64)
        fp = np.interp(t_rel, tp, pred["feed_mm_min"].to_numpy(dtype=np.float64), left=np.nan, right=np.nan)
        residuals[name] = measured_feed - fp

    orientation = None
    if "a_deg" in table.columns and "c_deg" in table.columns:
        sel = table.iloc[:: inputs.arrow_every]
        ori = tool_orientation(sel["a_deg"].to_numpy(), sel["c_deg"].to_numpy())
        orientation = pd.DataFrame({"x_mm": sel["x_mm"].to_numpy(), "y_mm": sel["y_mm"].to_numpy(),
                                    "z_mm": sel["z_mm"].to_numpy(), "i": ori[:, 0], "j": ori[:, 1], "k": ori[:, 2]})

    return ViewData(name=inputs.name, axes=axes, measured=table, blocks=_block_table(table, inputs, t_start),
                    programmed_path=inputs.program_path, sim=sim, model_series=model_series,
                    residuals=residuals, orientation=orientation, notes=notes)
