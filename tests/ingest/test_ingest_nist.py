"""Real public data: the NIST smart manufacturing test bed files in tests/fixtures/ingest/nist/ (public
domain, see its README). Every figure asserted here was measured on those files."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from feedlog.cli import main
from feedlog.errors import IngestError
from feedlog.ingest.data_checks import program_line_count, program_lines
from feedlog.ingest.reader import read_recording
from feedlog.ingest.readers import ImportOptions, read_source
from feedlog.ingest.recording import PROGRAM_ATTACHMENT
from feedlog.ingest.unit_check import feed_unit_check

NIST = Path(__file__).resolve().parents[1] / "fixtures" / "ingest" / "nist"
HURCO = NIST / "Box-OP2-Hurco02-01of20.txt"
PROGRAM = NIST / "NIST_MTC_CRADA_BOX_REV-A OP2 (Front).NC"
MAZAK = NIST / "Mazak01-20161006-head4000.txt"


def test_the_hurco_split_shdr_imports_with_no_options_and_says_what_it_mapped(tmp_path, capsys):
    out = tmp_path / "op2.mcap"
    assert main(["import", str(HURCO), "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert ("mapped: feed=Feed_Rate, line=Block_Number, rapid_override=Rapid_Override, tool=Current_Tool, "
            "spindle=Spindle_Speed (preset mtconnect-shdr)") in printed
    assert "no positions: align works on the line stream alone" in printed
    rec = read_recording(out)
    assert set(rec.streams) == {"feed", "line", "spindle", "override", "tool"}
    lines = rec.streams["line"]["line"].to_numpy()
    assert lines[0] == 0 and lines[1] == 8          # idle, then the first block: line 8 counting `%` as line 1
    assert lines.max() == 1209
    # Feed_Rate is mm/s: the program's F30. (in/min) is 12.7 mm/s after the tool change
    both = rec.streams["line"].merge(rec.streams["feed"], on="t_ns")      # one time grid, held values
    cutting = both[both["line"].between(1190, 1191) | both["line"].between(1200, 1202)]
    assert np.median(cutting["feed_mm_min"]) == pytest.approx(30 * 25.4, rel=0.01)
    assert rec.duration_s == pytest.approx(102.734, abs=0.001)  # first to last Block_Number/Feed_Rate/Spindle_Speed


def _observations(key: str) -> list[tuple[np.datetime64, str]]:
    """(time, value) of every observation of `key` in the Hurco file, read here line by line."""
    out = []
    for line in HURCO.read_text().splitlines():
        fields = line.split("|")
        out += [(np.datetime64(fields[0].rstrip("Z"), "ns"), fields[i + 1]) for i in range(1, len(fields) - 1, 2)
                if fields[i] == key]
    return out


def _changes(t: np.ndarray, v: np.ndarray) -> list[tuple[int, float]]:
    keep = np.r_[True, v[1:] != v[:-1]]
    return list(zip(t[keep].tolist(), v[keep].tolist()))


def test_the_hurco_rapid_override_and_current_tool_are_streams(tmp_path):
    out = tmp_path / "op2.mcap"
    assert main(["import", str(HURCO), "-o", str(out)]) == 0
    rec = read_recording(out)
    # the file, read here: each change of the dial (percent) and of the tool, with its time
    rapid = _observations("Rapid_Override")
    tool = _observations("Current_Tool")
    assert len(rapid) == 54 and len(tool) == 2                    # what the file holds
    t_rapid = np.array([t.astype(np.int64) for t, _ in rapid])
    want = _changes(t_rapid, np.array([float(v) / 100 for _, v in rapid]))
    ov = rec.streams["override"]
    got = _changes(ov["t_ns"].to_numpy(np.int64), ov["rapid_override"].to_numpy(np.float64))
    assert got == want
    assert want[0][1] == pytest.approx(0.54) and want[-1][1] == pytest.approx(1.0)   # turned up to 100 %
    assert min(v for _, v in want) == 0.0                                            # from 0 % at the start
    tl = rec.streams["tool"]
    assert _changes(tl["t_ns"].to_numpy(np.int64), tl["tool"].to_numpy(np.int64)) == [
        (int(t.astype(np.int64)), int(float(v))) for t, v in tool]
    assert [int(float(v)) for _, v in tool] == [0, 21]        # T21 in the spindle after the M6


def test_an_unknown_shdr_lists_its_real_keys_not_vector_items(tmp_path):
    bad = tmp_path / "other.txt"
    bad.write_text("2017-02-07T19:38:27.6093750Z|Foo|0\n2017-02-07T19:38:28.6093750Z|Bar|1\n")
    with pytest.raises(IngestError, match=r"none of the fields it maps is in the source; it has: Bar, Foo$"):
        read_source(bad, ImportOptions())


def test_lines_beyond_the_program_are_reported_with_the_first_mismatch(tmp_path, capsys):
    assert program_line_count(PROGRAM.read_bytes()) == 1186
    out = tmp_path / "op2.mcap"
    assert main(["import", str(HURCO), "--program", str(PROGRAM), "-o", str(out), "-q"]) == 0
    printed = capsys.readouterr().out
    assert ("warning: program_lines: recorded line 1189 (at 92.94 s, line sample 593) is beyond the program's "
            "1186 lines, up to line 1209 (60 of 653 samples): the program is not what ran?") in printed
    assert main(["info", str(out)]) == 0
    assert "warning: program_lines: recorded line 1189" in capsys.readouterr().out
    # the same recording with a program long enough: nothing to say
    rec = read_recording(out)
    rec.attachments[PROGRAM_ATTACHMENT] = PROGRAM.read_bytes() + b"(pad)\n" * 23
    assert program_lines(rec) is None


def test_block_numbers_the_program_does_not_hold_are_reported(tmp_path):
    rec = read_source(HURCO, ImportOptions(mapping="block_number=Block_Number,feed=Feed_Rate"))
    rec.attachments[PROGRAM_ATTACHMENT] = PROGRAM.read_bytes()
    text = program_lines(rec)
    # Block_Number holds file lines, not the program's N words (N100, N110, ... N2000): caught at once
    assert text.startswith("recorded block number N8 (at 3.453 s, line sample 1) is not in the program")
    assert "or the column is not N words?" in text


def test_mazak_feed_is_checked_against_its_axis_feed_rates_not_its_sparse_positions(tmp_path, capsys):
    out = tmp_path / "mazak.mcap"
    assert main(["import", str(MAZAK), "-o", str(out), "-q"]) == 0
    printed = capsys.readouterr().out
    assert "inches" not in printed                   # was: "reads 22.9 x ...: the positions are in inches"
    assert "the feed column reads 5.084 x the speed of the axis velocities (median over 53 moving samples)" in printed
    assert "ft/min -> mm/s" in printed
    rec = read_recording(out)
    assert rec.metadata["mapping_found"] == ("x=Xabs,y=Yabs,z=Zabs,vx=Xfrt,vy=Yfrt,vz=Zfrt,feed=Fact,line=line,"
                                             "spindle=Srpm")
    # without the axis feed rates, the positions (about 1 s apart) are no witness: no claim about units
    del rec.streams["velocity"]
    check = feed_unit_check(rec)
    assert check.ratio == pytest.approx(24.2, abs=0.05)
    assert check.warning.startswith("the feed column's unit not checked: the positions are 1.05 s apart")


def test_streams_xml_mapped_by_id_also_says_the_names(tmp_path, capsys):
    # the shape of the NIST Streams XML (tdp/mtc/MTConnect, not vendored: 1.87 MB and more): ids and names differ
    doc = tmp_path / "s.xml"
    doc.write_text(
        '<?xml version="1.0" encoding="UTF-8"?>\n<MTConnectStreams xmlns="urn:mtconnect.org:MTConnectStreams:1.3">'
        '<Header creationTime="2017-02-27T17:16:46Z" sender="s" instanceId="1" version="1.3" bufferSize="1" '
        'nextSequence="4" firstSequence="1" lastSequence="3"/><Streams><DeviceStream name="Hurco04" uuid="u">'
        '<ComponentStream component="Path" name="path" componentId="Hurco04-path"><Samples>'
        '<PathFeedrate dataItemId="Hurco04-path_9" timestamp="2017-02-07T16:02:39.2Z" name="Feed_Rate" sequence="1" '
        'subType="ACTUAL">12.7</PathFeedrate></Samples><Events>'
        '<Line dataItemId="Hurco04-path_1" timestamp="2017-02-07T16:02:39.2Z" name="Block_Number" sequence="2">8</Line>'
        '<Line dataItemId="Hurco04-path_1" timestamp="2017-02-07T16:02:40.2Z" name="Block_Number" sequence="3">9</Line>'
        '</Events></ComponentStream></DeviceStream></Streams></MTConnectStreams>\n')
    assert main(["import", str(doc), "-o", str(tmp_path / "s.mcap")]) == 0
    assert ("mapped: feed=Hurco04-path_9, line=Hurco04-path_1 (MTConnect types), by name feed=Feed_Rate, "
            "line=Block_Number; no positions") in capsys.readouterr().out
