"""Units: feedlog computes in mm, degrees, seconds and integer nanoseconds.

Controllers disagree on units (inches, mm/min vs mm/s, microseconds), so every input declares its
units and is converted here, at the edge. Column names carry their unit: `x_mm`, `feed_mm_min`, `t_ns`.
"""

from __future__ import annotations

import numpy as np

from feedlog.errors import UnitError

MM_PER_INCH = 25.4
NS_PER_S = 1_000_000_000
# Bounds on time. A program or a simulation lasts at most MAX_TIME_S (31.7 years); a recording's
# int64 t_ns stays within +-MAX_ABS_T_NS (year 1823 to 2116 as epoch times), so the difference of any
# two times still fits int64 and INT64_MIN (what a NaN becomes in a cast) is never a time.
MAX_TIME_S = 1e9
MAX_ABS_T_NS = 2**62
# Bound on a recorded value (a position, speed, angle or line number) in any unit a reader takes: no
# machine comes near it (1e12 um is 1000 km), while a corrupt cell (1e20, 1e308) does, and a unit
# factor (m -> mm, m/s -> mm/min) can never overflow a value within it.
MAX_ABS_VALUE = 1e12

# factor to the base unit of each dimension: length -> mm, time -> s, angle -> deg
_LENGTH = {"mm": 1.0, "m": 1000.0, "um": 1e-3, "in": MM_PER_INCH, "inch": MM_PER_INCH}
_TIME = {"s": 1.0, "ms": 1e-3, "us": 1e-6, "ns": 1e-9, "min": 60.0}
_ANGLE = {"deg": 1.0, "rad": 180.0 / np.pi}


def length_factor(unit: str) -> float:
    """Factor that converts `unit` to mm."""
    try:
        return _LENGTH[unit.strip().lower()]
    except KeyError:
        raise UnitError(f"unknown length unit {unit!r}; known: {', '.join(_LENGTH)}") from None


def time_factor(unit: str) -> float:
    """Factor that converts `unit` to seconds."""
    try:
        return _TIME[unit.strip().lower()]
    except KeyError:
        raise UnitError(f"unknown time unit {unit!r}; known: {', '.join(_TIME)}") from None


def angle_factor(unit: str) -> float:
    """Factor that converts `unit` to degrees."""
    try:
        return _ANGLE[unit.strip().lower()]
    except KeyError:
        raise UnitError(f"unknown angle unit {unit!r}; known: {', '.join(_ANGLE)}") from None


def velocity_factor(unit: str) -> float:
    """Factor that converts a velocity such as 'mm/min', 'in/min', 'mm/s', 'm/s' to mm/min."""
    try:
        num, den = unit.replace(" ", "").lower().split("/")
    except ValueError:
        raise UnitError(f"velocity unit {unit!r} is not of the form LENGTH/TIME") from None
    return length_factor(num) / time_factor(den) * 60.0


def seconds_to_ns(seconds) -> np.ndarray:
    """Float seconds -> int64 nanoseconds, rounded to the nearest ns. NaN, inf and times beyond
    +-MAX_ABS_T_NS raise UnitError instead of wrapping around in the cast."""
    ns = np.rint(np.asarray(seconds, dtype=np.float64) * NS_PER_S)
    if ns.size and not (np.abs(ns) <= MAX_ABS_T_NS).all():
        bad = ns.ravel()[~(np.abs(ns.ravel()) <= MAX_ABS_T_NS)][0] / NS_PER_S
        raise UnitError(f"time {bad:g} s cannot be counted in int64 nanoseconds (NaN, infinite or beyond "
                        f"+-{MAX_ABS_T_NS / NS_PER_S:.3g} s)")
    return ns.astype(np.int64)


def ns_to_seconds(t_ns) -> np.ndarray:
    return np.asarray(t_ns, dtype=np.int64) / NS_PER_S
