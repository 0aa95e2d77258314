"""Colours of every feedlog view (viz's Rerun overlays and PNG plots, diagnose's report and diagnose.rrd),
computed in numpy from matplotlib colormaps (Rerun's points take colours, not colormaps)."""

from __future__ import annotations

import numpy as np
from matplotlib import colormaps

# one colour per source, shared by the Rerun overlays and the PNG plots (RGB 0-255)
SOURCE_COLORS: dict[str, tuple[int, int, int]] = {
    "measured": (31, 119, 180),
    "commanded": (127, 127, 127),
    "sim": (255, 127, 14),
    "programmed": (160, 160, 160),
}
_MODEL_COLORS = [(44, 160, 44), (214, 39, 40), (148, 103, 189), (140, 86, 75), (227, 119, 194), (23, 190, 207)]


def source_color(name: str, index: int = 0) -> tuple[int, int, int]:
    """Colour of a named source; models take colours in order of `index`."""
    return SOURCE_COLORS.get(name, _MODEL_COLORS[index % len(_MODEL_COLORS)])


def to_rgb8(values: np.ndarray, *, vmin: float, vmax: float, cmap: str = "viridis") -> np.ndarray:
    """Map values to uint8 RGB through a matplotlib colormap; NaN becomes mid grey."""
    values = np.asarray(values, dtype=np.float64)
    span = vmax - vmin if vmax > vmin else 1.0
    scaled = np.clip((values - vmin) / span, 0.0, 1.0)
    rgb = (colormaps[cmap](np.nan_to_num(scaled, nan=0.0))[:, :3] * 255).astype(np.uint8)
    rgb[~np.isfinite(values)] = (128, 128, 128)
    return rgb


def feed_colors(feed_mm_min: np.ndarray) -> np.ndarray:
    """Colours for a feed: 0 to the 99th percentile on viridis."""
    finite = np.asarray(feed_mm_min)[np.isfinite(feed_mm_min)]
    top = float(np.percentile(finite, 99)) if len(finite) else 1.0
    return to_rgb8(feed_mm_min, vmin=0.0, vmax=top)


def residual_colors(residual_mm_min: np.ndarray) -> np.ndarray:
    """Colours for a residual, symmetric around 0 on a diverging map (blue: slower than predicted)."""
    finite = np.abs(np.asarray(residual_mm_min)[np.isfinite(residual_mm_min)])
    top = float(np.percentile(finite, 99)) if len(finite) else 1.0
    top = top if top > 0 else 1.0
    return to_rgb8(residual_mm_min, vmin=-top, vmax=top, cmap="coolwarm")
