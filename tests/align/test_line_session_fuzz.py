"""Any line stream (values, times, feed, spindle) read as a session: a result or one AlignmentError,
never a crash; the runs it keeps point at lines of the program or are left out."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feedlog.align.line_session import session_lines
from feedlog.errors import AlignmentError
from feedlog.profile import load_profile
from feedlog.recording import Recording
from feedlog.toolpath import parse_program

PROGRAM = parse_program("\n".join(["%", "N10 G21 G90 F600", "N20 T1 M6", "N30 G0 X0 Y0 S1000 M3", "N40 G1 Z0"]
                                  + [f"N{50 + 10 * i} G1 X{i * 3 % 17}.5 Y{i % 5}" for i in range(20)]
                                  + ["N300 M5", "N310 T2 M6", "N320 M3", "N330 G1 X0 Y0", "N340 M30", "%"]))
PROFILE = load_profile("generic-xyz")


@settings(max_examples=40, deadline=None)
@given(values=st.lists(st.integers(min_value=-3, max_value=400), min_size=2, max_size=80),
       steps=st.lists(st.integers(min_value=1, max_value=3_000_000_000), min_size=80, max_size=80),
       feed=st.lists(st.floats(min_value=0, max_value=5000), min_size=80, max_size=80),
       spindle=st.lists(st.sampled_from([0.0, 500.0, 1000.0]), min_size=80, max_size=80),
       numbering=st.sampled_from(["auto", "file-lines", "file-lines-no-percent", "n-words", "counter"]))
def test_any_line_stream_is_a_session_or_one_clear_error(values, steps, feed, spindle, numbering):
    n = len(values)
    t = 1_000_000_000 + np.cumsum(np.array(steps[:n], dtype=np.int64))
    rec = Recording(streams={"line": pd.DataFrame({"t_ns": t, "line": np.array(values, dtype=np.int64)}),
                             "feed": pd.DataFrame({"t_ns": t, "feed_mm_min": np.array(feed[:n])}),
                             "spindle": pd.DataFrame({"t_ns": t, "spindle_rpm": np.array(spindle[:n])})},
                    source="fuzz")
    try:
        t_out, lines, session = session_lines(rec, PROGRAM, PROFILE, t, np.array(values), numbering)
    except AlignmentError as exc:
        assert "numbering" in str(exc) and "\n" not in str(exc)
        return
    assert len(t_out) == len(lines) and (np.diff(t_out) >= 0).all()
    known = set(PROGRAM.blocks["line"].tolist()) | {0}
    placed = session.runs["program_line"].dropna().astype(int)
    assert set(lines.tolist()) <= known | set(placed.tolist())
    assert (session.events["duration_s"] >= 0).all() if len(session.events) else True
    assert session.report["numbering"]["numbering"] in ("file-lines", "file-lines-no-percent", "n-words", "counter")


def test_a_stated_unknown_numbering_is_one_error():
    t = np.array([1, 2, 3], dtype=np.int64) * 1_000_000_000
    rec = Recording(streams={"line": pd.DataFrame({"t_ns": t, "line": np.array([5, 6, 7])})}, source="x")
    with pytest.raises(AlignmentError, match="unknown block numbering 'lines'"):
        session_lines(rec, PROGRAM, PROFILE, t, np.array([5, 6, 7]), "lines")
