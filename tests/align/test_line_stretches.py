"""Per-stretch line offsets: a program whose run file had lines inserted (or removed) at a hidden place,
its line stream sampled like the NIST Hurco's (7 Hz), must be placed where the line times establish the
offset, never on a wrong program line, with the change found between the right recorded lines and the
count of lines without a counterpart."""

from __future__ import annotations

import numpy as np
import pandas as pd
from hypothesis import example, given, settings
from hypothesis import strategies as st

from feedlog.align.blocks import line_runs
from feedlog.align.line_stretches import stretch_offsets

PERIOD_S = 0.140625   # the NIST Hurco's line sampling


def _stream(seed: int, at: int, shift: int, n: int = 300):
    """(runs, expected): program lines 1..n with random times; the run file has `shift` extra lines after
    program line `at` (shift < 0: the program's lines at+1 .. at-shift did not run)."""
    rng = np.random.default_rng(seed)
    expected = pd.Series(np.exp(rng.uniform(np.log(0.03), np.log(1.5), n)), index=np.arange(1, n + 1))
    if shift >= 0:
        ran = list(range(1, at + 1)) + [None] * shift + list(range(at + 1, n + 1))
    else:
        ran = list(range(1, at + 1)) + list(range(at + 1 - shift, n + 1))
    dur = np.array([rng.uniform(0.03, 1.5) if p is None else expected[p] for p in ran])
    start = np.r_[0.0, np.cumsum(dur)[:-1]]
    t = np.arange(0.0, start[-1] + dur[-1], PERIOD_S)
    executing = np.searchsorted(start, t, side="right")          # recorded line = position in the run file
    runs = line_runs(np.rint(t * 1e9).astype(np.int64), executing)
    program = {k + 1: p for k, p in enumerate(ran)}
    return runs, expected, program


@settings(max_examples=25, deadline=None, derandomize=True)
@given(st.integers(0, 2**16), st.integers(80, 200), st.integers(-6, 14).filter(lambda s: s != 0))
@example(seed=1, at=120, shift=11)
def test_placed_runs_are_on_their_program_lines_and_the_change_is_counted(seed, at, shift):
    runs, expected, program = _stream(seed, at, shift)
    lines = runs["line"].to_numpy(np.int64)
    t = (runs["t_start_ns"].to_numpy(np.int64) - int(runs["t_start_ns"].iloc[0])) / 1e9
    first = int(np.searchsorted(lines, at - 40))          # a mismatch somewhere before the change ...
    last = int(np.searchsorted(lines, at + max(shift, 0) + 60))   # ... and an anchor after it
    offsets, stretches, changes = stretch_offsets(lines, t, np.zeros(len(lines)), expected, first, last, 0, shift)
    placed = [(lines[first + k], o) for k, o in enumerate(offsets) if o is not None]
    wrong = [(rec, o) for rec, o in placed if program.get(int(rec)) != rec - o]
    assert not wrong, wrong[:5]
    assert sum(c["recorded_without_counterpart"] - c["program_without_counterpart"] for c in changes) == shift
    # the inserted (or removed) lines lie where a change says
    assert any(c["between_recorded_lines"][0] <= at + 1 and c["between_recorded_lines"][1] >= at + 1 + max(shift, 0)
               for c in changes)
    assert sum(s["seconds"] for s in stretches if s["established"]) > 0.5 * (t[last] - t[first])


def test_a_stream_that_matches_gives_one_established_stretch_and_no_change():
    runs, expected, _ = _stream(3, 150, 0)
    lines = runs["line"].to_numpy(np.int64)
    t = (runs["t_start_ns"].to_numpy(np.int64) - int(runs["t_start_ns"].iloc[0])) / 1e9
    offsets, stretches, changes = stretch_offsets(lines, t, np.zeros(len(lines)), expected, 20, 150, 0, 0)
    assert changes == [] and [s["offset"] for s in stretches] == [0] and stretches[0]["established"]
    assert all(o == 0 for o in offsets)


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.lists(st.integers(-5, 400), min_size=0, max_size=40), st.integers(-30, 30), st.integers(-30, 30))
def test_any_run_sequence_gives_offsets_for_every_run_or_none(values, before, after):
    lines = np.asarray(values, dtype=np.int64)
    t = np.arange(len(lines), dtype=np.float64) * PERIOD_S
    expected = pd.Series(0.1, index=np.arange(1, 300))
    first, last = min(1, len(lines)), max(len(lines) - 1, 0)
    offsets, stretches, _ = stretch_offsets(lines, t, np.zeros(len(lines)), expected, first, last, before, after)
    assert len(offsets) == max(last - first, 0)
    assert all(o is None or min(before, after) - 8 <= o <= max(before, after) + 8 for o in offsets)
