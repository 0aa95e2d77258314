"""`feedlog record --source mtconnect` against a real HTTP agent on 127.0.0.1 (tests/ingest/mtconnect_test_agent.py)
replaying a bundled LinuxCNC recording: streaming and polling, a buffer overrun, a dropped connection,
kill -9, Ctrl-C, and the one-line errors (refused connection, bad URL, malformed probe, several devices)."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

from feedlog.cli import main
from feedlog.errors import IngestError
from feedlog.ingest import read_recording
from feedlog.ingest.mtconnect_agent import parse_probe
from feedlog.ingest.source_mtconnect import plan_items, record_agent
from tests.ingest.live_helpers import stop_when_set, wait_for_rows, watch_then_kill
from tests.ingest.mtconnect_test_agent import ITEMS, ReplayAgent, probe_xml

ROOT = Path(__file__).resolve().parents[2]
RECORDING = ROOT / "recordings" / "pocket_f3000_p001.mcap"   # 6.8 s of a 3-axis pocket at 1 kHz


def stop_after_replay(agent: ReplayAgent, stop: threading.Event, extra_s: float = 0.6) -> None:
    stop_when_set(agent.finished, stop, extra_s)


def assert_matches_replay(agent: ReplayAgent, rec, *, outside: list[tuple[int, int]] = ()) -> None:
    """Every recorded row holds the replayed values at its time; every change of the replay outside
    the `outside` spans (gaps) is there."""
    axes = rec.streams["axes"]
    t = axes["t_ns"].to_numpy()
    assert np.all(np.diff(t) > 0)
    expected = agent.values_at(t)
    for axis in "xyz":
        np.testing.assert_array_equal(axes[f"{axis}_mm"].to_numpy(), expected[axis])
        np.testing.assert_array_equal(rec.streams["axes_commanded"][f"{axis}_mm"].to_numpy(), expected[axis])
    line = rec.streams["line"]
    np.testing.assert_array_equal(line["line"].to_numpy(), agent.values_at(line["t_ns"].to_numpy())["line"])
    feed = rec.streams["feed"]
    np.testing.assert_allclose(feed["feed_mm_min"].to_numpy(), agent.values_at(feed["t_ns"].to_numpy())["feed"],
                               rtol=1e-12)
    # the times at which the replayed position changed, all present unless inside a gap
    tab = agent.table
    pos = np.stack([tab["x"], tab["y"], tab["z"]], axis=1)
    changed = np.concatenate(([True], np.any(pos[1:] != pos[:-1], axis=1)))
    want = tab["t_ns"][changed] + agent.t0_ns
    for start, end in outside:
        want = want[(want <= start) | (want >= end)]
    assert np.isin(want, t).all(), f"{int((~np.isin(want, t)).sum())} replayed changes missing"


@pytest.mark.parametrize("poll", [False, True], ids=["stream", "poll"])
def test_records_a_replayed_agent_exactly(tmp_path, poll, capsys):
    out = tmp_path / "m.mcap"
    with ReplayAgent(RECORDING) as agent:
        stop = threading.Event()
        stop_after_replay(agent, stop)
        summary = record_agent(agent.url, out, poll=poll, interval_ms=50, stop=stop, progress=None)
    assert summary["stopped_by"] == "signal" and summary["sequences_lost"] == 0 and summary["gaps"] == []
    assert summary["observations"] == len(agent.observations)   # every replayed observation, each once
    rec = read_recording(out)
    assert_matches_replay(agent, rec)
    assert rec.metadata["source"] == "mtconnect" and rec.metadata["agent"] == agent.url
    assert rec.metadata["device"] == "LinuxCNC" and rec.metadata["mode"] == ("poll" if poll else "stream")
    assert "pfo" not in rec.metadata["data_items"]          # the feed override (PERCENT) is not a feed
    events = rec.streams["events"]
    assert events[events["name"] == "execution"]["value"].tolist() == ["UNAVAILABLE", "ACTIVE", "READY"]  # /current first
    assert "replay.ngc" in events[events["name"] == "program"]["value"].tolist()
    assert main(["info", str(out), "--json"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["dropped_frames"] == 0
    assert {s["name"]: s["samples"] for s in info["streams"]}["axes"] == len(rec.streams["axes"])


def test_buffer_overrun_is_a_reported_gap_and_a_dropped_connection_loses_nothing(tmp_path):
    out = tmp_path / "gap.mcap"
    with ReplayAgent(RECORDING, buffer_size=300) as agent:
        # the replay makes ~1650 observations in 6.8 s (~240 per second)
        agent.drop_at_seq = 500           # half a part, then the connection is cut
        agent.stall_at_seq = 1100         # the stream stalls 2.5 s: the 300-sequence buffer overruns
        agent.stall_s = 2.5
        stop = threading.Event()
        stop_after_replay(agent, stop)
        summary = record_agent(agent.url, out, interval_ms=50, stop=stop, progress=None)
    kinds = [e[0] for e in agent.events]
    assert "drop" in kinds and "stall" in kinds and "out_of_range" in kinds
    assert summary["reconnects"] >= 1
    assert len(summary["gaps"]) == 1, summary["gaps"]
    gap = summary["gaps"][0]
    assert gap["lost"] > 0 and "OUT_OF_RANGE" in gap["reason"]
    # everything the agent produced was either recorded once or counted as lost in the gap
    assert summary["observations"] + summary["sequences_lost"] == len(agent.observations)
    assert summary["sequences_lost"] == gap["lost"]
    rec = read_recording(out)
    assert rec.dropped_frames == gap["lost"]
    gaps = rec.streams["gaps"]
    assert len(gaps) == 1 and gaps["lost"].tolist() == [gap["lost"]]
    start, end = int(gaps["t_ns"].iloc[0]), int(gaps["end_t_ns"].iloc[0])
    assert 0.3e9 < end - start < 3e9 and gap["span_s"] == pytest.approx((end - start) / 1e9, abs=1e-3)
    assert_matches_replay(agent, rec, outside=[(start, end)])
    t = rec.streams["axes"]["t_ns"].to_numpy()
    assert not ((t > start) & (t < end)).any()


def test_a_poll_that_fell_behind_the_buffer_is_a_gap(tmp_path):
    out = tmp_path / "poll_gap.mcap"
    with ReplayAgent(RECORDING, buffer_size=200) as agent:
        agent.stall_at_seq = 800          # one poll answered 2 s late, with OUT_OF_RANGE
        agent.stall_s = 2.0
        stop = threading.Event()
        stop_after_replay(agent, stop)
        summary = record_agent(agent.url, out, poll=True, interval_ms=100, stop=stop, progress=None)
    assert "stall" in [e[0] for e in agent.events]
    assert len(summary["gaps"]) == 1 and summary["sequences_lost"] > 0
    assert summary["observations"] + summary["sequences_lost"] == len(agent.observations)
    rec = read_recording(out)
    spans = list(zip(rec.streams["gaps"]["t_ns"].tolist(), rec.streams["gaps"]["end_t_ns"].tolist()))
    assert_matches_replay(agent, rec, outside=spans)


def test_a_damaged_document_is_asked_for_again_and_three_in_a_row_stop_with_one_line(tmp_path, capsys):
    out = tmp_path / "bad.mcap"
    with ReplayAgent(RECORDING) as agent:
        agent.corrupt_at_seq, agent.corrupt_times = 600, 1
        stop = threading.Event()
        stop_after_replay(agent, stop)
        summary = record_agent(agent.url, out, interval_ms=50, stop=stop, progress=None)
    assert ("corrupt" in [e[0] for e in agent.events]) and summary["reconnects"] >= 1
    assert summary["observations"] == len(agent.observations) and summary["gaps"] == []
    assert_matches_replay(agent, read_recording(out))

    out = tmp_path / "worse.mcap"
    with ReplayAgent(RECORDING) as agent:
        agent.corrupt_at_seq, agent.corrupt_times = 600, 100
        err = _one_line_error(["record", "--source", "mtconnect", "--url", agent.url, "-o", str(out), "--quiet",
                               "--duration-s", "30"], capsys)
    assert "malformed XML" in err and "3 times in a row" in err and "the recording keeps what arrived before" in err
    rec = read_recording(out)  # finished: everything before the damaged part is there
    assert 0 < len(rec.streams["axes"]) and rec.streams["axes"]["t_ns"].iloc[-1] < agent.t0_ns + 7e9
    assert_matches_replay_prefix(agent, rec)


def test_an_agent_restart_is_a_gap_of_unknown_size_and_recording_goes_on(tmp_path):
    out = tmp_path / "restart.mcap"
    with ReplayAgent(RECORDING) as agent:
        def restart_midway():
            time.sleep(agent.start_delay_s + 3.0)
            agent.restart()
        threading.Thread(target=restart_midway, daemon=True).start()
        stop = threading.Event()
        stop_after_replay(agent, stop)
        summary = record_agent(agent.url, out, interval_ms=50, stop=stop, progress=None)
    assert len(summary["gaps"]) == 1 and summary["gaps"][0]["lost"] == -1
    assert "restarted" in summary["gaps"][0]["reason"]
    rec = read_recording(out)
    gaps = rec.streams["gaps"]
    spans = list(zip(gaps["t_ns"].tolist(), gaps["end_t_ns"].tolist()))
    assert_matches_replay(agent, rec, outside=spans)
    assert rec.streams["axes"]["t_ns"].iloc[-1] > spans[0][1]      # recorded on after the restart


def _recorder(url: str, out: Path) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "feedlog.cli", "record", "--source", "mtconnect", "--url", url, "-o", str(out),
           "--quiet", "--json"]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, cwd=ROOT)


def test_kill_9_loses_at_most_about_one_second(tmp_path):
    out = tmp_path / "kill.mcap"
    with ReplayAgent(RECORDING, start_delay_s=1.5) as agent:
        proc = _recorder(agent.url, out)
        try:
            wait_for_rows(out, proc)
            killed_at_ns, on_disk_ns, min_lag_ns = watch_then_kill(out, proc)
        finally:
            proc.kill()
        assert not agent.finished.is_set(), "the replay ended before the kill: nothing to lose was tested"
    with pytest.raises(IngestError, match="truncated"):
        read_recording(out)
    rec = read_recording(out, recover=True)
    t = rec.streams["axes"]["t_ns"].to_numpy()
    assert len(t) > 100 and t[-1] >= on_disk_ns
    # agent times run with the wall clock; the file trails it by the smallest lag seen (right after
    # a flush) plus at most one flush interval (1 s) and the 0.3 s hold-back of the latest time
    assert (killed_at_ns - t[-1]) - min_lag_ns < 1.4e9
    assert_matches_replay_prefix(agent, rec)


def assert_matches_replay_prefix(agent: ReplayAgent, rec) -> None:
    axes = rec.streams["axes"]
    expected = agent.values_at(axes["t_ns"].to_numpy())
    for axis in "xyz":
        np.testing.assert_array_equal(axes[f"{axis}_mm"].to_numpy(), expected[axis])


def test_sigint_finishes_the_file(tmp_path):
    out = tmp_path / "int.mcap"
    with ReplayAgent(RECORDING) as agent:
        proc = _recorder(agent.url, out)
        try:
            wait_for_rows(out, proc)
            time.sleep(0.5)
            proc.send_signal(signal.SIGINT)
            stdout, stderr = proc.communicate(timeout=30)
        finally:
            proc.kill()
    assert proc.returncode == 0, stderr
    summary = json.loads(stdout)
    assert summary["stopped_by"] == "signal"
    rec = read_recording(out)   # strict: the file was finished
    assert len(rec.streams["axes"]) == summary["streams"]["axes"] > 10
    assert_matches_replay_prefix(agent, rec)


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _one_line_error(argv: list[str], capsys) -> str:
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert "Traceback" not in err and len(err.splitlines()) == 1, err
    return err


def test_bad_urls_and_a_refused_connection_are_one_line_errors(tmp_path, capsys):
    base = ["record", "--source", "mtconnect", "-o", str(tmp_path / "x.mcap"), "--url"]
    assert "cannot reach the MTConnect agent" in _one_line_error(base + [f"http://127.0.0.1:{_free_port()}"], capsys)
    assert "bad agent URL" in _one_line_error(base + ["opc.tcp://127.0.0.1:4840"], capsys)
    assert "bad agent URL" in _one_line_error(base + ["http://127.0.0.1:99999"], capsys)
    assert "bad agent URL" in _one_line_error(base + ["http:///probe"], capsys)
    assert "needs --url" in _one_line_error(base[:-1], capsys)
    assert not (tmp_path / "x.mcap").exists()


def test_malformed_probe_and_devices_are_one_line_errors(tmp_path, capsys):
    out = str(tmp_path / "x.mcap")
    with ReplayAgent(RECORDING) as agent:
        argv = ["record", "--source", "mtconnect", "--url", agent.url, "-o", out]
        agent.probe_body = probe_xml()[:300]
        assert "malformed XML" in _one_line_error(argv, capsys)
        agent.probe_body = b'<?xml version="1.0"?><!DOCTYPE x [<!ENTITY a "b">]><MTConnectDevices/>'
        assert "DOCTYPE" in _one_line_error(argv, capsys)
        agent.probe_body = b"<html>not an agent</html>"
        assert "not an MTConnect probe" in _one_line_error(argv, capsys)
        agent.probe_body = probe_xml(items={k: v for k, v in ITEMS.items() if v[3] in ("EXECUTION", "AVAILABILITY")})
        assert "no axis positions, path feed or line number" in _one_line_error(argv, capsys)
        agent.probe_body = probe_xml(extra_devices=("Lathe",))
        assert "several devices (LinuxCNC, Lathe): choose one with --device" in _one_line_error(argv, capsys)
        assert "no device 'Mill' at the agent (devices: LinuxCNC, Lathe)" in _one_line_error(
            argv + ["--device", "Mill"], capsys)
        assert "HTTP 404 (NO_DEVICE: no device Lathe)" in _one_line_error(argv + ["--device", "Lathe"], capsys)
    assert not Path(out).exists()


def test_units_come_from_the_probe():
    items = {"Xa": ("Linear", "X", "SAMPLE", "POSITION", "ACTUAL", "INCH"),
             "Ca": ("Rotary", "C", "SAMPLE", "ANGLE", "ACTUAL", "RADIAN"),
             "f": ("Path", "p", "SAMPLE", "PATH_FEEDRATE", "ACTUAL", "INCH/MINUTE"),
             "fc": ("Path", "p", "SAMPLE", "PATH_FEEDRATE", "PROGRAMMED", "MILLIMETER/SECOND"),
             "l": ("Path", "p", "EVENT", "LINE", "", "")}
    plan = plan_items(parse_probe(probe_xml(items=items))[0])
    cols = {i: (c.stream, c.column, c.factor) for i, c in plan.columns.items()}
    assert cols["Xa"] == ("axes", "x_mm", 25.4) and cols["f"] == ("feed", "feed_mm_min", 25.4)
    assert cols["Ca"][:2] == ("axes", "c_deg") and cols["Ca"][2] == pytest.approx(57.29577951308232)
    assert cols["fc"] == ("feed", "requested_feed_mm_min", 60.0) and cols["l"] == ("line", "line", 0.0)
    with pytest.raises(IngestError, match="units 'FURLONG'"):
        plan_items(parse_probe(probe_xml(items={"Xa": ("Linear", "X", "SAMPLE", "POSITION", "ACTUAL", "FURLONG")}))[0])


def test_a_column_the_source_never_reports_is_left_out_after_two_seconds_not_every_row():
    from feedlog.ingest.live_rows import Column, Pivot, Plan
    from feedlog.ingest.mtconnect_agent import Observation

    plan = Plan("m", columns={"X": Column("axes", "x_mm", 1.0), "Y": Column("axes", "y_mm", 1.0),
                              "C": Column("axes", "c_deg", 1.0), "L": Column("line", "line", 0.0)})
    pivot = Pivot(plan)
    obs, times = [Observation("C", 0, "", "UNAVAILABLE")], [0]
    for k in range(1, 400):  # X every 10 ms from 10 ms on, Y from 15 ms on, C never; line from 20 ms on
        obs += [Observation("X", 3 * k, "", str(k)), Observation("Y", 3 * k + 1, "", str(-k))]
        times += [k * 10_000_000, k * 10_000_000 + (5_000_000 if k == 1 else 0)]
        if k == 2:
            obs.append(Observation("L", 3 * k + 2, "", "N7"))
            times.append(k * 10_000_000)
    out = pivot.feed(obs, np.array(times, dtype=np.int64))
    tail = pivot.release()
    axes = out["axes"]
    assert list(axes.columns) == ["t_ns", "x_mm", "y_mm"] and pivot.left_out == ["axes.c_deg"]
    assert axes["t_ns"].iloc[0] >= 2_000_000_000 and len(axes) + len(tail.get("axes", ())) >= 190
    assert out["line"]["line"].tolist() == [7]   # complete at once: fixed at its first value
    np.testing.assert_array_equal(axes["x_mm"].to_numpy(), -axes["y_mm"].to_numpy())
