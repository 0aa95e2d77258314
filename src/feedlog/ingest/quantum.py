"""How finely a column of recorded numbers is resolved: fixed decimals or significant digits.

Exports round positions (the UMich tool-wear CSVs hold 3 significant digits: at 100-999 mm a step of
1 mm); a speed computed from them is uncertain by one step per sample interval. `position_step_mm`
gives the coarsest step of a column; `ingest.data_checks` reports it and `ingest.unit_check` refuses to
judge a feed's unit with positions too coarse to resolve it.
"""

from __future__ import annotations

import numpy as np

SAMPLE = 20_000   # values looked at per column (evenly spaced: the cost stays bounded on long recordings)


def significant_digits(values: np.ndarray, most: int = 8) -> int | None:
    """The fewest significant digits (1..most) that every value holds exactly, or None."""
    v = values[np.isfinite(values) & (values != 0)]
    if not len(v):
        return None
    magnitude = np.floor(np.log10(np.abs(v)))
    for digits in range(1, most + 1):
        scale = 10.0 ** (digits - 1 - magnitude)
        if np.all(np.abs(np.rint(v * scale) - v * scale) < 1e-6):
            return digits
    return None


def decimals(values: np.ndarray, most: int = 6) -> int | None:
    """The fewest decimals (0..most) that every value holds exactly, or None."""
    v = values[np.isfinite(values)]
    if not len(v):
        return None
    for k in range(most + 1):
        scaled = v * 10.0 ** k
        if np.all(np.abs(np.rint(scaled) - scaled) < 1e-6 * np.maximum(1.0, np.abs(scaled)) + 1e-9):
            return k
    return None


def finite(values: np.ndarray) -> np.ndarray:
    """`values` without NaN and infinities: the array itself when it holds none (found by its minimum and
    maximum, two passes without a copy), else a filtered copy."""
    if len(values) and np.isfinite(values.min()) and np.isfinite(values.max()):
        return values
    return values[np.isfinite(values)]


def position_step_mm(values: np.ndarray) -> tuple[float, str] | None:
    """The coarsest step between representable values of a column and how it arises (`3 significant
    digits` or `2 decimals`), or None for a constant, empty or finely resolved column."""
    v = finite(values)
    if len(v) > SAMPLE:
        v = v[np.linspace(0, len(v) - 1, SAMPLE).astype(np.int64)]
    if not len(v) or np.ptp(v) == 0:
        return None
    top = float(np.max(np.abs(v)))
    places, digits = decimals(v), significant_digits(v)
    fixed = 10.0 ** -places if places is not None else 0.0
    sig = 10.0 ** (np.floor(np.log10(top)) - digits + 1) if digits is not None and top > 0 else 0.0
    if digits is not None and sig > fixed * 1.0001:
        low = 10 ** np.floor(np.log10(top))
        return float(sig), f"{digits} significant digits (a step of {sig:g} mm at {low:g}-{top:g} mm)"
    if places is not None:
        return float(fixed), f"{places} decimals (a step of {fixed:g} mm)"
    return None
