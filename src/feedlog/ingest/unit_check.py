"""Does the recorded path feed agree with the speed the positions show? A unit check at import.

Controllers report feed in mm/min, mm/s, in/min or their own units, and exports rarely say which; a
wrong `--feed-unit` (or `--length-unit`) is off by a factor such as 60 or 25.4 everywhere. The
positions are a second witness: their derivative is the path speed. `feed_unit_check` compares the
`feed` stream's `feed_mm_min` with the speed of x/y/z where the tool moves and, when the two disagree by
more than 25 % in the median, says by what factor and which declared unit would explain it. It never
changes the data: units stay declared, this only warns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feedlog.recording import Recording

TOLERANCE = 1.25     # median ratio within 1/1.25 .. 1.25: the units agree
MIN_SAMPLES = 5      # moving samples needed to say anything
# factor (feed column / position speed) -> the likely mistake
EXPLANATIONS = {
    1 / 60: "the feed column is per second, not per minute (--feed-unit mm/s, or in/s)",
    60.0: "the feed column is per minute, not per second (--feed-unit mm/min, or in/min)",
    1 / 25.4: "the feed column is in inches (--feed-unit in/min), or the positions are not in inches",
    25.4: "the positions are in inches (--length-unit in), or the feed column is not",
    1 / 1000: "the feed column is in m/min or the positions in um (check --feed-unit / --length-unit)",
    1000.0: "the positions are in m, or the feed column in um/min (check --length-unit / --feed-unit)",
}


@dataclass(frozen=True)
class UnitCheck:
    ratio: float          # median of feed column / position speed over moving samples
    samples: int
    warning: str | None   # None: the units agree

    def as_dict(self) -> dict:
        return {"ratio": self.ratio, "samples": self.samples, "warning": self.warning}


def feed_unit_check(recording: Recording, *, positions: str = "axes", feed: str = "feed") -> UnitCheck | None:
    """Compare the recorded path feed with the positions' speed; None when the recording lacks either."""
    axes, stream = recording.streams.get(positions), recording.streams.get(feed)
    if axes is None or stream is None or "feed_mm_min" not in stream.columns or len(axes) < 3 or len(stream) < 2:
        return None
    cols = [c for c in ("x_mm", "y_mm", "z_mm") if c in axes.columns]
    if not cols:
        return None
    t = axes["t_ns"].to_numpy(dtype=np.int64)
    p = axes[cols].to_numpy(dtype=np.float64)
    dt = np.diff(t) / 1e9
    ok = dt > 0
    if ok.sum() < MIN_SAMPLES:
        return None
    speed = np.linalg.norm(np.diff(p, axis=0)[ok], axis=1) / dt[ok] * 60.0   # mm/min between samples
    mid = (t[:-1][ok] + t[1:][ok]) // 2
    ft = stream["t_ns"].to_numpy(dtype=np.int64)
    fv = stream["feed_mm_min"].to_numpy(dtype=np.float64)
    feed_mid = np.interp((mid - ft[0]).astype(np.float64), (ft - ft[0]).astype(np.float64), fv)
    # moving on both witnesses, away from the starts and stops where averages over a sample lag
    moving = (speed > 0.2 * np.percentile(speed, 95)) & (feed_mid > 0.2 * np.percentile(np.abs(fv), 95))
    if moving.sum() < MIN_SAMPLES:
        return None
    ratio = float(np.median(feed_mid[moving] / speed[moving]))
    n = int(moving.sum())
    if 1 / TOLERANCE <= ratio <= TOLERANCE or not math.isfinite(ratio) or ratio <= 0:
        return UnitCheck(ratio, n, None)
    factor, why = min(EXPLANATIONS.items(), key=lambda kv: abs(math.log(ratio / kv[0])))
    text = (f"the feed column reads {ratio:.4g} x the path speed of the positions (median over {n} moving "
            "samples): ")
    if abs(math.log(ratio / factor)) < math.log(TOLERANCE):
        text += f"{why}"
    else:
        text += "check the declared --feed-unit and --length-unit (or the feed is not the path feed)"
    return UnitCheck(ratio, n, text)
