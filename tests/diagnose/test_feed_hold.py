"""A feed hold in a recording with positions: an operator's pause of a few seconds in the middle of a
program (simulated: every stream of the measured recording stands still for HOLD_S at a line change in
the middle of the motion, and everything after it comes HOLD_S later) must be found with its duration and
line, and kept out of the comparison of measured with simulated time: on an unchanged machine no cause
and no cycle error; with a hidden cause (Y acceleration 350 mm/s^2) the cause still named within 5 %.
A programmed dwell is a standstill too, but the program's: it stays in the comparison."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feedlog.align.holds import HOLD, find_holds, hold_free, still_stretches
from feedlog.diagnose.cases import prepare_case
from feedlog.diagnose.engine import DiagnoseConfig, diagnose
from feedlog.diagnose.summary import to_json
from feedlog.profile import load_profile

from .conftest import make_hidden

FAST = DiagnoseConfig(learned=False)
HOLD_S = 4.0


def insert_hold(rec, hold_s: float) -> tuple[int, int]:
    """Stand every stream still for `hold_s` at the slowest line change in the middle of the motion (the
    feed reads 0 meanwhile); returns (when, the line it stood on)."""
    line, feed = rec.streams["line"], rec.streams["feed"]
    t, ln = line["t_ns"].to_numpy(np.int64), line["line"].to_numpy()
    f = feed["feed_mm_min"].to_numpy(np.float64)
    moving = np.flatnonzero(f > 6.0)
    lo, hi = t[moving[0]], t[moving[-1]]
    change = np.flatnonzero(ln[1:] != ln[:-1]) + 1
    middle = [k for k in change if lo + 0.3 * (hi - lo) < t[k] < lo + 0.7 * (hi - lo)]
    k = min(middle, key=lambda j: f[j])
    at, d = int(t[k]), int(hold_s * 1e9)
    for name, table in list(rec.streams.items()):
        tt = table["t_ns"].to_numpy(np.int64)
        i = int(np.searchsorted(tt, at))
        fill = table.iloc[[i - 1] * int(d // int(np.median(np.diff(tt))))].copy()
        fill["t_ns"] = at + np.arange(len(fill), dtype=np.int64) * int(np.median(np.diff(tt)))
        if "feed_mm_min" in fill.columns:
            fill["feed_mm_min"] = 0.0
        after = table.iloc[i:].copy()
        after["t_ns"] = after["t_ns"] + d
        rec.streams[name] = pd.concat([table.iloc[:i], fill, after], ignore_index=True)
    return at, int(ln[k - 1])


@pytest.fixture(scope="module")
def held():
    out = {}
    for name, values in (("hold_control", None), ("hold_yacc", {"axes.y.acc_max": 350.0})):
        recs = make_hidden(name, values=values)
        out[name] = (recs, insert_hold(recs[1], HOLD_S))
    return out


def test_a_feed_hold_is_found_and_kept_out_of_the_comparison(held):
    recs, (_, line) = held["hold_control"]
    dx = diagnose(recs, "linuxcnc-xyz", config=FAST)
    holds = dx.cases[1].holds
    (hold,) = holds[holds["removed"]].to_dict("records")
    assert hold["kind"] == HOLD and hold["line"] == line
    assert hold["duration_s"] == pytest.approx(HOLD_S, rel=0.05)
    assert dx.findings == [] and dx.changes == []
    cyc = dx.levels["cycle"]
    assert abs(cyc["error_before_pct"]) < 0.5                     # the 4 s are not a 30 % short simulation
    assert cyc["recordings"][1]["measured_s"] < 8.0               # the pocket's motion alone (6.6 s)
    assert any("feed hold" in n and f"line {line}" in n for n in dx.cases[1].notes)
    assert to_json(dx)["holds"][dx.cases[1].name][0]["duration_s"] == pytest.approx(HOLD_S, rel=0.05)


def test_a_hidden_cause_is_still_named_with_a_feed_hold(held):
    recs, _ = held["hold_yacc"]
    dx = diagnose(recs, "linuxcnc-xyz", config=FAST)
    assert [f.parameter for f in dx.findings] == ["axes.y.acc_max"]
    assert dx.findings[0].fitted_value == pytest.approx(350.0, rel=0.05)


def test_a_programmed_dwell_stays_in_the_comparison():
    def dwell(text: str) -> str:
        lines = text.splitlines()
        lines.insert(12, "G4 P2")
        return "\n".join(lines) + "\n"

    (rec,) = make_hidden("hold_dwell", programs=("corners_f3000_p001",), program_edit=dwell)
    case = prepare_case(rec, load_profile("linuxcnc-xyz"))
    assert case.removed_s == []
    (row,) = case.holds.to_dict("records")
    assert row["kind"] == "dwell" and not row["removed"] and row["duration_s"] == pytest.approx(2.0, rel=0.05)


@settings(max_examples=60, deadline=None, derandomize=True)
@given(st.lists(st.tuples(st.floats(0, 50), st.floats(0, 5)), max_size=4),
       st.lists(st.floats(-10, 80), min_size=1, max_size=30))
def test_hold_free_moves_times_back_by_the_holds_before_them(spans, times):
    removed = sorted((a, a + d) for a, d in spans)
    merged = []
    for a, b in removed:           # hold_free takes disjoint stretches, as the stills are
        if not merged or a > merged[-1][1]:
            merged.append((a, b))
    t = np.sort(np.asarray(times))
    out = hold_free(t, merged)
    assert np.all(np.diff(out) >= -1e-9)                         # order kept
    assert np.all(out <= t + 1e-12)
    late = t > max((b for _, b in merged), default=-np.inf)
    assert np.allclose(out[late], t[late] - sum(b - a for a, b in merged))


@settings(max_examples=40, deadline=None, derandomize=True)
@given(st.floats(1.2, 5.0), st.floats(0.2, 3.0), st.integers(0, 2**16))
def test_a_still_stretch_is_found_within_a_sampling_period(still_s, start_s, seed):
    rng = np.random.default_rng(seed)
    dt = 1e-3
    t = np.arange(0.0, start_s + still_s + 2.0, dt)
    x = np.where(t < start_s, 50.0 * t, np.where(t < start_s + still_s, 50.0 * start_s, 50.0 * (t - still_s)))
    pos = np.column_stack([x, np.zeros_like(t), np.zeros_like(t)]) + rng.normal(0, 0.002, (len(t), 3))
    t_ns = np.rint(t * 1e9).astype(np.int64)
    (a, b), = still_stretches(t_ns, pos, 0.015)
    assert abs(t[a] - start_s) <= 2 * dt and abs(t[b] - (start_s + still_s)) <= 2 * dt


def test_a_still_recording_without_blocks_has_no_holds():
    t = np.arange(0, 3_000_000_000, 1_000_000, dtype=np.int64)
    axes = pd.DataFrame({"t_ns": t, "x_mm": 0.0, "y_mm": 0.0, "z_mm": 0.0})
    from feedlog.toolpath import parse_program

    prog = parse_program("G1 X1 F100\nM2\n", name="p")
    empty = pd.DataFrame(columns=["block", "line", "t_start_ns", "t_end_ns"])
    assert find_holds(axes, empty, prog, span_ns=(0, int(t[-1])), still_mm=0.01).empty


def test_a_feed_hold_in_a_5_hz_recording_is_kept_out_of_the_comparison_too():
    """At 5 Hz the progress timing samples the simulation at the recording's instants: those are taken on
    the hold-free clock too (a sample inside the hold at its start), so the 4 s are no cycle error and
    name nothing on the unchanged machine."""
    recs = make_hidden("hold_5hz", rate_hz=5.0)
    _, line = insert_hold(recs[1], HOLD_S)
    dx = diagnose(recs, "linuxcnc-xyz", config=FAST)
    holds = dx.cases[1].holds
    (hold,) = holds[holds["removed"]].to_dict("records")
    assert hold["line"] == line and hold["duration_s"] == pytest.approx(HOLD_S, abs=0.45)   # +-2 samples
    assert dx.findings == [] and dx.changes == []
    assert abs(dx.levels["cycle"]["error_before_pct"]) < 1.0
