"""The NIST box part, operation 2, end to end on the real vendored files (tests/fixtures/ingest/nist/,
public domain): import, align on its line stream alone, diagnose its cycle. Every figure was measured
on those files (docs/diagnose.md, "Line stream only")."""

from __future__ import annotations

import json
from datetime import datetime
from pathlib import Path

import pytest

from feedlog.cli import main

NIST = Path(__file__).resolve().parents[1] / "fixtures" / "ingest" / "nist"
HURCO = NIST / "Box-OP2-Hurco02-01of20.txt"
PROGRAM = NIST / "NIST_MTC_CRADA_BOX_REV-A OP2 (Front).NC"


@pytest.fixture(scope="module")
def box(tmp_path_factory):
    folder = tmp_path_factory.mktemp("box")
    rec = folder / "box.mcap"
    assert main(["import", str(HURCO), "-o", str(rec)]) == 0
    return folder, rec


def test_align_on_the_line_stream_finds_the_numbering_the_tool_change_and_the_mismatch(box, capsys):
    folder, rec = box
    assert main(["align", str(rec), "--program", str(PROGRAM), "-o", str(folder / "al")]) == 0
    printed = capsys.readouterr().out
    assert "block numbers read as file-lines" in printed and "the program is not what ran" in printed
    assert "tool change 1 x 6.94 s" in printed
    report = json.loads((folder / "al" / "box" / "report.json").read_text())
    assert report["mode"] == "line stream only"
    assert report["numbering"]["numbering"] == "file-lines"      # Block_Number counts `%` as line 1
    assert report["numbering"]["from"] == "detected from the data"
    lm = report["line_map"]
    assert not lm["matches"]
    # the first line whose time the published program cannot give: recorded 309 lasts 0.84 s where
    # line 309 is a 0.04 s feed move; program line 298 (an arc, 0.77 s) fits: the run file had 11 more lines
    assert lm["first_mismatch"]["recorded_line"] == 309
    assert lm["first_mismatch"]["likely_line"] == 298
    tool_anchor = lm["anchors"][0]
    assert (tool_anchor["recorded_line"], tool_anchor["program_line"], tool_anchor["offset"]) == (1183, 1159, 24)
    assert lm["anchors"][-1]["offset"] == 24                     # the program end: recorded 1209, M30 on 1185
    events = {e["kind"]: e for e in report["events"]}
    tool = events["tool change"]
    assert (tool["recorded_line"], tool["program_line"], tool["m_codes"]) == (1182, 1158, "M6")
    assert tool["duration_s"] == pytest.approx(6.94, abs=0.01) and tool["spindle_off"]
    assert events["optional stop"]["program_line"] == 1157     # N1720M01, spindle already off
    waits = [e for e in report["events"] if e["kind"] == "wait on M codes"]
    assert [w["program_line"] for w in waits] == [9, 1160] and all(w["m_codes"] == "M8" for w in waits)
    assert any("not" in w and "line for line" in w and "+24" in w for w in report["warnings"])
    # between the mismatch and the tool change: the stretch the line times establish is placed, the rest
    # left out; the 24 inserted lines lie between the last run placed before it and the first after
    placed = [s for s in lm["stretches"] if s["established"]]
    assert [(s["offset"], s["recorded_lines"], s["program_lines"]) for s in placed] == [(24, [894, 1178], [870, 1154])]
    assert all(s["margin"] < 1.0 for s in lm["stretches"] if not s["established"])
    (change,) = lm["offset_changes"]
    assert (change["from_offset"], change["to_offset"], change["recorded_without_counterpart"]) == (0, 24, 24)
    assert change["between_recorded_lines"] == [304, 894]
    assert lm["runs_left_out"] == 137                            # was 210 of 297 with no stretch placed


def test_diagnose_explains_the_cycle_from_the_line_stream(box, capsys):
    folder, rec = box
    out = folder / "dx"
    assert main(["diagnose", str(rec), "--program", str(PROGRAM), "--profile", "generic-xyz", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "line stream only" in printed and "the block level cannot see" in printed
    dx = json.loads((out / "diagnose.json").read_text())
    f, fit = dx["figures"], dx["fit"]
    assert f["measured_cycle_s"] == pytest.approx(99.28, abs=0.01)
    assert f["simulated_cycle_s"] == pytest.approx(67.76, abs=0.05)
    assert f["tool_change_share_pct"] == pytest.approx(7.0, abs=0.1)
    assert f["standstill_share_pct"] == pytest.approx(19.8, abs=0.2)      # M1 stop and two M8 waits
    # the first tool runs at ~114 % feed, the second at ~97 %: the block level sees a factor per tool
    assert fit["k_feed"][0] == pytest.approx(0.874, abs=0.01)
    assert fit["k_feed"][1] == pytest.approx(1.03, abs=0.02)
    assert fit["held_out_error_after_pct"] < fit["held_out_error_before_pct"]
    assert fit["values"]["sim.tool_change.time_s"] == pytest.approx(6.94, abs=0.01)
    assert abs(f["error_before_pct"]) > 30 and abs(f["error_after_pct"]) < 2
    # the stretch placed after the mismatch is timed block by block: 44.03 s of the 72.72 s of motion
    # (60.6 %) are compared stretch by stretch, 27.72 s (38.1 %) before it was placed; 27.45 s run unplaced
    # (42.80 s before)
    assert f["timed_per_block_s"] == pytest.approx(44.03, abs=0.01)
    assert f["timed_per_block_pct"] == pytest.approx(60.6, abs=0.1) and f["unplaced_s"] == pytest.approx(27.45, abs=0.01)
    (stretch,) = [s for s in f["stretches"] if s["established"]]
    assert stretch["intervals"] == 72 == len(stretch["blocks"])
    assert stretch["measured_s"] == pytest.approx(15.05, abs=0.01) and stretch["simulated_s"] == pytest.approx(15.66, abs=0.01)
    assert stretch["blocks"][0] == {"from_line": 870, "to_line": 871, "recorded_from_line": 894,
                                    "measured_s": pytest.approx(0.656, abs=1e-3), "simulated_s": pytest.approx(0.386, abs=1e-3)}
    # the recorded rapid override (`Rapid_Override`): read from the file here, the dial's last rise to 100 %
    # after the first block (Block_Number 8) started, and the wait at line 9 ran with the dial turned down
    stamps = {}
    for row in HURCO.read_text().splitlines():
        fields = row.split("|")
        for key, value in zip(fields[1::2], fields[2::2]):
            stamps.setdefault((key, value), []).append(datetime.fromisoformat(fields[0][:26]))
    start = stamps[("Block_Number", "8")][0]
    full = stamps[("Rapid_Override", "100.000000")][-1]
    rd = f["rapid_override"]
    assert rd["min"] == 0.0 and rd["full_from_s"] == pytest.approx((full - start).total_seconds(), abs=1e-3)
    assert 0 < rd["below_full_s"] <= rd["full_from_s"]
    (slow,) = rd["events_below_full"]
    assert (slow["kind"], slow["recorded_line"]) == ("wait on M codes", 9) and slow["rapid_override_mean"] < 0.5
    assert "recorded rapid override: lowest 0 %" in printed
    profile = (out / "profile.toml").read_text()
    assert "[sim.tool_change]" in profile and "time_s = 6.938" in profile
    # the fitted profile simulates the program with the tool change in it
    assert main(["sim", str(PROGRAM), "--profile", str(out / "profile.toml"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["cycle_time_s"] == pytest.approx(f["simulated_after_s"], abs=0.01)
