"""Does the recorded path feed agree with the speed the positions show? A unit check at import.

Controllers report feed in mm/min, mm/s, in/min or their own units, and exports rarely say which; a
wrong `--feed-unit` (or `--length-unit`) is off by a factor such as 60 or 25.4 everywhere. The
positions are a second witness: their derivative is the path speed. `feed_unit_check` compares the
`feed` stream's `feed_mm_min` with the speed of x/y/z where the tool moves and, when the two disagree by
more than 25 % in the median, says by what factor and which declared unit would explain it. It never
changes the data: units stay declared, this only warns. `feed_unit_checks` does the same for every
feed-like column (`feed_mm_min`, the path feed, and `requested_feed_mm_min`, the programmed one, which
is only warned about when a unit mistake explains it: a programmed feed is often not reached).

The positions are a witness only where they are sampled densely: a log that reports positions when they
change, about once a second (the NIST test bed's Mazak), averages reversals and stops into each
interval, so its speeds are far below the feed (the Mazak's day read 22.9 x, "inches", while its feed
column agrees with the axis feed rates to the 5.08 x of a unit conversion). When the moving samples are
further apart than `MAX_WITNESS_DT_S` in the median, or rounded so coarsely that one step per sample
is more than `COARSE_SHARE` of the feed (the UMich CSVs: 1 mm steps at 10 Hz, 10 mm/s, against feeds of
6-50 mm/s), the check says it cannot judge instead of naming a unit.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from feedlog.ingest.position_steps import PositionSteps
from feedlog.recording import Recording

TOLERANCE = 1.25     # median ratio within 1/1.25 .. 1.25: the units agree
MIN_SAMPLES = 5      # moving samples needed to say anything
MAX_PAIRS = 200_000  # samples (or consecutive pairs) looked at, evenly spread over a long recording
COARSE_SHARE = 0.25  # positions whose step per sample exceeds this share of the feed cannot judge its unit
MAX_WITNESS_DT_S = 0.5  # positions further apart than this (median, while moving) cannot judge a feed's unit
# factor (feed column / position speed) -> the likely mistake
EXPLANATIONS = {
    1 / 60: "the feed column is per second, not per minute (--feed-unit mm/s, or in/s)",
    60.0: "the feed column is per minute, not per second (--feed-unit mm/min, or in/min)",
    1 / 25.4: "the feed column is in inches (--feed-unit in/min), or the positions are not in inches",
    25.4: "the positions are in inches (--length-unit in), or the feed column is not",
    304.8 / 60: "5.08 is the ft/min -> mm/s factor: a conversion applied to a value already in mm/s (an "
                "MTConnect device file declaring nativeUnits FOOT/MINUTE, as the NIST test bed's Mazak has)?",
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


VELOCITY_STREAM = "velocity"    # the controller's axis velocities, mm/s (targets vx/vy/vz: X1_ActualVelocity, Xfrt)
VELOCITY_COLUMNS = ("x_mm_s", "y_mm_s", "z_mm_s")
FEED_COLUMNS = {"feed_mm_min": "the feed column", "requested_feed_mm_min": "the requested-feed column"}


def feed_unit_checks(recording: Recording, *, positions: str = "axes", feed: str = "feed",
                     steps: PositionSteps | None = None) -> dict[str, UnitCheck]:
    """`feed_unit_check` for each feed-like column the recording has: column -> check. `steps`: the
    `positions` stream's `PositionSteps` when the caller has them already (`data_checks.run_checks`)."""
    out = {}
    for column in FEED_COLUMNS:
        check = feed_unit_check(recording, positions=positions, feed=feed, column=column, steps=steps)
        if check is not None:
            out[column] = check
    return out


def _spread(n: int) -> np.ndarray:
    """Indices 0..n-1, or `MAX_PAIRS` of them evenly spread: a median needs no more (import stays fast)."""
    if n <= MAX_PAIRS:
        return np.arange(max(n, 0), dtype=np.int64)
    rows = np.linspace(0, n - 1, MAX_PAIRS).astype(np.int64)
    # more rows than picks: the picks are more than one apart, so already sorted and distinct (np.unique,
    # a hash of 200 000 values, was most of this check's time on long recordings); kept for safety
    return rows if (rows[1:] > rows[:-1]).all() else np.unique(rows)


def velocity_check(recording: Recording, *, feed: str = "feed", column: str = "feed_mm_min") -> UnitCheck | None:
    """Compare a feed column with the controller's own axis velocities (`velocity` stream, mm/s), a
    witness that is neither sparse nor rounded nor thrown by position glitches; None without them."""
    vel, stream = recording.streams.get(VELOCITY_STREAM), recording.streams.get(feed)
    if vel is None or stream is None or column not in stream.columns or len(vel) < MIN_SAMPLES or len(stream) < 2:
        return None
    cols = [c for c in VELOCITY_COLUMNS if c in vel.columns]
    if not cols:
        return None
    rows = _spread(len(vel))
    speed = np.linalg.norm(vel[cols].to_numpy(dtype=np.float64)[rows], axis=1) * 60.0      # mm/min
    t = vel["t_ns"].to_numpy(dtype=np.int64)[rows]
    ft = stream["t_ns"].to_numpy(dtype=np.int64)
    fv = stream[column].to_numpy(dtype=np.float64)
    at = np.clip(np.searchsorted(ft, t, side="right") - 1, 0, len(ft) - 1)          # the feed held at each time
    feed_at = fv[at]
    ok = np.isfinite(speed) & np.isfinite(feed_at)
    if ok.sum() < MIN_SAMPLES:
        return None
    # moving by the witness (a feed column may hold spikes: the Mazak's Fact reads 16074 during a rapid)
    moving = ok & (speed > 0.2 * np.percentile(speed[ok], 95)) & (feed_at > 0)
    if moving.sum() < MIN_SAMPLES:
        return None
    return _verdict(float(np.median(feed_at[moving] / speed[moving])), int(moving.sum()),
                    FEED_COLUMNS.get(column, column), "the speed of the axis velocities",
                    unit_factors_only=column != "feed_mm_min")


def _verdict(ratio: float, n: int, name: str, witness: str, *, unit_factors_only: bool = False) -> UnitCheck:
    """The warning for a median ratio; `unit_factors_only`: say something only when a unit mistake
    explains the ratio (a requested feed is often not reached: overrides, limits, short blocks)."""
    if 1 / TOLERANCE <= ratio <= TOLERANCE or not math.isfinite(ratio) or ratio <= 0:
        return UnitCheck(ratio, n, None)
    factor, why = min(EXPLANATIONS.items(), key=lambda kv: abs(math.log(ratio / kv[0])))
    explained = abs(math.log(ratio / factor)) < math.log(TOLERANCE)
    if unit_factors_only and not explained:
        return UnitCheck(ratio, n, None)
    text = f"{name} reads {ratio:.4g} x {witness} (median over {n} moving samples): "
    if explained:
        text += f"{why}"
    else:
        text += "check the declared --feed-unit and --length-unit (or the feed is not the path feed)"
    return UnitCheck(ratio, n, text)


def feed_unit_check(recording: Recording, *, positions: str = "axes", feed: str = "feed",
                    column: str = "feed_mm_min", steps: PositionSteps | None = None) -> UnitCheck | None:
    """Compare a recorded feed column with the axis velocities when the recording has them, else with
    the positions' speed; None when the recording lacks either. `steps`: the `positions` stream's
    `PositionSteps` when the caller has them already."""
    by_velocity = velocity_check(recording, feed=feed, column=column)
    if by_velocity is not None:
        return by_velocity
    stream = recording.streams.get(feed)
    if stream is None or column not in stream.columns or len(stream) < 2:
        return None
    steps = steps if steps is not None else PositionSteps.of(recording, positions)
    if steps is None or len(steps) < 3:
        return None
    t = steps.t_ns
    first = _spread(len(t) - 1)                          # pairs of consecutive samples (first of each)
    dt = steps.dt_s[first]
    ok = dt > 0
    if ok.sum() < MIN_SAMPLES:
        return None
    first = first[ok]
    speed = steps.step_mm[first] / dt[ok] * 60.0         # mm/min between samples
    mid = (t[first] + t[first + 1]) // 2
    ft = stream["t_ns"].to_numpy(dtype=np.int64)
    fv = stream[column].to_numpy(dtype=np.float64)
    feed_mid = np.interp((mid - ft[0]).astype(np.float64), (ft - ft[0]).astype(np.float64), fv)
    # moving on both witnesses, away from the starts and stops where averages over a sample lag; the
    # positions' own scale is their median speed where the feed says the tool moves (a high percentile
    # would be set by glitches: real logs jump to a home position and back within a row)
    feeding = feed_mid > 0.2 * np.percentile(np.abs(fv), 95, overwrite_input=True)   # on a copy: abs
    if feeding.sum() < MIN_SAMPLES:
        return None
    moving = feeding & (speed > 0.2 * np.median(speed[feeding]))
    if moving.sum() < MIN_SAMPLES:
        return None
    ratio = float(np.median(feed_mid[moving] / speed[moving]))
    n = int(moving.sum())
    name = FEED_COLUMNS.get(column, column)
    spacing = float(np.median(dt[ok][moving]))
    if spacing > MAX_WITNESS_DT_S:
        return UnitCheck(ratio, n, f"{name}'s unit not checked: the positions are {spacing:.3g} s apart while "
                                   f"moving (median over {n} samples), too sparse for their speed to be a witness "
                                   f"(it reads {ratio:.3g} x)")
    step = max((q[0] for q in map(steps.quantum, steps.columns) if q), default=0.0)
    resolved = step / spacing * 60.0                     # mm/min one position step per sample interval
    typical = float(np.median(feed_mid[moving]))
    if resolved > COARSE_SHARE * typical:
        return UnitCheck(ratio, n, f"{name}'s unit not checked: the positions move in steps of {step:g} mm, "
                                   f"{resolved / 60:.3g} mm/s per {spacing:.3g} s sample, too coarse for a feed of "
                                   f"{typical / 60:.3g} mm/s (median while moving; their speed reads {ratio:.3g} x)")
    return _verdict(ratio, n, name, "the path speed of the positions", unit_factors_only=column != "feed_mm_min")
