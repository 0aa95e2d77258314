"""What the live-source tests share: wait for a recorder process to write, watch how far the file trails
the wall clock, then kill it with SIGKILL."""

from __future__ import annotations

import signal
import subprocess
import threading
import time
from pathlib import Path

import pytest

from feedlog.errors import IngestError
from feedlog.ingest import read_recording


def wait_for_rows(out: Path, proc: subprocess.Popen, *, after_ns: int = 0, rows: int = 1, seconds: float = 30) -> None:
    """Until the recording holds `rows` axes rows later than `after_ns` (fails if the recorder ends)."""
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if proc.poll() is not None:
            pytest.fail(f"recorder ended early: {proc.communicate()}")
        try:
            axes = read_recording(out, recover=True).streams.get("axes")
            if axes is not None and (axes["t_ns"] > after_ns).sum() >= rows:
                return
        except IngestError:
            pass
        time.sleep(0.1)
    pytest.fail("recorder wrote nothing")


def watch_then_kill(out: Path, proc: subprocess.Popen, *, watch_s: float = 2.5) -> tuple[int, int, int]:
    """Watch the file for `watch_s` (how far its newest axes row trails the wall clock), then SIGKILL the
    recorder: (time of the kill, newest row on disk before it, smallest lag seen) in ns."""
    lags, on_disk = [], 0
    until = time.monotonic() + watch_s
    while time.monotonic() < until:
        on_disk = int(read_recording(out, recover=True).streams["axes"]["t_ns"].iloc[-1])
        lags.append(time.time_ns() - on_disk)
        time.sleep(0.1)
    killed_at = time.time_ns()
    proc.send_signal(signal.SIGKILL)
    proc.wait(timeout=10)
    return killed_at, on_disk, min(lags)


def stop_when_set(event: threading.Event, stop: threading.Event, extra_s: float) -> None:
    """Set `stop` `extra_s` after `event` (the replay ended), so the recorder gets what is still in flight."""
    def watch():
        event.wait(90)
        time.sleep(extra_s)
        stop.set()
    threading.Thread(target=watch, daemon=True).start()
