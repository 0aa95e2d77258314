"""Compact training sessions (stream set, priority) and the random_mix training programs."""

from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feedlog.errors import IngestError
from feedlog.ingest import read_recording
from feedlog.ingest.linuxcnc import STREAM_SETS, select_streams
from feedlog.ingest.linuxcnc_session import _launch_command, priority_prefix
from feedlog.manifest import read_manifest
from feedlog.toolpath import parse_program

ROOT = Path(__file__).resolve().parents[2]
RECORDINGS = ROOT / "recordings"
sys.path.insert(0, str(ROOT / "scripts"))
import linuxcnc_programs as progs  # noqa: E402
import make_recordings  # noqa: E402


def _captured(n: int = 10) -> dict[str, pd.DataFrame]:
    t = np.arange(n, dtype=np.int64) * 1_000_000
    return {
        "axes": pd.DataFrame({"t_ns": t, "x_mm": np.linspace(0, 1, n)}),
        "joints": pd.DataFrame({"t_ns": t, "j0_pos": np.linspace(0, 1, n), "j0_pos_fb": np.linspace(0, 1, n)}),
        "feed": pd.DataFrame({"t_ns": t, "feed_mm_min": np.full(n, 60.0), "requested_feed_mm_min": np.full(n, 60.0),
                              "programmed_feed_mm_min": np.full(n, 60.0), "distance_to_go_mm": np.zeros(n)}),
        "line": pd.DataFrame({"t_ns": t, "line": np.arange(n, dtype=np.int32)}),
        "status": pd.DataFrame({"t_ns": t, "in_position": np.zeros(n, bool)}),
    }


def test_compact_keeps_what_align_train_and_viz_read():
    kept = select_streams(_captured(), "compact")
    assert set(kept) == {"axes", "line", "feed"}
    assert list(kept["feed"].columns) == ["t_ns", "feed_mm_min"]
    assert list(kept["axes"].columns) == ["t_ns", "x_mm"]
    assert set(select_streams(_captured(), "full")) == {"axes", "joints", "feed", "line", "status"}
    with pytest.raises(ValueError, match="not one of"):
        select_streams(_captured(), "tiny")
    assert set(STREAM_SETS) == {"full", "compact"}


def test_priority_prefixes_the_whole_process_tree(tmp_path):
    ini = tmp_path / "m.ini"
    assert _launch_command(ini, isolate=False) == ["linuxcnc", "-r", str(ini)]
    if os.geteuid() == 0:
        assert _launch_command(ini, isolate=False, priority="realtime")[:3] == ["chrt", "--fifo", "20"]
        isolated = _launch_command(ini, isolate=True, priority="high")
        assert isolated[:3] == ["nice", "-n", "-10"] and isolated[3] == "unshare"
    else:
        with pytest.raises(IngestError, match="root"):
            priority_prefix("high")
    with pytest.raises(ValueError, match="not one of"):
        priority_prefix("urgent")


def _mix_entries():
    return [e for e in make_recordings.catalogue() if e.family.startswith("random_mix")]


def test_random_mix_programs_cover_the_regimes_of_the_held_out_tests(tmp_path):
    entries = _mix_entries()
    assert len(entries) >= 60
    assert {e.split for e in entries} == {"train"} and {e.streams for e in entries} == {"compact"}
    assert {e.tolerance.replace(" Q0", "") for e in entries} == {"G61", "G64 P0.01", "G64 P0.05", "G64 P0.1"}
    assert any(e.tolerance.endswith("Q0") for e in entries)
    assert {e.feed_mm_min for e in entries} >= {1000.0, 3000.0}
    assert {e.machine for e in entries} == {"xyz", "xyzac"}
    dense_f3000 = offsets = near_zero = 0
    for e in entries:
        path = tmp_path / f"{e.name}.ngc"
        path.write_text(e.text)
        program = parse_program(path)  # strict: our own parser reads every training program
        assert not program.unsupported, e.name
        moves = [ln for ln in e.text.splitlines() if ln.startswith("G1 ")]
        assert 60 <= len(moves) <= 400, e.name
        xyz = np.array([[float(w[1:]) for w in ln.split()[1:4]] for ln in moves])
        seg = np.linalg.norm(np.diff(xyz, axis=0), axis=1)
        dense_f3000 += int(e.feed_mm_min == 3000.0 and np.sum(seg < 0.03) >= 10)
        offsets += "G10 L2" in e.text
        a = np.array([float(w[1:]) for ln in moves for w in ln.split() if w.startswith("A")])
        if len(a):
            assert a.min() >= -55.0 and a.max() <= 0.0, e.name
            near_zero += int(np.any(a > -2.0))
    assert offsets >= 3 and near_zero >= 5 and dense_f3000 >= 3
    # dense002q0's regime: 3-axis, G64 with Q0, F2500-F3000, mostly dense runs
    dense_q0 = [e for e in entries if e.family == "random_mix_dense"]
    assert len(dense_q0) >= 8 and all(e.tolerance.endswith("Q0") and e.feed_mm_min >= 2500 for e in dense_q0)
    assert sum(e.tolerance == "G64 P0.01 Q0" for e in dense_q0) >= 4
    # no training program is a test program
    tests = {e.text.split("\n", 2)[2] for e in make_recordings.catalogue() if e.split == "test"}
    assert not {e.text.split("\n", 2)[2] for e in entries} & tests


def test_random_mix_is_seeded_and_has_dense_runs():
    a = progs.random_mix(3000, "G64 P0.01 Q0", seed=5, lines=120)
    assert a == progs.random_mix(3000, "G64 P0.01 Q0", seed=5, lines=120)
    assert a != progs.random_mix(3000, "G64 P0.01 Q0", seed=6, lines=120)
    xy = np.array([[float(w[1:]) for w in ln.split()[1:3]] for ln in a.splitlines() if ln.startswith("G1 ")])
    seg = np.linalg.norm(np.diff(xy, axis=0), axis=1)
    assert seg.max() > 5.0  # long lines ...
    assert 0.0 < np.percentile(seg, 5) < 0.07  # ... and dense runs that LinuxCNC's block rate limits at F3000
    assert np.abs(xy).max() <= 30.0 + 1e-6
    # however dense, a program moves for at least min_time_s of CAM time
    total_mm = float(seg.sum())
    assert total_mm >= 2.0 * 3000 / 60 * 0.9


def test_committed_training_sessions_are_compact_and_test_sessions_full():
    path = RECORDINGS / "manifest.toml"
    rows = read_manifest(path)
    for split, streams, expected in (("train", "compact", {"axes", "line", "feed"}),
                                     ("test", "full", {"axes", "joints", "feed", "line", "status"})):
        row = next(r for r in rows if r["split"] == split and r.get("streams") == streams)
        rec = read_recording(RECORDINGS / row["file"])
        assert set(rec.streams) == expected, row["name"]
        assert len(rec.stream("feed")) == row["samples"]


def test_long_dense_programs_have_runs_of_hundreds_of_dense_segments():
    entries = [e for e in make_recordings.catalogue() if e.family == "long_dense"]
    assert len(entries) >= 6 and {e.split for e in entries} == {"train"} and {e.machine for e in entries} == {"xyz"}
    assert {e.tol_mm for e in entries} == {0.01, 0.05, 0.1} and sum(e.tolerance.endswith("Q0") for e in entries) >= 5
    tests = {e.text.split("\n", 2)[2] for e in make_recordings.catalogue() if e.split == "test"}
    for e in entries:
        assert e.text.split("\n", 2)[2] not in tests, e.name
        xy = np.array([[float(w[1:]) for w in ln.split()[1:3]] for ln in e.text.splitlines() if ln.startswith("G1 ")])
        dense = np.linalg.norm(np.diff(xy, axis=0), axis=1) < 0.07
        edges = np.flatnonzero(np.diff(np.r_[0, dense.astype(int), 0]))
        longest = int(np.max(edges[1::2] - edges[::2]))
        assert longest >= 200, (e.name, longest)  # the mixdense runs are at most 80
