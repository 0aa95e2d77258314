"""Line-stream-only diagnosis on data with hidden effects: a line stream (10 Hz), feed and spindle made
from the simulation with a feed override, a tool change time, a coolant wait and a numbering the test
chooses; the diagnosis must find each of them, and nothing where none was hidden."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from feedlog.align.line_numbering import NUMBERINGS, detect
from feedlog.align.line_session import expected_times
from feedlog.diagnose.line_level import diagnose_lines
from feedlog.profile import load_profile
from feedlog.recording import Recording
from feedlog.sim import simulate
from feedlog.toolpath.load import load_program

PROFILE = load_profile("generic-xyz")


def program_text(moves: int = 24, *, long: bool = True) -> str:
    rng = np.random.default_rng(7)
    out = ["%", "N10 G21 G90 G17", "N20 T1 M6", "N30 G0 X0 Y0 S8000 M3", "N40 Z5 M8", "N50 G1 Z0 F600"]
    n = 60
    for tool in (1, 2):
        x = 0.0
        for _ in range(moves):
            x += 30.0 if long and n % 50 == 0 else float(rng.uniform(2.0, 6.0))   # 3 s, else 0.2-0.6 s at F600
            out.append(f"N{n} G1 X{x:.3f} Y{(n % 7):.1f}")
            n += 10
        out.append("")          # a blank line: no block (a block counter and the file lines part here)
        out += [f"N{n} G0 Z50", f"N{n + 10} M5", f"N{n + 20} T{tool + 1} M6", f"N{n + 30} G0 X0 Y0 S8000 M3",
                f"N{n + 40} Z5", f"N{n + 50} G1 Z0 F600"] if tool == 1 else [f"N{n} G0 Z50", f"N{n + 10} M30"]
        n += 60
    return "\n".join(out + ["%"]) + "\n"


def recording(path, *, override: float, tool_s: float, wait_s: float = 0.0, numbering: str = "file-lines",
              rate_hz: float = 10.0) -> Recording:
    """The line, feed and spindle streams of a run of the program at `override` with a `tool_s` tool
    change (line stream on the M6 line, spindle off) and `wait_s` on the first line with M8."""
    prog = load_program(path)
    sim = simulate(prog, PROFILE, mechanisms={"feed_override": {"override": override}})
    b = sim.blocks
    lines = prog.blocks.set_index("block")["line"]
    kinds = prog.blocks.set_index("block")["kind"].astype(str)
    m6 = int(prog.blocks.loc[prog.blocks["mcodes"].astype(str).str.contains("M6"), "line"].iloc[-1])
    m8 = int(prog.blocks.loc[prog.blocks["mcodes"].astype(str).str.contains("M8"), "line"].iloc[0])
    segs, t = [], 0.0          # (line, start, end, feed mm/min, spindle rpm)
    for row in b.itertuples(index=False):
        ln = int(lines[row.block])
        if ln > m6 and not any(s[0] == m6 for s in segs):
            segs.append((m6, t, t + tool_s, 0.0, 0.0))
            t += tool_s
        if ln == m8 and wait_s:
            segs.append((ln, t, t + wait_s, 0.0, 8000.0))
            t += wait_s
        feed = 15000.0 if kinds[row.block] == "rapid" else 600.0 * override
        segs.append((ln, t, t + row.duration_s, feed, 8000.0))
        t += row.duration_s
    end = int(prog.blocks["line"].max())          # the controller shows the program end (M30) last
    segs.append((end, t, t + 0.5, 0.0, 0.0))
    t += 0.5
    grid = np.arange(0.0, t, 1.0 / rate_hz)
    starts = np.array([s[1] for s in segs])
    k = np.searchsorted(starts, grid, side="right") - 1
    seg = np.array(segs)[k]
    t_ns = (1_000_000_000 + grid * 1e9).astype(np.int64)
    values = seg[:, 0].astype(np.int64)
    if numbering == "file-lines-no-percent":
        values = values - 1
    elif numbering == "n-words":
        words = prog.blocks.set_index("line")["n_word"]
        values = words.reindex(values).to_numpy(np.int64)
    elif numbering == "counter":
        order = {ln: i + 1 for i, ln in enumerate(prog.blocks["line"].drop_duplicates())}
        values = np.array([order[v] for v in values], dtype=np.int64)
    streams = {"line": pd.DataFrame({"t_ns": t_ns, "line": values}),
               "feed": pd.DataFrame({"t_ns": t_ns, "feed_mm_min": seg[:, 3]}),
               "spindle": pd.DataFrame({"t_ns": t_ns, "spindle_rpm": seg[:, 4]})}
    return Recording(streams=streams, source="synthetic")


@pytest.fixture(scope="module")
def prog_path(tmp_path_factory):
    path = tmp_path_factory.mktemp("prog") / "two_tools.ngc"
    path.write_text(program_text())
    return path


@pytest.mark.parametrize("override,tool_s", [(0.8, 4.0), (1.2, 9.5)])
def test_hidden_feed_override_and_tool_change_time_are_found(prog_path, override, tool_s):
    rec = recording(prog_path, override=override, tool_s=tool_s, wait_s=3.0)
    ld = diagnose_lines(rec, PROFILE, str(prog_path))
    assert ld.session.numbering.name == "file-lines"
    assert ld.session.line_map.matches
    events = ld.session.events
    tool = events[events["kind"] == "tool change"]
    assert len(tool) == 1 and tool["duration_s"].iloc[0] == pytest.approx(tool_s, abs=0.15)
    wait = events[events["kind"] == "wait on M codes"]
    assert len(wait) == 1 and wait["duration_s"].iloc[0] == pytest.approx(3.0, abs=0.15)
    assert ld.values["sim.tool_change.time_s"] == pytest.approx(tool_s, abs=0.15)
    assert ld.values["sim.feed_override.override"] == pytest.approx(override, rel=0.05)
    assert abs(ld.figures["error_after_pct"]) < 2.0


def test_nothing_hidden_nothing_found(prog_path):
    rec = recording(prog_path, override=1.0, tool_s=0.0)
    ld = diagnose_lines(rec, PROFILE, str(prog_path))
    assert (ld.session.events["kind"] != "tool change").all() and "sim.tool_change.time_s" not in ld.values
    assert "sim.feed_override.override" not in ld.values     # within 2 % of 1: nothing proposed
    assert ld.fit["k_feed"][0] == pytest.approx(1.0, abs=0.03)
    assert abs(ld.figures["error_before_pct"]) < 2.0


@pytest.mark.parametrize("numbering", NUMBERINGS)
def test_the_numbering_hidden_in_the_data_is_detected(prog_path, numbering):
    rec = recording(prog_path, override=1.0, tool_s=5.0, numbering=numbering)
    ld = diagnose_lines(rec, PROFILE, str(prog_path))
    assert ld.session.numbering.name == numbering and not ld.session.numbering.stated
    tool = ld.session.events[ld.session.events["kind"] == "tool change"]
    assert len(tool) == 1 and tool["duration_s"].iloc[0] == pytest.approx(5.0, abs=0.15)


@pytest.mark.parametrize("where,long", [(18, True), (3, True), (18, False)])
def test_inserted_lines_are_reported_as_a_mismatch(tmp_path, where, long):
    """The machine ran a file with 3 more lines (comments the published program lacks) after line `where`:
    the lines after it are 3 ahead, which the tool change and the program end pin down. With a few long
    moves the line times place the first mismatch; with none, only the anchors say it."""
    published = tmp_path / "published.ngc"
    published.write_text(program_text(long=long))
    text = program_text(long=long).splitlines()
    ran = text[:where] + ["(a)", "(b)", "(c)"] + text[where:]
    ran_path = tmp_path / "ran.ngc"
    ran_path.write_text("\n".join(ran) + "\n")
    rec = recording(ran_path, override=1.0, tool_s=5.0)
    ld = diagnose_lines(rec, PROFILE, str(published), numbering="file-lines")   # stated: the start differs too
    lm = ld.session.line_map
    assert not lm.matches
    assert {a["offset"] for a in lm.anchors} == {3}    # the spindle restart after M6, the program end
    assert "line for line" in " ".join(ld.warnings)
    if long:            # a 3 s move lands on a short line: the line times place it (at or after the insertion)
        assert lm.first_mismatch["found_by"] == "line time" and lm.first_mismatch["recorded_line"] > where
    else:
        assert lm.first_mismatch["found_by"] == "anchor"
    assert ld.values["sim.tool_change.time_s"] == pytest.approx(5.0, abs=0.15)


@settings(max_examples=40, deadline=None)
@given(values=st.lists(st.integers(min_value=-5, max_value=10**6), min_size=1, max_size=60),
       durations=st.lists(st.floats(min_value=0.0, max_value=100.0), min_size=60, max_size=60))
def test_detect_takes_any_recorded_values(prog_path, values, durations):
    """Any block values (negative, huge, unknown): a numbering or one clear AlignmentError, never a crash."""
    from feedlog.errors import AlignmentError

    prog = load_program(prog_path)
    expected = expected_times(prog, PROFILE)
    try:
        found = detect(np.array(values), np.array(durations[:len(values)]), prog, expected)
    except AlignmentError as exc:
        assert "no block numbering fits" in str(exc)
    else:
        assert found.name in NUMBERINGS
