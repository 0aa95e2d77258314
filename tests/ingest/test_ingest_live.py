"""The live logger: virtual CAN bus -> recording; drops, signals, kill -9, disk full, short load test."""

from __future__ import annotations

import json
import resource
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import can
import numpy as np
import pandas as pd
import pytest

from feedlog.cli import main
from feedlog.errors import IngestError
from feedlog.ingest import read_recording
from feedlog.ingest.can_dbc import DbcLayout
from feedlog.ingest.live import FrameBuffer, record_bus
from feedlog.ingest.source_sim import sim_frames

ROOT = Path(__file__).resolve().parents[2]


def series(n: int, *, rate_hz: float = 1000.0) -> pd.DataFrame:
    i = np.arange(n)
    return pd.DataFrame({"t_ns": (i * (1e9 / rate_hz)).astype(np.int64), "x_mm": 0.01 * i, "y_mm": np.sin(i / 100),
                         "z_mm": np.full(n, -2.0), "feed_mm_min": 600.0 + (i % 7), "line": 10 + i // 100})


def send_frames(channel: str, frames, *, skip_every: int = 0) -> threading.Thread:
    def run():
        bus = can.Bus(interface="virtual", channel=channel, preserve_timestamps=True)
        try:
            for k in range(len(frames)):
                if skip_every and k % skip_every == skip_every - 1:
                    continue
                bus.send(can.Message(timestamp=frames.t_ns[k] / 1e9, arbitration_id=int(frames.can_id[k]),
                                     data=frames.data[k].tobytes(), is_extended_id=False))
        finally:
            bus.shutdown()
    thread = threading.Thread(target=run, daemon=True)
    return thread


def long_program(path: Path, loops: int) -> Path:
    lines = ["G21 G90 G64 P0.01", "G0 X0 Y0 Z1", "G1 Z0 F600"]
    for _ in range(loops):
        lines += ["G1 X10 F1200", "G1 Y10", "G1 X0", "G1 Y0"]
    path.write_text("\n".join(lines + ["M2"]) + "\n")
    return path


def test_record_bus_decodes_every_frame_into_standard_streams(tmp_path):
    layout = DbcLayout()
    data = series(3000)
    frames = sim_frames(data, layout, t0_ns=1_700_000_000_000_000_000)
    rx = can.Bus(interface="virtual", channel="live-1")
    sender = send_frames("live-1", frames)
    sender.start()
    try:
        summary = record_bus(rx, tmp_path / "rec.mcap", metadata={"machine": "m"}, progress=None,
                             finished=lambda: not sender.is_alive() and rx.queue.empty())
    finally:
        rx.shutdown()
    assert summary["frames"] == len(frames) == 3 * 3000 and summary["dropped_frames"] == 0
    rec = read_recording(tmp_path / "rec.mcap")
    axes = rec.streams["axes"]
    assert len(axes) == 3000
    np.testing.assert_array_equal(axes["t_ns"].to_numpy() - 1_700_000_000_000_000_000, data["t_ns"].to_numpy())
    np.testing.assert_allclose(axes["x_mm"], data["x_mm"], atol=1e-4)
    np.testing.assert_allclose(axes["y_mm"], data["y_mm"], atol=1e-4)
    np.testing.assert_allclose(rec.streams["feed"]["feed_mm_min"], data["feed_mm_min"], atol=0.006)
    assert rec.streams["line"]["line"].tolist() == data["line"].tolist()
    assert rec.metadata["machine"] == "m" and "feedlog_axes.dbc" in rec.attachments
    assert rec.dropped_frames == 0


def test_missing_frames_are_counted_as_dropped_and_shown_by_info(tmp_path, capsys):
    layout = DbcLayout()
    frames = sim_frames(series(2000), layout)
    rx = can.Bus(interface="virtual", channel="live-2")
    # 60 of 6000 frames never reach the bus; the very last one cannot be noticed (no later seq)
    sender = send_frames("live-2", frames, skip_every=100)
    sender.start()
    try:
        summary = record_bus(rx, tmp_path / "rec.mcap", progress=None,
                             finished=lambda: not sender.is_alive() and rx.queue.empty())
    finally:
        rx.shutdown()
    assert summary["frames"] == 5940
    assert summary["lost_frames"] == 59 and summary["dropped_frames"] == 59
    assert main(["info", str(tmp_path / "rec.mcap"), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["dropped_frames"] == 59


def test_frame_buffer_is_bounded_and_counts_overflow():
    buffer = FrameBuffer(max_frames=10)
    for k in range(25):
        buffer.on_message_received(can.Message(timestamp=k, arbitration_id=0x100, data=bytes(8)))
    buffer.on_message_received(can.Message(is_error_frame=True))
    assert len(buffer) == 10 and buffer.dropped == 15 and buffer.error_frames == 1
    frames = buffer.take()
    assert len(frames) == 10 and len(buffer) == 0 and frames.t_ns[-1] == 9_000_000_000


def test_frame_buffer_counts_frames_no_bus_can_carry_and_keeps_lengths():
    buffer = FrameBuffer()
    buffer.on_message_received(can.Message(timestamp=1.0, arbitration_id=0x100, data=bytes(3)))
    buffer.on_message_received(can.Message(timestamp=1.0, arbitration_id=0x3FFF_FFFF, data=bytes(8)))
    buffer.on_message_received(can.Message(timestamp=1.0, arbitration_id=0x800, data=bytes(8), is_extended_id=False))
    buffer.on_message_received(can.Message(timestamp=float("nan"), arbitration_id=0x100, data=bytes(8)))
    buffer.on_message_received(can.Message(is_error_frame=True))
    assert buffer.received == 5 and buffer.bad_frames == 3 and buffer.error_frames == 1
    frames = buffer.take()
    assert len(frames) == 1 and frames.dlc.tolist() == [3]  # decode_frames leaves the short frame out


def test_sim_source_records_the_simulated_program(tmp_path, capsys):
    from feedlog.sim import simulate
    from feedlog.toolpath import parse_program

    program = long_program(tmp_path / "p.ngc", 1)
    out = tmp_path / "sim.mcap"
    assert main(["record", "--source", "sim", str(program), "--profile", "linuxcnc-xyz", "--speedup", "20",
                 "--rate-hz", "500", "-o", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out)
    expected = simulate(parse_program(program), "linuxcnc-xyz", dt_s=0.002).series
    assert summary["dropped_frames"] == 0 and summary["frames"] == 3 * len(expected)
    rec = read_recording(out)
    axes = rec.streams["axes"]
    assert list(axes.columns) == ["t_ns", "x_mm", "y_mm", "z_mm"]  # no A angle on a three-axis machine
    assert len(axes) == len(expected)
    np.testing.assert_array_equal(np.diff(axes["t_ns"].to_numpy()), np.diff(expected["t_ns"].to_numpy()))
    np.testing.assert_allclose(axes["x_mm"], expected["x_mm"], atol=1e-4)
    np.testing.assert_allclose(rec.streams["feed"]["feed_mm_min"], expected["feed_mm_min"], atol=0.006)
    assert rec.streams["line"]["line"].tolist() == expected["line"].tolist()
    assert rec.program_text == program.read_text() and rec.metadata["speedup"] == "20"
    assert rec.metadata["machine"] == "linuxcnc-xyz"


def _start_recorder(tmp_path: Path, out: Path, *extra: str, preexec=None) -> subprocess.Popen:
    program = long_program(tmp_path / "long.ngc", 20)
    cmd = [sys.executable, "-m", "feedlog.cli", "record", "--source", "sim", str(program), "--profile",
           "linuxcnc-xyz", "--rate-hz", "200", "-o", str(out), "--quiet", "--json", *extra]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, preexec_fn=preexec)


def _wait_for_data(out: Path, proc: subprocess.Popen, seconds: float = 60) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"recorder ended early: {proc.communicate()}")
        try:
            if len(read_recording(out, recover=True).streams.get("axes", ())) > 0:
                return
        except IngestError:
            pass
        time.sleep(0.2)
    pytest.fail("recorder wrote nothing")


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_signal_stops_cleanly_with_a_complete_file(tmp_path, signum):
    out = tmp_path / "rec.mcap"
    proc = _start_recorder(tmp_path, out)
    try:
        _wait_for_data(out, proc)
        time.sleep(1.0)
        proc.send_signal(signum)
        stdout, stderr = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 0, stderr
    summary = json.loads(stdout)
    assert summary["stopped_by"] == "signal"
    rec = read_recording(out)  # strict: the file was finished
    assert len(rec.streams["axes"]) == summary["streams"]["axes"] > 100


def test_kill_9_loses_at_most_one_second(tmp_path):
    out = tmp_path / "rec.mcap"
    proc = _start_recorder(tmp_path, out)
    try:
        _wait_for_data(out, proc)
        # watch the file while the recorder runs: how far its newest sample trails the wall clock
        lags_ns, on_disk_ns = [], 0
        watch_until = time.monotonic() + 2.5
        while time.monotonic() < watch_until:
            on_disk_ns = int(read_recording(out, recover=True).streams["axes"]["t_ns"].iloc[-1])
            lags_ns.append(time.time_ns() - on_disk_ns)
            time.sleep(0.1)
        killed_at_ns = time.time_ns()
        proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        proc.kill()
    with pytest.raises(IngestError, match="truncated"):
        read_recording(out)
    rec = read_recording(out, recover=True)
    t = rec.streams["axes"]["t_ns"].to_numpy()
    assert len(t) > 200
    assert t[-1] >= on_disk_ns  # nothing that had reached the disk is lost
    # speedup 1: machine time runs with the wall clock, behind it by the player's start-up delay
    # (the smallest lag seen, right after a flush). At the kill the file may miss at most one flush
    # interval more (1 s, plus the logger's 0.1 s tick and 5 ms hold-back).
    assert (killed_at_ns - t[-1]) - min(lags_ns) < 1.3e9
    assert np.all(np.diff(t) == 5_000_000)


def test_full_disk_stops_cleanly_and_keeps_what_was_written(tmp_path):
    out = tmp_path / "rec.mcap"

    def limit_file_size():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (60_000, 60_000))

    proc = _start_recorder(tmp_path, out, "--speedup", "10", preexec=limit_file_size)
    stdout, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 1, (stdout, stderr)
    assert "recording stopped" in stderr and "Traceback" not in stderr
    assert json.loads(stdout)["stopped_by"] == "write error"
    assert out.stat().st_size <= 60_000
    rec = read_recording(out)  # strict: the writer ended the file at its last complete flush
    assert "write failed" in rec.metadata["incomplete"]
    t = rec.streams["axes"]["t_ns"].to_numpy()
    assert len(t) > 100 and np.all(np.diff(t) == 5_000_000)


def test_short_load_run_at_30k_frames_per_second_drops_nothing(tmp_path, capsys):
    program = long_program(tmp_path / "p.ngc", 1)  # ~2.2 s of motion
    out = tmp_path / "load.mcap"
    assert main(["record", "--source", "sim", str(program), "--profile", "linuxcnc-xyz", "--rate-hz", "10000",
                 "-o", str(out), "--json", "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["bus_overruns"] == 0 and summary["dropped_frames"] == 0
    assert summary["frames"] == summary["frames_planned"] == 3 * summary["sim_samples"]
    print(f"load: {summary['frames_per_s']:.0f} frames/s achieved, {summary['dropped_frames']} dropped",
          file=sys.stderr)
    assert len(read_recording(out).streams["axes"]) == summary["sim_samples"]


def test_can_source_cli_records_a_virtual_bus_for_a_duration(tmp_path, capsys):
    frames = sim_frames(series(500, rate_hz=500.0), DbcLayout(), t0_ns=time.time_ns() // 10**6 * 10**6)
    out = tmp_path / "can.mcap"

    def delayed():
        time.sleep(0.3)  # the logger's bus must exist before frames are sent
        thread = send_frames("cli-can", frames)
        thread.start()
        thread.join()

    threading.Thread(target=delayed, daemon=True).start()
    assert main(["record", "--source", "can", "--interface", "virtual", "--channel", "cli-can", "--duration-s", "2.5",
                 "-o", str(out), "--json", "--quiet"]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["stopped_by"] == "duration" and summary["frames"] == 1500 and summary["dropped_frames"] == 0
    rec = read_recording(out)
    assert len(rec.streams["axes"]) == 500 and rec.metadata["source"] == "can virtual:cli-can"
    assert main(["record", "--source", "can", "--interface", "nosuchbus", "--channel", "x", "-o",
                 str(tmp_path / "x.mcap")]) == 2
    assert "cannot open CAN bus" in capsys.readouterr().err


def test_stream_columns_follow_dbc_order_whatever_message_is_missing():
    from feedlog.ingest.can_streams import assemble_streams, decode_frames

    layout = DbcLayout()
    frames = sim_frames(series(10), layout)
    only_za = frames.can_id != 0x100
    part = type(frames)(frames.t_ns[only_za], frames.can_id[only_za], frames.data[only_za])
    streams, _ = assemble_streams(decode_frames(part, layout), layout)
    axes = streams["axes"]
    assert list(axes.columns) == ["t_ns", "z_mm", "a_deg"] and (axes["z_mm"] == -2.0).all()
    both = assemble_streams(decode_frames(frames, layout), layout)[0]["axes"]
    assert list(both.columns) == ["t_ns", "x_mm", "y_mm", "z_mm", "a_deg"]
