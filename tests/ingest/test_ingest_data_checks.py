"""ingest.data_checks: data that lies is reported. Code paths on constructed recordings here; the claims
about real files are in test_ingest_nist.py (vendored, public domain) and, for the UMich tool-wear CSVs
(no licence stated where they are published on GitHub: not vendored), in the tests below that run when
FEEDLOG_UMICH_DIR names a folder holding experiment_01.csv .. experiment_18.csv (e.g. a clone of
github.com/ejhusom/cnc_milling_tool_wear, folder data/), and are skipped otherwise."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feedlog.cli import main
from feedlog.ingest.data_checks import position_jumps, program_line_count, program_lines, quantisation
from feedlog.ingest.quantum import decimals, position_step_mm, significant_digits
from feedlog.ingest.readers import ImportOptions, read_source
from feedlog.ingest.recording import PROGRAM_ATTACHMENT, Recording
from feedlog.ingest.unit_check import velocity_check

UMICH = os.environ.get("FEEDLOG_UMICH_DIR")
needs_umich = pytest.mark.skipif(
    not UMICH or not (Path(UMICH) / "experiment_02.csv").is_file(),
    reason="the UMich CNC Mill Tool Wear CSVs are not vendored (their GitHub copy states no licence); "
           "set FEEDLOG_UMICH_DIR to a folder holding experiment_01.csv .. experiment_18.csv")


def moving(n=200, dt_s=0.1, speed_mm_s=20.0, feed_mm_min=None) -> Recording:
    t = np.arange(n, dtype=np.int64) * int(dt_s * 1e9)
    x = np.arange(n) * speed_mm_s * dt_s
    streams = {"axes": pd.DataFrame({"t_ns": t, "x_mm": x, "y_mm": np.zeros(n), "z_mm": np.zeros(n)})}
    if feed_mm_min is not None:
        streams["feed"] = pd.DataFrame({"t_ns": t, "feed_mm_min": np.full(n, feed_mm_min)})
    return Recording(streams=streams)


def test_a_jump_to_home_and_back_is_reported_with_its_rows():
    rec = moving(feed_mm_min=1200.0)
    assert position_jumps(rec) is None
    rec.streams["axes"].loc[50, "x_mm"] = 198.0            # one row at "home": out and back
    text = position_jumps(rec)
    assert text.startswith("2 position steps faster than 40 mm/s (2 x the fastest recorded feed, 20 mm/s): up to ")
    assert "first at axes rows 50 (t = 5 s), 51 (t = 5.1 s)" in text
    # without a feed only what no machine does is a jump
    del rec.streams["feed"]
    assert position_jumps(rec) is None
    rec.streams["axes"].loc[80, "x_mm"] = 1000.0
    assert "no machine tool's axes move faster" in position_jumps(rec)


def test_rounded_positions_are_reported_with_their_coarsest_step():
    values = np.array([198.0, 157.0, 12.3, 0.541, -3.25])
    assert significant_digits(values) == 3 and decimals(values) == 3
    assert position_step_mm(values)[0] == pytest.approx(1.0)
    assert position_step_mm(np.round(np.linspace(0, 50, 400), 4))[0] == pytest.approx(1e-4)
    assert position_step_mm(np.full(5, 3.0)) is None
    rec = moving(speed_mm_s=13.0)
    rec.streams["axes"]["x_mm"] = np.round(rec.streams["axes"]["x_mm"], 1)
    assert quantisation(rec).startswith("positions are rounded: x to 1 decimals (a step of 0.1 mm)")
    rec.streams["axes"]["x_mm"] = rec.streams["axes"]["x_mm"] + 0.0123
    assert quantisation(rec) is None


def test_lines_are_counted_as_feedlog_counts_them_and_n_words_checked():
    assert program_line_count(b"%\nN10 G0 X1\n%\n") == 3 and program_line_count(b"%\nG0 X1") == 2
    assert program_line_count(b"") == 0
    t = np.arange(4, dtype=np.int64) * 10**9
    rec = Recording(streams={"line": pd.DataFrame({"t_ns": t, "block_number": np.array([10, 20, 20, 30])})})
    rec.attachments[PROGRAM_ATTACHMENT] = b"%\nN10 G0 X1\nN20 X2\n%\n"
    assert program_lines(rec).startswith("recorded block number N30 (at 3 s, line sample 3) is not in the program")
    rec.attachments[PROGRAM_ATTACHMENT] = b"%\nG0 X1\nX2\n%\n"
    assert "the program has no N words" in program_lines(rec)


def test_velocity_witness_catches_a_feed_declared_per_minute():
    rec = moving(speed_mm_s=20.0, feed_mm_min=20.0)       # a feed column in mm/s read as mm/min
    t = rec.streams["axes"]["t_ns"]
    rec.streams["velocity"] = pd.DataFrame({"t_ns": t, "x_mm_s": np.full(len(t), 20.0), "y_mm_s": 0.0, "z_mm_s": 0.0})
    check = velocity_check(rec)
    assert check.ratio == pytest.approx(1 / 60) and "per second, not per minute" in check.warning
    rec.streams["feed"]["feed_mm_min"] = 1200.0
    assert velocity_check(rec).warning is None


@needs_umich
def test_umich_real_feed_is_mm_per_s_and_jumps_and_rounding_are_reported(tmp_path, capsys):
    src = Path(UMICH) / "experiment_02.csv"
    assert main(["import", str(src), "--preset", "umich-tool-wear", "-o", str(tmp_path / "u.mcap"), "-q"]) == 0
    printed = capsys.readouterr().out
    assert "unit_check" not in printed                       # the feed agrees with the velocity columns
    assert ("warning: position_jumps: 90 position steps faster than 100 mm/s (2 x the fastest recorded feed, "
            "50 mm/s): up to 136.8 mm in 0.1 s; first at axes rows 30 (t = 3 s), 40 (t = 4 s)") in printed
    assert "y to 3 significant digits (a step of 1 mm at 100-158 mm)" in printed
    assert main(["info", str(tmp_path / "u.mcap")]) == 0
    assert "warning: position_jumps: 90 position steps" in capsys.readouterr().out
    rec = read_source(src, ImportOptions(preset="umich-tool-wear", feed_unit="mm/min"))
    assert "per second, not per minute" in velocity_check(rec, column="requested_feed_mm_min").warning
    assert "line" not in rec.streams                         # the sequence counter is not read as N words


@needs_umich
def test_umich_real_all_experiments_import_with_consistent_units():
    for k in range(1, 19):
        rec = read_source(Path(UMICH) / f"experiment_{k:02d}.csv", ImportOptions(preset="umich-tool-wear"))
        check = velocity_check(rec, column="requested_feed_mm_min")
        assert check.warning is None and check.ratio == pytest.approx(1.0, abs=0.02), (k, check)


def test_align_warns_when_recorded_lines_pass_the_programs_last_block():
    from feedlog.align.pipeline import align_recording

    real = Path(__file__).resolve().parents[1] / "fixtures" / "ingest" / "real"
    rec = read_source(real / "hurco_shdr.txt", ImportOptions(length_unit="in", feed_unit="in/min"))
    assert not [w for w in align_recording(rec, real / "hurco_part.nc").report["warnings"] if "beyond" in w]
    lines = rec.streams["line"]
    lines.loc[lines.index[-1], "line"] = 99
    warned = [w for w in align_recording(rec, real / "hurco_part.nc").report["warnings"] if "beyond" in w]
    assert warned == ["recorded line 99 (at 15.9 s, line sample 147) is beyond the program's last block (line 29), "
                      "up to line 99 (1 of 148 samples): the program is not what ran?"]


def test_align_reports_position_jumps_in_its_warnings_or_its_error():
    from feedlog.align.pipeline import align_recording
    from feedlog.errors import AlignmentError

    real = Path(__file__).resolve().parents[1] / "fixtures" / "ingest" / "real"
    rec = read_source(real / "umich_experiment.csv", ImportOptions(preset="umich-tool-wear"))
    assert not [w for w in align_recording(rec, real / "umich_part.nc").report["warnings"] if "position steps" in w]
    rec.streams["axes"].loc[0, "x_mm"] = 198.0          # a glitch before the motion: aligned, and said
    warned = [w for w in align_recording(rec, real / "umich_part.nc").report["warnings"] if "position steps" in w]
    assert len(warned) == 1 and "first at axes rows 1 (t = 0.1 s)" in warned[0]
    rec.streams["axes"].loc[40, "x_mm"] = 198.0         # one in the middle of the part: the match fails, and says why
    with pytest.raises(AlignmentError, match=r"farther than their tolerance .*; the positions may be why: 3 position "
                                             r"steps faster than"):
        align_recording(rec, real / "umich_part.nc")
