"""`feedlog record --source mtconnect` against the test agent serving the NIST test bed's REAL files
(tests/ingest/mtconnect_nist_agent.py): NIST's agent Devices.xml as the probe (seven devices) and the
vendored SHDR logs of Hurco02 (box part, op 2) and Mazak01 replayed at once through one agent, each
recorded end to end by device, then read back, compared with `feedlog import` of the same log, and
shown by `feedlog info`."""

from __future__ import annotations

import json
import threading

import numpy as np
import pandas as pd
import pytest

from feedlog.cli import main
from feedlog.errors import IngestError
from feedlog.ingest import read_recording
from feedlog.ingest.mtconnect_agent import parse_probe
from feedlog.ingest.source_mtconnect import choose_device, plan_items, record_agent
from tests.ingest.live_helpers import stop_when_set
from tests.ingest.mtconnect_nist_agent import DEVICES_XML, HURCO, MAZAK, NistAgent


def _plans() -> dict:
    return {d.name: plan_items(d) for d in parse_probe(DEVICES_XML.read_bytes())}


def _columns(plan) -> dict[str, str]:
    return {f"{c.stream}.{c.column}": item for item, c in plan.columns.items()}


def test_the_real_probe_is_planned_by_type_subtype_and_units():
    devices = parse_probe(DEVICES_XML.read_bytes())
    assert [d.name for d in devices] == ["GFAgie01", "Mazak01", "Mazak03", "Hurco01", "Hurco02", "Hurco03",
                                         "Hurco04", "Hurco06"]
    with pytest.raises(IngestError, match=r"several devices \(GFAgie01, Mazak01, Mazak03, Hurco01, Hurco02, "
                                          r"Hurco03, Hurco04, Hurco06\): choose one with --device"):
        choose_device(devices, None, "probe")
    plans = _plans()
    # the Hurcos: no positions; LINE without a subType is the line, PATH_FEEDRATE ACTUAL in mm/s the feed;
    # the overrides (PATH_FEEDRATE_OVERRIDE, PERCENT) and the spindle (a Rotary's ROTARY_VELOCITY) are not
    hurco = plans["Hurco02"]
    assert _columns(hurco) == {"feed.feed_mm_min": "Hurco02-path_9", "line.line": "Hurco02-path_1"}
    assert hurco.columns["Hurco02-path_9"].factor == 60.0
    assert hurco.events == {"Hurco02-path_2": "program", "Hurco02-path_5": "execution", "Hurco02-path_6": "tool_number"}
    assert hurco.notes == ["no axis positions: align and diagnose use the line stream"]
    # the Mazak mill-turn: X/Y/Z POSITION ACTUAL and B/C ANGLE ACTUAL, not the travel CONDITIONs of the same
    # types on the same components, not the spindle's second Rotary also named C
    mazak = plans["Mazak01"]
    assert _columns(mazak) == {"axes.x_mm": "Mazak01-X_1", "axes.y_mm": "Mazak01-Y_1", "axes.z_mm": "Mazak01-Z_1",
                               "axes.b_deg": "Mazak01-B_4", "axes.c_deg": "Mazak01-C_8",
                               "feed.feed_mm_min": "Mazak01-path_7", "line.line": "Mazak01-path_3"}
    # PROGRAM and PROGRAM subType x:SUB are two events, not one name for both
    assert mazak.events["Mazak01-path_1"] == "program" and mazak.events["Mazak01-path_2"] == "program_sub"
    # the feed the agent converts from FOOT/MINUTE: said, since that is where the NIST Mazak's 5.08 x comes from
    assert any("Mazak01-path_7 (PATH_FEEDRATE): the agent converts the adapter's FOOT/MINUTE to MILLIMETER/SECOND"
               in note for note in mazak.notes)
    assert "POSITION ACTUAL MILLIMETER MACHINE" in mazak.describe()
    assert plans["Mazak03"].events["Mazak03-path_25"] == "tool_asset_id"          # its tool is a TOOL_ASSET_ID
    assert set(_columns(plans["Mazak03"])) == {"axes.x_mm", "axes.z_mm", "axes.c_deg", "feed.feed_mm_min", "line.line"}
    assert set(_columns(plans["GFAgie01"])) == {"axes.x_mm", "axes.y_mm", "axes.z_mm", "axes.a_deg", "axes.c_deg",
                                                "line.line"}


def test_a_travel_condition_is_not_an_axis():
    # the same probe without the Mazak's X position sample: its Linear X keeps only the Xtravel CONDITION
    # (type POSITION), which carries no position and must not become the x column
    xml = DEVICES_XML.read_bytes().replace(
        b'<DataItem category="SAMPLE" coordinateSystem="MACHINE" id="Mazak01-X_1" name="Xabs" nativeUnits="MILLIMETER" '
        b'subType="ACTUAL" type="POSITION" units="MILLIMETER"/>', b"")
    assert b"Mazak01-X_1" not in xml
    mazak = next(d for d in parse_probe(xml) if d.name == "Mazak01")
    assert "axes.x_mm" not in _columns(plan_items(mazak))
    assert "Mazak01-X_2" not in plan_items(mazak).columns


def _expected(agent: NistAgent, device: str, item: str) -> pd.DataFrame:
    """The log's values of one data item (t_ns, text), as the agent replayed them."""
    rows = [(t, text) for t, i, text in agent.logged[device] if i == item]
    return pd.DataFrame(rows, columns=["t_ns", "text"])


def _held(table: pd.DataFrame, column: str, t_ns: np.ndarray) -> np.ndarray:
    k = np.searchsorted(table["t_ns"].to_numpy(), t_ns, side="right") - 1
    assert (k >= 0).all()
    return table[column].to_numpy()[k]


def test_two_real_devices_through_one_agent_recorded_end_to_end(tmp_path, capsys):
    hurco_out, mazak_out = tmp_path / "hurco.mcap", tmp_path / "mazak.mcap"
    summaries = {}
    with NistAgent({"Hurco02": HURCO, "Mazak01": MAZAK}, speed=25.0, max_pause_s=0.002) as agent:
        stop = threading.Event()
        stop_when_set(agent.finished, stop, 0.8)

        def mazak() -> None:   # polled, while the Hurco is streamed: sequence numbers shared by both devices
            summaries["mazak"] = record_agent(agent.url, mazak_out, device="Mazak01", poll=True, interval_ms=100,
                                              stop=stop, progress=None)
        thread = threading.Thread(target=mazak)
        thread.start()
        summaries["hurco"] = record_agent(agent.url, hurco_out, device="Hurco02", interval_ms=50, stop=stop,
                                          progress=None)
        thread.join(timeout=60)
    assert agent.ignored == {"Hurco02": 0, "Mazak01": 21}   # Mazak log keys its Devices.xml lacks (C2..., S3...)
    hurco, mazak = summaries["hurco"], summaries["mazak"]
    for s, device in ((hurco, "Hurco02"), (mazak, "Mazak01")):
        assert s["gaps"] == [] and s["sequences_lost"] == 0 and s["bad_values"] == 0
        values = [e for e in agent.logged[device] if agent.nist_items[e[1]].category != "CONDITION"]
        assert s["observations"] == len(values)   # each sample and event of its device, once; conditions are
    assert len(agent.logged["Mazak01"]) - mazak["observations"] == 72   # passed over (as `import` does)
    assert hurco["late_observations"] == 0 and mazak["late_observations"] == 0   # the 2017 times kept in order

    # -- Hurco02: line and feed, no positions; as `feedlog import` reads the same log --------------------------
    rec = read_recording(hurco_out)
    assert set(rec.streams) == {"line", "feed", "events"}
    assert rec.metadata["device"] == "Hurco02" and "no axis positions" in rec.metadata["notes"]
    line, feed = rec.streams["line"], rec.streams["feed"]
    blocks = _expected(agent, "Hurco02", "Hurco02-path_1")
    np.testing.assert_array_equal(line["t_ns"].to_numpy(), blocks["t_ns"].to_numpy())   # the adapter's times
    np.testing.assert_array_equal(line["line"].to_numpy(), blocks["text"].astype(np.int64).to_numpy())
    assert pd.Timestamp(int(line["t_ns"].iloc[0]), tz="UTC").isoformat().startswith("2017-02-07T19:38:27.609375")
    rates = _expected(agent, "Hurco02", "Hurco02-path_9")
    np.testing.assert_array_equal(feed["t_ns"].to_numpy(), rates["t_ns"].to_numpy())
    np.testing.assert_allclose(feed["feed_mm_min"].to_numpy(), rates["text"].astype(float).to_numpy() * 60.0,
                               rtol=1e-15)
    events = rec.streams["events"]
    assert events[events["name"] == "execution"]["value"].tolist() == ["UNAVAILABLE", "ACTIVE", "PROGRAM_COMPLETED"]
    assert events[events["name"] == "tool_number"]["value"].tolist() == ["UNAVAILABLE", "0.000000", "21.000000"]
    imported = tmp_path / "imported.mcap"
    assert main(["import", str(HURCO), "-o", str(imported), "-q"]) == 0
    ref = read_recording(imported)
    for stream, column in (("line", "line"), ("feed", "feed_mm_min")):
        t = rec.streams[stream]["t_ns"].to_numpy()
        np.testing.assert_array_equal(rec.streams[stream][column].to_numpy(), _held(ref.streams[stream], column, t))
    again = tmp_path / "reimported.mcap"     # the live recording is a recording like any: `feedlog import` takes it
    assert main(["import", str(hurco_out), "-o", str(again), "-q"]) == 0
    for stream in ("line", "feed"):
        assert read_recording(again).streams[stream].equals(rec.streams[stream])
    capsys.readouterr()
    assert main(["info", str(hurco_out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    columns = {s["name"]: s["columns"] for s in info["streams"]}
    assert columns["line"] == ["t_ns", "line"] and columns["feed"] == ["t_ns", "feed_mm_min"]
    assert "feed.feed_mm_min=Hurco02-path_9(PATH_FEEDRATE ACTUAL MILLIMETER/SECOND)" in info["metadata"]["data_items"]
    assert info["metadata"]["units"] == "mm, deg, mm/min"
    # and diagnose, with no program, says what the live recording alone supports: what it says on the import
    assert main(["diagnose", str(hurco_out), "--json"]) == 0
    live_dx = json.loads(capsys.readouterr().out)
    assert main(["diagnose", str(imported), "--json"]) == 0
    file_dx = json.loads(capsys.readouterr().out)
    assert live_dx["mode"] == "no_program" and live_dx["axes"] == {} and live_dx["lines"] == file_dx["lines"]
    assert live_dx["lines"]["last"] == 1209

    # -- Mazak01: positions (B and C too), feed, line, conditions and UNAVAILABLE in the stream ---------------
    rec = read_recording(mazak_out)
    axes = rec.streams["axes"]
    assert list(axes.columns) == ["t_ns", "x_mm", "y_mm", "z_mm", "b_deg", "c_deg"]
    assert rec.metadata["mode"] == "poll" and rec.metadata["device"] == "Mazak01"
    assert mazak["unavailable_rows"] > 0 and mazak["left_out"] == []     # the log starts UNAVAILABLE, then reports
    t = axes["t_ns"].to_numpy()
    for axis, item in (("x_mm", "Mazak01-X_1"), ("z_mm", "Mazak01-Z_1"), ("c_deg", "Mazak01-C_8")):
        expected = _expected(agent, "Mazak01", item)
        np.testing.assert_array_equal(axes[axis].to_numpy(), _held(expected, "text", t).astype(float))
    imported = tmp_path / "mazak_imported.mcap"
    assert main(["import", str(MAZAK), "-o", str(imported), "-q"]) == 0
    ref = read_recording(imported)
    for axis in ("x_mm", "y_mm", "z_mm"):   # the import maps X/Y/Z (not B/C): the same values at every row
        np.testing.assert_array_equal(axes[axis].to_numpy(), _held(ref.streams["axes"], axis, t))
    feed = rec.streams["feed"]
    np.testing.assert_array_equal(feed["feed_mm_min"].to_numpy(),
                                  _held(ref.streams["feed"], "feed_mm_min", feed["t_ns"].to_numpy()))
    assert "FOOT/MINUTE" in rec.metadata["notes"]
    events = rec.streams["events"]
    assert {"program", "program_sub", "execution", "tool_number"} <= set(events["name"])
