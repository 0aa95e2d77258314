"""MTConnect readers: SHDR logs and Streams XML -> wide, forward-filled recordings with declared units."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from feedlog.cli import main
from feedlog.errors import IngestError
from feedlog.ingest import read_recording
from feedlog.ingest.readers import ImportOptions, read_source

REAL = Path(__file__).resolve().parents[1] / "fixtures" / "ingest" / "real"
MM = 25.4

SHDR = """* shdrVersion: 2.0
* device: mill
2020-01-01T00:00:00.000Z|Xact|UNAVAILABLE|Yact|UNAVAILABLE|path_feedrate|UNAVAILABLE|line|UNAVAILABLE
2020-01-01T00:00:00.050Z|system|NORMAL||||
2020-01-01T00:00:00.100Z|Xact|1.0000|Yact|2.0000|path_feedrate|10|line|7
2020-01-01T00:00:00.200Z|Xact|1.5000
2020-01-01T00:00:00.300Z|Yact|2.5000|line|8
2020-01-01T00:00:00.350Z|message|M1|operator message
2020-01-01T00:00:00.400Z|Xact|UNAVAILABLE
2020-01-01T00:00:00.500Z|Xact|2.0000|path_feedrate|20
"""


def write(tmp_path, name: str, text: str | bytes) -> Path:
    path = tmp_path / name
    path.write_bytes(text.encode() if isinstance(text, str) else text)
    return path


def test_shdr_pivots_forward_fills_and_leaves_unavailable_rows_out(tmp_path):
    rec = read_source(write(tmp_path, "m.txt", SHDR), ImportOptions(length_unit="in", feed_unit="in/min"))
    axes = rec.streams["axes"]
    t0 = np.datetime64("2020-01-01T00:00:00.100", "ns").astype(np.int64)
    # 0.1 (both), 0.2 (x changes), 0.3 (y held from 0.1 -> new), 0.4 x UNAVAILABLE: no row, 0.5 x back
    assert (axes["t_ns"] - t0).tolist() == [0, 100_000_000, 200_000_000, 400_000_000]
    np.testing.assert_allclose(axes["x_mm"], np.array([1.0, 1.5, 1.5, 2.0]) * MM)
    np.testing.assert_allclose(axes["y_mm"], np.array([2.0, 2.0, 2.5, 2.5]) * MM)
    feed = rec.streams["feed"]
    np.testing.assert_allclose(feed["feed_mm_min"].to_numpy()[[0, -1]], [10 * MM, 20 * MM])  # in/min -> mm/min
    assert rec.streams["line"]["line"].tolist() == [7, 7, 8, 8, 8]
    assert rec.metadata["other_records"] == "2"       # the condition and the message line
    assert "axes 2" in rec.metadata["unavailable"]      # the first row and the UNAVAILABLE at 0.4
    assert rec.metadata["mapping"] == "preset mtconnect-shdr"


def test_shdr_standard_units_are_mm_and_mm_per_s(tmp_path):
    rec = read_source(write(tmp_path, "m.shdr", SHDR), ImportOptions())
    np.testing.assert_allclose(rec.streams["axes"]["x_mm"].iloc[0], 1.0)
    np.testing.assert_allclose(rec.streams["feed"]["feed_mm_min"].iloc[0], 600.0)   # 10 mm/s


def test_shdr_bad_line_names_file_and_line_and_lenient_counts_it(tmp_path):
    path = write(tmp_path, "m.txt", SHDR.replace("2020-01-01T00:00:00.200Z|Xact|1.5000", "garbage|Xact|1.5"))
    with pytest.raises(IngestError, match=r"m\.txt:6: .*not an SHDR timestamp"):
        read_source(path, ImportOptions())
    rec = read_source(path, ImportOptions(strict=False))
    assert "1 bad rows at lines 6" in rec.metadata["bad_records"]
    path = write(tmp_path, "n.txt", SHDR.replace("|Xact|1.5000", "|Xact|one.five"))
    with pytest.raises(IngestError, match=r"n\.txt:6: .*'one\.five' is not a number"):
        read_source(path, ImportOptions())


def test_shdr_map_with_indexed_path_position_and_devices(tmp_path):
    text = ("2020-01-01T00:00:00Z|mill:pp|1 2 3|mill:F|5|lathe:pp|9 9 9\n"
            "2020-01-01T00:00:01Z|mill:pp|4 5 6|lathe:pp|8 8 8\n")
    path = write(tmp_path, "two.txt", text)
    with pytest.raises(IngestError, match="several devices .*lathe, mill.*--device"):
        read_source(path, ImportOptions(mapping="x=pp[0],y=pp[1],z=pp[2],feed=F"))
    rec = read_source(path, ImportOptions(mapping="x=pp[0],y=pp[1],z=pp[2],feed=F", device="mill"))
    np.testing.assert_allclose(rec.streams["axes"][["x_mm", "y_mm", "z_mm"]].to_numpy(), [[1, 2, 3], [4, 5, 6]])


def streams_xml(body: str, *, root: str = "MTConnectStreams") -> str:
    return (f'<?xml version="1.0" encoding="UTF-8"?>\n<{root} xmlns="urn:mtconnect.org:MTConnectStreams:1.3">\n'
            '<Header creationTime="2020-01-01T00:00:00Z" instanceId="1" version="1.3.0"/>\n<Streams>\n'
            f'<DeviceStream name="vmc" uuid="u1">\n{body}\n</DeviceStream>\n</Streams>\n</{root}>\n')


AXES = """<ComponentStream component="Linear" name="X" componentId="x"><Samples>
<Position dataItemId="xc" subType="COMMANDED" sequence="1" timestamp="2020-01-01T00:00:00Z">9</Position>
<Position dataItemId="xa" subType="ACTUAL" sequence="2" timestamp="2020-01-01T00:00:00Z">1.5</Position>
<Position dataItemId="xa" subType="ACTUAL" sequence="5" timestamp="2020-01-01T00:00:00.2Z">UNAVAILABLE</Position>
<Position dataItemId="xa" subType="ACTUAL" sequence="6" timestamp="2020-01-01T00:00:00.3Z">2.5</Position>
</Samples></ComponentStream>
<ComponentStream component="Path" name="path" componentId="p"><Samples>
<PathFeedrate dataItemId="f" subType="ACTUAL" sequence="3" timestamp="2020-01-01T00:00:00Z">2</PathFeedrate>
</Samples><Events>
<LineLabel dataItemId="ll" sequence="4" timestamp="2020-01-01T00:00:00.1Z">N120</LineLabel>
</Events></ComponentStream>"""


def test_streams_xml_maps_by_type_actual_first_and_converts_mm_per_s(tmp_path):
    rec = read_source(write(tmp_path, "s.xml", streams_xml(AXES)), ImportOptions())
    assert rec.metadata["mapping_found"] == "x=xa,feed=f,block_number=ll"
    assert rec.streams["axes"]["x_mm"].tolist() == [1.5, 1.5, 2.5]      # the UNAVAILABLE at 0.2 s left out
    np.testing.assert_allclose(rec.streams["feed"]["feed_mm_min"].iloc[0], 120.0)
    assert rec.streams["line"]["block_number"].tolist() == [120] * 3  # from its first value on, N stripped


def test_streams_xml_refuses_doctype_error_documents_and_names_the_line(tmp_path):
    with pytest.raises(IngestError, match=r"d\.xml:\d+: a DOCTYPE"):
        read_source(write(tmp_path, "d.xml", streams_xml(AXES).replace("<MTConnectStreams",
                                                                        '<!DOCTYPE x [<!ENTITY a "b">]>\n<MTConnectStreams', 1)),
                    ImportOptions())
    with pytest.raises(IngestError, match=r"e\.xml:1: an MTConnectError document: NO_DEVICE: no such device"):
        read_source(write(tmp_path, "e.xml", '<MTConnectError><Errors><Error errorCode="NO_DEVICE">no such device'
                                             '</Error></Errors></MTConnectError>'), ImportOptions())
    broken = streams_xml(AXES).replace("</Samples></ComponentStream>\n<ComponentStream", "</Samples>\n<ComponentStream", 1)
    with pytest.raises(IngestError, match=r"b\.xml:\d+: malformed XML"):
        read_source(write(tmp_path, "b.xml", broken), ImportOptions())
    with pytest.raises(IngestError, match=r"u\.xml:1: .*UTF-16"):
        read_source(write(tmp_path, "u.xml", streams_xml(AXES).encode("utf-16")), ImportOptions())


def test_real_shaped_fixtures_import_with_one_command_each(tmp_path):
    hurco = read_source(REAL / "hurco_shdr.txt", ImportOptions(length_unit="in", feed_unit="in/min"))
    assert set(hurco.streams) == {"axes", "feed", "line", "spindle"} and len(hurco.streams["axes"]) > 100
    assert hurco.streams["feed"]["feed_mm_min"].max() == pytest.approx(12000.0, rel=1e-3)  # the rapid, in/min
    mazak = read_source(REAL / "mazak_streams.xml", ImportOptions())
    assert mazak.metadata["documents"] == "3"
    t = mazak.streams["axes"]["t_ns"].to_numpy()
    assert (np.diff(t) > 0).all()                                       # repeated observations kept once
    assert mazak.streams["line"]["block_number"].iloc[-1] == 190


def test_import_cli_warns_when_the_feed_unit_disagrees_with_the_positions(tmp_path, capsys):
    out = tmp_path / "h.mcap"
    assert main(["import", str(REAL / "hurco_shdr.txt"), "--length-unit", "in", "-o", str(out)]) == 0
    printed = capsys.readouterr().out
    assert "warning: unit_check: the feed column reads" in printed and "--feed-unit" in printed
    assert "unit_check" in read_recording(out).metadata
    assert main(["import", str(REAL / "hurco_shdr.txt"), "--length-unit", "in", "--feed-unit", "in/min", "-o",
                 str(out), "--overwrite"]) == 0
    assert "unit_check" not in capsys.readouterr().out
    # -q: the warning still, the summary not
    assert main(["import", str(REAL / "hurco_shdr.txt"), "--length-unit", "in", "-o", str(out), "--overwrite",
                 "-q"]) == 0
    printed = capsys.readouterr().out
    assert "warning: unit_check: the feed column reads" in printed
    assert all(line.startswith("warning: ") for line in printed.splitlines())
    assert main(["import", str(tmp_path / "none.txt"), "-o", str(tmp_path / "x.mcap")]) == 2
    assert not (tmp_path / "x.mcap").exists()


def test_a_csv_saved_as_txt_is_not_taken_for_an_shdr_log(tmp_path):
    path = write(tmp_path, "trace.txt", "\ufefftime,X\n0,1\n1,2\n")
    with pytest.raises(IngestError, match=r"trace\.txt:1: not an SHDR log: .*csv:FILE"):
        read_source(path, ImportOptions())
    rec = read_source(f"csv:{path}", ImportOptions(mapping="t=time,x=X"))
    assert rec.streams["axes"]["x_mm"].tolist() == [1.0, 2.0]
