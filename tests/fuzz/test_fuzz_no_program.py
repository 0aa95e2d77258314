"""Seeded fuzzing (hypothesis, derandomized) of what `feedlog diagnose` without a program measures: any
finite signal on any increasing clock gives plateaus that are runs inside the band they claim, a held
level no higher than the signal, and a measurement that never raises anything but our one-line error."""

from __future__ import annotations

import numpy as np
import pandas as pd
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.diagnose.cases import DiagnoseError
from feedlog.diagnose.no_program import measure, plateaus, top_held
from feedlog.recording import Recording

FUZZ = settings(max_examples=100, derandomize=True, deadline=None, suppress_health_check=list(HealthCheck))
values = st.lists(st.floats(-1e4, 1e4, allow_nan=False), min_size=1, max_size=300)
steps = st.lists(st.integers(1, 200_000_000), min_size=300, max_size=300)


@FUZZ
@given(values, steps, st.floats(0.001, 0.2), st.floats(0.0, 0.5))
def test_plateaus_are_runs_inside_their_band(xs, dts, rel, min_s):
    x = np.array(xs)
    t = np.cumsum(np.array(dts[:len(x)], dtype=np.int64))
    runs = plateaus(x, t, rel=rel, floor=0.0, min_s=min_s)
    end = 0
    for level, i, j, seconds in runs:
        assert end <= i < j <= len(x) and j - i >= 2 and seconds >= min_s
        assert x[i:j].min() - 1e-9 <= level <= x[i:j].max() + 1e-9
        end = j
    held = top_held(runs, [False] * len(runs), rel=rel)
    if held is not None:
        assert held.value <= np.abs(x).max() + 1e-6 and held.count >= 1


@FUZZ
@given(st.lists(st.tuples(st.floats(-1e3, 1e3, allow_nan=False), st.floats(-1e3, 1e3, allow_nan=False)),
                min_size=0, max_size=80), st.integers(1, 100_000_000), st.booleans(), st.integers(0, 3))
def test_measure_takes_any_finite_recording_or_says_why_not(rows, step_ns, with_feed, repeat):
    t = np.arange(len(rows), dtype=np.int64) * step_ns
    if repeat:   # times stamped in bunches (several samples at one time), as some sources do
        t = t // (repeat + 1) * (repeat + 1)
    streams = {"axes": pd.DataFrame({"t_ns": t, "x_mm": [r[0] for r in rows], "y_mm": [r[1] for r in rows]})}
    if with_feed:
        streams["feed"] = pd.DataFrame({"t_ns": t, "feed_mm_min": np.abs([r[1] for r in rows])})
    try:
        dx = measure([Recording(streams=streams, source="fuzz.mcap")])
    except DiagnoseError as exc:
        assert "nothing to measure" in str(exc) and "\n" not in str(exc)
        return
    for facts in dx.axes.values():
        assert facts.minimum <= facts.maximum
        assert facts.peak_speed is None or 0 <= facts.peak_speed < np.inf
        assert facts.peak_acc is None or 0 <= facts.peak_acc < np.inf
    from feedlog.diagnose.no_program_report import summary_lines, to_json
    import json
    json.dumps(to_json(dx), allow_nan=False)   # what --json prints: finite everywhere
    assert summary_lines(dx)
