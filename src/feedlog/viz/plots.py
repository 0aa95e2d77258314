"""The overlays as static PNG plots (matplotlib, Agg backend) for reports and the README.

Each function draws one figure from a `ViewData` (or the cycle-time table) and returns the path
it wrote. Colours match the Rerun overlays (`feedlog.colors`).
"""

from __future__ import annotations

from pathlib import Path

import matplotlib
import matplotlib.ticker

matplotlib.use("Agg")  # no display: figures only go to files

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd

from feedlog.colors import source_color
from feedlog.viz.prepare import ViewData

DPI = 100
MARKERS = ("o", "s", "^", "D", "v", "P", "X")
HOLLOW = ("hybrid",)   # sources built on another (hybrid = sim x a learned factor): rings, so the base shows


def _c(name: str, index: int = 0) -> tuple[float, float, float]:
    return tuple(v / 255 for v in source_color(name, index))


def _save(fig, path: Path) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=DPI)
    plt.close(fig)
    return path


def plot_feed(data: ViewData, path: str | Path) -> Path:
    """Path feed over time: measured, commanded F, simulated, learned; the residual below."""
    fig, (ax, res) = plt.subplots(2, 1, figsize=(10, 6), sharex=True, height_ratios=[3, 1])
    fig.subplots_adjust(left=0.09, right=0.98, top=0.94, bottom=0.09, hspace=0.08)
    m = data.measured
    t = m["t_rel_ns"].to_numpy() / 1e9
    ax.plot(t, m["feed_mm_min"], color=_c("measured"), lw=1.2, label="measured")
    if "commanded_feed_mm_min" in m.columns:
        ax.plot(t, m["commanded_feed_mm_min"], color=_c("commanded"), lw=1, ls="--", label="commanded F")
    if data.sim is not None:
        ax.plot(data.sim["t_rel_ns"] / 1e9, data.sim["feed_mm_min"], color=_c("sim"), lw=1, label="simulated")
    for i, (name, s) in enumerate(data.model_series.items()):
        ax.plot(s["t_rel_ns"] / 1e9, s["feed_mm_min"], color=_c(name, i), lw=1, label=name)
    ax.set_ylabel("path feed (mm/min)")
    ax.set_title(f"{data.name}: path feed")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    for i, (name, r) in enumerate(data.residuals.items()):
        res.plot(t, r, color=_c(name, i - 1), lw=0.8, label=f"measured - {name}")
    if data.residuals:
        res.legend(loc="upper right", fontsize=8)
    else:
        res.text(0.5, 0.5, "no prediction to compare with", ha="center", va="center", transform=res.transAxes)
    res.set_ylabel("residual (mm/min)")
    res.set_xlabel("time since program start (s)")
    res.grid(alpha=0.3)
    return _save(fig, Path(path))


def plot_axes(data: ViewData, path: str | Path) -> Path:
    """Per-axis feeds, measured vs simulated, one panel per axis."""
    fig, axs = plt.subplots(len(data.axes), 1, figsize=(10, 1.8 * len(data.axes) + 1), sharex=True, squeeze=False)
    fig.subplots_adjust(left=0.1, right=0.98, top=0.94, bottom=0.08, hspace=0.1)
    m = data.measured
    for ax, a in zip(axs[:, 0], data.axes, strict=True):
        ax.plot(m["t_rel_ns"] / 1e9, m[f"v{a}"], color=_c("measured"), lw=1, label="measured")
        if data.sim is not None and f"v{a}" in data.sim.columns:
            ax.plot(data.sim["t_rel_ns"] / 1e9, data.sim[f"v{a}"], color=_c("sim"), lw=1, label="simulated")
        ax.set_ylabel(f"{a} ({'deg' if a in 'abc' else 'mm'}/min)")
        ax.ticklabel_format(axis="y", useOffset=False)
        ax.grid(alpha=0.3)
    axs[0, 0].legend(loc="upper right", fontsize=8)
    axs[0, 0].set_title(f"{data.name}: axis feeds")
    axs[-1, 0].set_xlabel("time since program start (s)")
    return _save(fig, Path(path))


def plot_path(data: ViewData, path: str | Path) -> Path:
    """Top view (XY) of the programmed path and the measured path coloured by measured feed."""
    fig, ax = plt.subplots(figsize=(7, 6))
    fig.subplots_adjust(left=0.11, right=0.98, top=0.94, bottom=0.09)
    if data.programmed_path is not None and len(data.programmed_path):
        ax.plot(data.programmed_path["x_mm"], data.programmed_path["y_mm"], color=_c("programmed"), lw=2,
                label="programmed", zorder=1)
    m = data.measured
    pts = ax.scatter(m["x_mm"], m["y_mm"], c=m["feed_mm_min"], s=2, cmap="viridis", zorder=2, label="measured")
    fig.colorbar(pts, ax=ax, label="measured feed (mm/min)")
    if data.orientation is not None and len(data.orientation):
        o = data.orientation
        ax.quiver(o["x_mm"], o["y_mm"], o["i"], o["j"], color="tab:red", width=0.003, label="tool orientation")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (mm)")
    ax.set_ylabel("y (mm)")
    ax.set_title(f"{data.name}: toolpath (top view)")
    ax.legend(loc="best", fontsize=8)
    return _save(fig, Path(path))


def plot_block_times(data: ViewData, path: str | Path) -> Path:
    """Measured vs predicted block times: predicted over measured, with the identity line."""
    fig, ax = plt.subplots(figsize=(6, 6))
    fig.subplots_adjust(left=0.13, right=0.97, top=0.94, bottom=0.09)
    b = data.blocks
    predicted = [c for c in b.columns if c.endswith("_s") and c != "measured_s"]
    top = 0.0
    for i, col in enumerate(predicted):
        ok = b["measured_s"].notna() & b[col].notna() if "measured_s" in b.columns else b[col].isna()
        color = _c(col[:-2], i - 1)
        style = (dict(s=30, facecolors="none", edgecolors=[color], linewidths=1.0) if col[:-2] in HOLLOW
                 else dict(s=10, color=color))
        ax.scatter(b.loc[ok, "measured_s"], b.loc[ok, col], label=col[:-2], **style)
        top = max(top, float(b.loc[ok, ["measured_s", col]].to_numpy().max(initial=0.0)))
    if not predicted:
        ax.text(0.5, 0.5, "no predicted block times", ha="center", va="center", transform=ax.transAxes)
    else:
        values = b[["measured_s", *predicted]].to_numpy(dtype=np.float64) if "measured_s" in b.columns else np.array([])
        if spans_decades(values):
            low = float(values[np.isfinite(values) & (values > 0)].min())
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.plot([low, top], [low, top], color="k", lw=0.8, ls=":")
            ax.set_title(f"{data.name}: block times (log axes)")
        else:
            ax.plot([0, top], [0, top], color="k", lw=0.8, ls=":")
        ax.legend(loc="upper left", fontsize=8)
    ax.set_xlabel("measured block time (s)")
    ax.set_ylabel("predicted block time (s)")
    if not ax.get_title():
        ax.set_title(f"{data.name}: block times")
    ax.grid(alpha=0.3)
    return _save(fig, Path(path))


MAX_BARS = 30   # more programs than this: one point per program against the first source (readable at any count)


def plot_cycle_times(table: pd.DataFrame, path: str | Path) -> Path:
    """Grouped bars: cycle time per program for every source present in the table (seconds); with more
    than MAX_BARS programs, every other source against the first (usually the measured time)."""
    sources = [c for c in table.columns if c.endswith("_s") and table[c].notna().any()]
    if len(table) > MAX_BARS and len(sources) > 1:
        return _cycle_time_scatter(table, sources, Path(path))
    fig, ax = plt.subplots(figsize=(max(6, 0.5 * len(table) + 3), 5))
    fig.subplots_adjust(left=0.08, right=0.98, top=0.93, bottom=0.3)
    x = np.arange(len(table))
    width = 0.8 / max(len(sources), 1)
    for i, col in enumerate(sources):
        name = col[:-2]
        ax.bar(x + (i - (len(sources) - 1) / 2) * width, table[col].to_numpy(dtype=np.float64), width,
               label=name, color=_c(name, i - 3))
    ax.set_xticks(x, table["program"], rotation=20, ha="right")
    ax.set_ylabel("cycle time (s)")
    ax.set_title("cycle time per program")
    ax.legend(fontsize=8)
    ax.grid(axis="y", alpha=0.3)
    return _save(fig, Path(path))


def _cycle_time_scatter(table: pd.DataFrame, sources: list[str], path: Path) -> Path:
    """Left: every estimate against the reference (first source); right: its error in percent on a
    symmetric-log axis, so 0.1 % and 60 % errors both show. A source drawn as rings (`HOLLOW`) leaves the
    points it covers visible."""
    ref = sources[0]
    x = table[ref].to_numpy(dtype=np.float64)
    fig, (ax, err) = plt.subplots(1, 2, figsize=(13, 6))
    fig.subplots_adjust(left=0.06, right=0.98, top=0.9, bottom=0.16, wspace=0.22)
    for i, col in enumerate(sources[1:]):
        name = col[:-2]
        y = table[col].to_numpy(dtype=np.float64)
        color = _c(name, i - 2)
        style = (dict(s=40, facecolors="none", edgecolors=[color], linewidths=1.2) if name in HOLLOW
                 else dict(s=14, color=color))
        marker = MARKERS[i % len(MARKERS)]
        ax.scatter(x, y, marker=marker, label=name, zorder=3 + i, **style)
        with np.errstate(divide="ignore", invalid="ignore"):
            err.scatter(x, (y - x) / x * 100.0, marker=marker, label=name, zorder=3 + i, **style)
    finite = x[np.isfinite(x)]
    hi = float(finite.max()) * 1.05 if len(finite) else 1.0
    ax.plot([0, hi], [0, hi], color="0.5", lw=0.8, label=f"= {ref[:-2]}")
    ax.set_xlabel(f"{ref[:-2]} cycle time (s)")
    ax.set_ylabel("estimated cycle time (s)")
    ax.set_title(f"cycle time of {len(table)} programs against {ref[:-2]}")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    err.axhline(0.0, color="0.5", lw=0.8)
    err.set_yscale("symlog", linthresh=1.0)
    err.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(lambda v, _: f"{v:g} %"))
    err.set_xlabel(f"{ref[:-2]} cycle time (s)")
    err.set_ylabel(f"(estimate - {ref[:-2]}) / {ref[:-2]}, linear within +-1 %")
    err.set_title("error of each estimate")
    err.grid(alpha=0.3, which="both")
    hollow = [c[:-2] for c in sources[1:] if c[:-2] in HOLLOW]
    if hollow:
        fig.text(0.5, 0.02, f"{', '.join(hollow)}: rings. The hybrid is the simulation times a learned factor per "
                 "block; where it learns no correction, its rings sit around the simulation's points.",
                 ha="center", fontsize=9)
    return _save(fig, path)


def spans_decades(values: np.ndarray, decades: float = 2.0) -> bool:
    """Positive values spread over more than `decades` powers of ten: a log axis shows them, a linear one
    squashes the small ones into a corner."""
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v) & (v > 0)]
    return len(v) > 1 and float(np.log10(v.max() / v.min())) > decades


PLOTS = {"feed": plot_feed, "axes": plot_axes, "path": plot_path, "blocks": plot_block_times}


def plot_view(data: ViewData, out_dir: str | Path, *, stem: str | None = None,
              kinds: tuple[str, ...] | None = None) -> dict[str, Path]:
    """Per-recording plots (`kinds` of PLOTS, default all) into `out_dir` as `<stem>_<kind>.png`."""
    out = Path(out_dir)
    stem = stem or data.name
    unknown = set(kinds or ()) - set(PLOTS)
    if unknown:
        raise ValueError(f"unknown plot kinds {sorted(unknown)}; known: {', '.join(PLOTS)}")
    return {kind: PLOTS[kind](data, out / f"{stem}_{kind}.png") for kind in (kinds or tuple(PLOTS))}
