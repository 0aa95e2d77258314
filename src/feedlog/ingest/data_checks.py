"""Data that lies is reported, not absorbed: checks of a recording against itself and its program.

Real logs carry mistakes nobody wrote down; `feedlog import` and `feedlog info` run these checks and
print what they find (`align` the position jumps and the lines past the program) (the recording keeps every sample as recorded: a check never edits data):

- `unit_check` (`unit_check_requested_feed`): every feed-like column against the axis velocities or the
  positions' speed (`ingest.unit_check`).
- `position_jumps`: steps between consecutive position samples faster than the recording allows: the
  speed limit is `JUMP_FACTOR` x the fastest feed the recording itself shows (its `feed` stream; a rapid
  is often a short share of the samples, so the maximum, not a percentile), or
  `MAX_MACHINE_SPEED_MM_S` without one. The UMich tool-wear CSVs jump between the home position and
  the part, up to 137 mm in one 0.1 s row, while their feed column never exceeds 50 mm/s.
- `quantised`: positions rounded to a few significant digits (the UMich CSVs hold 3: at 100-999 mm a
  step of 1 mm) or to a coarse fixed resolution; reported with the coarsest step, which is the noise
  floor of any speed computed from them.
- `program_lines`: recorded program lines beyond the attached program's last line, or block numbers
  (N words) the program does not hold: the program is not what ran (the NIST box op 2 recording reaches
  line 1209 of a published program of 1186 lines).

Each check returns a one-line text or None; `run_checks` gathers them as metadata key -> text. The
three that read positions share one `PositionSteps` per `run_checks` call (times between samples, step
lengths and each axis's resolution, computed once).
"""

from __future__ import annotations

import re

import numpy as np

from feedlog.recording import Recording
from feedlog.ingest.position_steps import PositionSteps
from feedlog.ingest.quantum import finite
from feedlog.ingest.unit_check import feed_unit_checks

JUMP_FACTOR = 2.0                 # a step faster than twice the fastest recorded feed is no motion
MAX_MACHINE_SPEED_MM_S = 3000.0   # 180 m/min: beyond any machine tool's axes (used without a feed witness)
MIN_QUANTUM_MM = 0.01             # resolutions finer than this are not worth a word
SHOWN = 5                         # rows or values named in a message
CHECK_KEYS = ("unit_check", "unit_check_requested_feed", "position_jumps", "quantised", "program_lines")
_N_WORD = re.compile(rb"^\s*(?:/\d?\s*)?N(\d+)", re.IGNORECASE | re.MULTILINE)


def run_checks(recording: Recording) -> dict[str, str]:
    """metadata key -> warning text, for every check that finds something."""
    found = {}
    steps = PositionSteps.of(recording)
    for column, check in feed_unit_checks(recording, steps=steps).items():
        if check.warning:
            found["unit_check" if column == "feed_mm_min" else f"unit_check_{column.removesuffix('_mm_min')}"] = \
                check.warning
    for key, text in (("position_jumps", position_jumps(recording, steps=steps)),
                      ("quantised", quantisation(recording, steps=steps)),
                      ("program_lines", program_lines(recording))):
        if text:
            found[key] = text
    return found


def speed_limit_mm_s(recording: Recording) -> tuple[float, str]:
    """The fastest speed a position step may show, and where the limit comes from."""
    feed = recording.streams.get("feed")
    fastest = 0.0
    if feed is not None and len(feed):
        for column in ("feed_mm_min", "requested_feed_mm_min"):
            if column in feed.columns:
                values = finite(feed[column].to_numpy(dtype=np.float64))
                if len(values):   # the largest magnitude, from the extremes (no copy of the column)
                    fastest = max(fastest, max(-float(values.min()), float(values.max())) / 60.0)
    if fastest > 0:
        return JUMP_FACTOR * fastest, f"{JUMP_FACTOR:g} x the fastest recorded feed, {fastest:.4g} mm/s"
    return MAX_MACHINE_SPEED_MM_S, "no machine tool's axes move faster; the recording has no feed to compare"


def position_jumps(recording: Recording, *, steps: PositionSteps | None = None) -> str | None:
    """Steps between position samples faster than `speed_limit_mm_s`: count, largest, first rows.
    `steps`: the axes' `PositionSteps` when the caller has them already."""
    steps = steps if steps is not None else PositionSteps.of(recording)
    if steps is None:
        return None
    t, dt, step = steps.t_ns, steps.dt_s, steps.step_mm
    limit, why = speed_limit_mm_s(recording)
    with np.errstate(divide="ignore", invalid="ignore"):
        fast = step > limit * dt                  # False where a step is NaN
        if not (dt.min() > 0 and np.isfinite(step.max())):   # a zero or negative interval, an infinite step
            fast &= (dt > 0) & np.isfinite(step)
    if not fast.any():
        return None
    rows = np.flatnonzero(fast) + 1           # the sample a jump arrives at
    worst = int(np.argmax(np.where(fast, step, -1.0)))
    shown = ", ".join(f"{r} (t = {(t[r] - t[0]) / 1e9:.4g} s)" for r in rows[:SHOWN])
    return (f"{len(rows)} position steps faster than {limit:.4g} mm/s ({why}): up to {step[worst]:.4g} mm in "
            f"{dt[worst]:.3g} s; first at axes rows {shown}{', ...' if len(rows) > SHOWN else ''}; "
            "kept as recorded (glitches, not motion: the positions jump, e.g. to a home position and back)")


def quantisation(recording: Recording, *, steps: PositionSteps | None = None) -> str | None:
    """Positions held to few significant digits or a coarse resolution, per axis, with the coarsest step.
    `steps`: the axes' `PositionSteps` when the caller has them already."""
    steps = steps if steps is not None else PositionSteps.of(recording)
    if steps is None:
        return None
    parts, floors = [], []
    for col in steps.columns:
        step = steps.quantum(col)
        if step is not None and step[0] >= MIN_QUANTUM_MM:
            parts.append(f"{col[0]} to {step[1]}")
            floors.append(step[0])
    if not parts:
        return None
    return (f"positions are rounded: {'; '.join(parts)}; speeds from them are uncertain by one step per sample "
            f"interval (the noise floor: {max(floors):g} mm)")


def program_line_count(text: bytes) -> int:
    """Lines of a program file as feedlog counts them (1-based; `%` counts as a line)."""
    if not text:
        return 0
    return text.count(b"\n") + (0 if text.endswith(b"\n") else 1)


def lines_beyond(t_ns: np.ndarray, lines: np.ndarray, last: int, what: str) -> str | None:
    """The first recorded line beyond `last` (a program's last line), with how far and how often, or None.
    `t_ns`: the samples' times from the recording's start; `what` names the limit in the message."""
    beyond = np.flatnonzero(lines > last)
    if not len(beyond):
        return None
    first = int(beyond[0])
    return (f"recorded line {int(lines[first])} (at {t_ns[first] / 1e9:.4g} s, line sample {first}) is beyond "
            f"{what}, up to line {int(lines.max())} ({len(beyond)} of {len(lines)} samples): the program is not "
            "what ran?")


def program_lines(recording: Recording) -> str | None:
    """Recorded lines beyond the attached program's last line, or N words it does not hold (first one)."""
    from feedlog.recording import PROGRAM_ATTACHMENT

    program = recording.attachments.get(PROGRAM_ATTACHMENT)
    table = recording.streams.get("line")
    if not program or table is None or not len(table):
        return None
    t = table["t_ns"].to_numpy(dtype=np.int64)
    t0 = recording.t_range_ns[0]
    if "line" in table.columns:
        return lines_beyond(t - t0, table["line"].to_numpy(), program_line_count(program),
                            f"the program's {program_line_count(program)} lines")
    if "block_number" in table.columns:
        numbers = table["block_number"].to_numpy()
        words = {int(m) for m in _N_WORD.findall(program)}
        unknown = np.flatnonzero((numbers > 0) & ~np.isin(numbers, list(words)))
        if not words or not len(unknown):
            return None if words or not (numbers > 0).any() else \
                "the recording has block numbers but the program has no N words: they are not N words?"
        first = int(unknown[0])
        return (f"recorded block number N{int(numbers[first])} (at {(t[first] - t0) / 1e9:.4g} s, line sample "
                f"{first}) is not in the program ({len(unknown)} of {len(numbers)} samples hold N words the program "
                "does not have): the program is not what ran, or the column is not N words?")
    return None
