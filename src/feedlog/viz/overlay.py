"""Log a `ViewData` to Rerun: 3D paths, feed series, per-axis feeds, residuals and block times.

Recorded series go out columnar with `rr.send_columns` (one call per entity), never sample by
sample. Three timelines index the series:
- `time`: duration since the program's first block started (measured, simulated and learned align);
- `block`: the active block as a sequence, to scrub block by block;
- `path_um`: cumulative path length in micrometres, to read feeds along the path.

Entity paths (ENTITY_* below) are the contract the tests check in the saved .rrd.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
import rerun as rr
import rerun.blueprint as rrb

from feedlog.colors import feed_colors, residual_colors, source_color
from feedlog.rerun_stream import new_stream
from feedlog.viz.decimate import linear_keep, rate_keep, spacing_keep
from feedlog.viz.prepare import AXIS_COLUMNS, ViewData

TIMELINE_TIME, TIMELINE_BLOCK, TIMELINE_PATH = "time", "block", "path_um"
ENTITY_PROGRAMMED = "path/programmed"
ENTITY_MEASURED_PATH = "path/measured"
ENTITY_RESIDUAL_PATH = "path/residual"
ENTITY_TOOL = "path/tool"
ENTITY_ORIENTATION = "path/orientation"
FEED, AXES, RESIDUAL, BLOCKS = "feed", "axes", "residual", "blocks"
MAX_CLOUD_POINTS = 250_000  # static coloured path clouds are decimated above this
CLOUD_RADIUS = 0.15  # mm, the points of the coloured path clouds


class _Indexes:
    """Time columns of one source (measured, sim, ...), built once and subset per series."""

    def __init__(self, t_rel_ns, block=None, s_mm=None) -> None:
        self.t_rel_ns = np.asarray(t_rel_ns, dtype=np.int64)
        self.block = None if block is None else np.asarray(block, dtype=np.int64)
        self.path_um = None
        if s_mm is not None and np.isfinite(s_mm).all():
            self.path_um = np.rint(np.asarray(s_mm) * 1000.0).astype(np.int64)
        self._full: dict[tuple[bool, bool], list[rr.TimeColumn]] = {}

    def __call__(self, keep: np.ndarray | None, *, block: bool = True, path: bool = False) -> list[rr.TimeColumn]:
        """Time columns for the kept samples: always `time`, `block` and `path_um` when asked and known."""
        if keep is not None and keep.all():
            keep = None
        key = (block, path)
        if keep is None and key in self._full:
            return self._full[key]

        def sub(a):
            return a if keep is None else a[keep]

        cols = [rr.TimeColumn(TIMELINE_TIME, duration=sub(self.t_rel_ns).astype("timedelta64[ns]"))]
        if block and self.block is not None:
            cols.append(rr.TimeColumn(TIMELINE_BLOCK, sequence=sub(self.block)))
        if path and self.path_um is not None:
            cols.append(rr.TimeColumn(TIMELINE_PATH, sequence=sub(self.path_um)))
        if keep is None:
            self._full[key] = cols
        return cols


Style = tuple[str, tuple[int, int, int]]   # a series' legend label and colour


def _series(stream: rr.RecordingStream, entity: str, values: np.ndarray, indexes: _Indexes, *, label: str,
            color: tuple[int, int, int], counts: dict[str, int], block: bool = True, path: bool = False,
            columns: int | None = None, styles: dict[str, Style] | None = None) -> None:
    """One scalar series in one `send_columns` call (non-finite samples left out: Rerun draws a gap).
    `columns`: keep what a view that many pixels wide draws (`viz.decimate.linear_keep`). `styles`
    (None: logged with the series): the label and colour go there instead, for a blueprint to carry."""
    values = np.asarray(values, dtype=np.float64)
    keep = np.isfinite(values)
    if not keep.any():
        return
    if columns is not None:
        finite = np.flatnonzero(keep)
        shown = linear_keep(indexes.t_rel_ns[finite], values[finite], columns)
        if not shown.all():
            keep = np.zeros_like(keep)
            keep[finite[shown]] = True
    if styles is None:
        stream.log(entity, rr.SeriesLines(colors=[color], names=[label]), static=True)
    else:
        styles.setdefault(f"/{entity}", (label, color))
    stream.send_columns(entity, indexes=indexes(keep, block=block, path=path),
                        columns=rr.Scalars.columns(scalars=values if keep.all() else values[keep]))
    counts[entity] = int(keep.sum())


def log_view(data: ViewData, stream: rr.RecordingStream, *, columns: int | None = None,
             styles: dict[str, Style] | None = None) -> dict[str, int]:
    """Log every overlay of `data` to `stream`; returns entity path -> samples sent over time.

    `styles` (None: each series' legend label and colour are logged with it, a static `SeriesLines`
    per entity): a dict that collects them instead (entity path -> (label, colour), the first one
    seen kept), for `series_blueprint` to carry once for many recordings (the demo's .rrd).

    `columns` (None: every sample): each time series keeps the first, last, lowest and highest sample
    per `columns`-th of its time span (what a view that many pixels wide draws; straight stretches
    only their ends: `viz.decimate.linear_keep`), the moving tool one position per display frame
    (`rate_keep`) and the coloured path clouds a point per pixel of the 3D view beside the series views
    (2/3 of `columns`) along the path, at least a point diameter apart (`spacing_keep`)."""
    counts: dict[str, int] = {}
    m = data.measured
    measured = _Indexes(m["t_rel_ns"].to_numpy(), m["block"].to_numpy(), m["s_mm"].to_numpy())
    xyz = m[["x_mm", "y_mm", "z_mm"]].to_numpy(dtype=np.float32)

    # 3D: programmed path, measured path coloured by feed (and residual), moving tool, orientation
    if data.programmed_path is not None and len(data.programmed_path):
        pts = data.programmed_path[["x_mm", "y_mm", "z_mm"]].to_numpy(dtype=np.float32)
        stream.log(ENTITY_PROGRAMMED, rr.LineStrips3D([pts], colors=[source_color("programmed")], radii=[0.05]),
                   static=True)
    step = max(1, -(-len(m) // MAX_CLOUD_POINTS))  # the static clouds are views, not data: cap their size
    # downsampled: a point per pixel of the 3D view (2 shares of the width beside the series views' 3),
    # never closer than touching spheres (a diameter apart: still a continuous band)
    cloud = (slice(None, None, step) if columns is None
             else spacing_keep(xyz, columns * 2 // 3, min_step=2 * CLOUD_RADIUS))
    stream.log(ENTITY_MEASURED_PATH, rr.Points3D(xyz[cloud], colors=feed_colors(m["feed_mm_min"].to_numpy()[cloud]),
                                                 radii=[CLOUD_RADIUS]), static=True)
    if data.model_series or data.sim is not None:
        first = next(iter(data.model_series), "sim")
        stream.log(ENTITY_RESIDUAL_PATH, rr.Points3D(xyz[cloud], colors=residual_colors(data.residuals[first][cloud]),
                                                     radii=[CLOUD_RADIUS]), static=True)
    tool = None if columns is None else rate_keep(measured.t_rel_ns)
    stream.send_columns(ENTITY_TOOL, indexes=measured(tool),
                        columns=rr.Points3D.columns(positions=xyz if tool is None else xyz[tool]))
    counts[ENTITY_TOOL] = len(m) if tool is None else int(tool.sum())
    if data.orientation is not None and len(data.orientation):
        o = data.orientation
        scale = max(float(np.ptp(xyz, axis=0).max()) * 0.05, 1.0)
        stream.log(ENTITY_ORIENTATION, rr.Arrows3D(origins=o[["x_mm", "y_mm", "z_mm"]].to_numpy(np.float32),
                                                   vectors=o[["i", "j", "k"]].to_numpy(np.float32) * scale,
                                                   colors=[(200, 60, 60)]), static=True)

    # path feed: measured, commanded, simulated, learned (over time, block and path length)
    _series(stream, f"{FEED}/measured", m["feed_mm_min"].to_numpy(), measured, label="measured",
            color=source_color("measured"), counts=counts, path=True, columns=columns, styles=styles)
    if "commanded_feed_mm_min" in m.columns:
        _series(stream, f"{FEED}/commanded", m["commanded_feed_mm_min"].to_numpy(), measured,
                label="commanded F", color=source_color("commanded"), counts=counts, path=True, columns=columns, styles=styles)
    if data.sim is not None:
        s = data.sim
        sim = _Indexes(s["t_rel_ns"].to_numpy(), s["block"].to_numpy(), s["s_mm"].to_numpy())
        _series(stream, f"{FEED}/sim", s["feed_mm_min"].to_numpy(), sim, label="simulated",
                color=source_color("sim"), counts=counts, path=True, columns=columns, styles=styles)
        for a in data.axes:
            if f"v{a}" in s.columns:
                _series(stream, f"{AXES}/{a}/sim", s[f"v{a}"].to_numpy(), sim, label=f"{a} simulated",
                        color=source_color("sim"), counts=counts, block=False, columns=columns, styles=styles)
    for i, (name, series) in enumerate(data.model_series.items()):
        _series(stream, f"{FEED}/{name}", series["feed_mm_min"].to_numpy(), _Indexes(series["t_rel_ns"].to_numpy()),
                label=name, color=source_color(name, i), counts=counts, columns=columns, styles=styles)

    # per-axis feeds (over time) and residuals (over time and block)
    for a in data.axes:
        unit = "deg/min" if AXIS_COLUMNS[a].endswith("deg") else "mm/min"
        _series(stream, f"{AXES}/{a}/measured", m[f"v{a}"].to_numpy(), measured,
                label=f"{a} measured ({unit})", color=source_color("measured"), counts=counts, block=False, columns=columns, styles=styles)
    for i, (name, residual) in enumerate(data.residuals.items()):
        _series(stream, f"{RESIDUAL}/{name}", residual, measured, label=f"measured - {name}",
                color=source_color(name, i - 1), counts=counts, columns=columns, styles=styles)

    # per block: measured vs predicted block times, on the block timeline and at the block's start time
    _log_blocks(data, stream, counts, columns, styles)
    return counts


def _log_blocks(data: ViewData, stream: rr.RecordingStream, counts: dict[str, int], columns: int | None,
                styles: dict[str, Style] | None) -> None:
    blocks = data.blocks
    if not len(blocks):
        return
    t_start = blocks["t_start_rel_ns"].to_numpy(dtype=np.float64)  # NaN: a block only predicted, never measured
    has_time = np.isfinite(t_start)
    if not has_time.any():
        return
    index = _Indexes(t_start[has_time].astype(np.int64), blocks["block"].to_numpy(dtype=np.int64)[has_time])
    for i, col in enumerate(c for c in blocks.columns if c.endswith("_s")):
        _series(stream, f"{BLOCKS}/{col[:-2]}", blocks[col].to_numpy(dtype=np.float64)[has_time], index,
                label=f"{col[:-2]} block time (s)", color=source_color(col[:-2], i - 2), counts=counts,
                columns=columns, styles=styles)


def view_blueprint(data: ViewData) -> rrb.Blueprint:
    """The default layout: 3D paths left, feeds/axes/residuals/blocks right."""
    return series_blueprint(data.axes, residuals=bool(data.residuals), title=f"{data.name}: toolpath")


def series_blueprint(axes: Sequence[str], *, residuals: bool, title: str,
                     styles: Mapping[str, Style] | None = None) -> rrb.Blueprint:
    """3D paths left; path feed, a tab per axis in `axes`, residuals and block times right. The views'
    origins are relative entity paths (`/feed`, `/axes/x`, ...): the layout fits every recording that
    logs them, so one blueprint serves many recordings of one application id. `styles` (entity path ->
    (label, colour), from `log_view(styles=...)`): each series' legend label and colour, as view overrides."""
    styles = styles or {}

    def view(origin: str, name: str) -> rrb.TimeSeriesView:
        inside = {path: rr.SeriesLines(colors=[color], names=[label]) for path, (label, color) in sorted(styles.items())
                  if path.startswith(f"{origin}/")}
        return rrb.TimeSeriesView(origin=origin, name=name, overrides=inside or None)

    series_views = [view(f"/{FEED}", "path feed (mm/min)"),
                    rrb.Tabs(*[view(f"/{AXES}/{a}", f"{a} feed") for a in axes], name="axis feeds")]
    if residuals:
        series_views.append(view(f"/{RESIDUAL}", "feed residual (mm/min)"))
    series_views.append(view(f"/{BLOCKS}", "block times (s)"))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial3DView(origin="/path", name=title),
            rrb.Vertical(*series_views),
            column_shares=[2, 3],
        ),
        rrb.TimePanel(timeline=TIMELINE_TIME),
        collapse_panels=False,
    )


def save_view(data: ViewData, path: str | Path, *, columns: int | None = None) -> dict[str, int]:
    """Write `data` with its blueprint to an .rrd file; returns entity -> samples sent over time
    (`columns`: downsampled as in `log_view`)."""
    stream = new_stream(data.name)
    stream.save(str(path), default_blueprint=view_blueprint(data))
    try:
        stream.send_recording_name(data.name)
        counts = log_view(data, stream, columns=columns)
    finally:
        stream.flush()
        stream.disconnect()
    return counts
