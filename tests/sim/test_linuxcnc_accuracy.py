"""The LinuxCNC reference profiles reproduce measured LinuxCNC cycle times (../shared/LINUXCNC.md and
the recordings in recordings/ with their manifest)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from feedlog.sim import simulate
from feedlog.toolpath import parse_program
from feedlog.manifest import ManifestEntry, read_manifest

ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT / "recordings" / "programs"  # the shared LinuxCNC programs, kept in the repo
MANIFEST = ROOT / "recordings" / "manifest.toml"
# program -> (profile, measured cycle time in s, first motion to end of motion)
MEASURED = {
    "test_p001.ngc": ("linuxcnc-xyz", 10.065),
    "test_p01.ngc": ("linuxcnc-xyz", 9.651),
    "test_g61.ngc": ("linuxcnc-xyz", 13.788),
    "dense002q0.ngc": ("linuxcnc-xyz", 5.466),
    "5ax_p001.ngc": ("linuxcnc-xyzac", 13.951),
    "5ax_g61.ngc": ("linuxcnc-xyzac", 13.044),
}


@pytest.mark.parametrize("name", sorted(MEASURED))
def test_cycle_time_within_two_percent(name):
    profile, measured = MEASURED[name]
    res = simulate(parse_program(SHARED / name), profile)
    assert res.cycle_time_s == pytest.approx(measured, rel=0.02)
    # the CAM estimate is far off: the simulation is doing real work
    assert abs(res.cam_time_s - measured) / measured > 0.2


def _recordings() -> list[ManifestEntry]:
    if not MANIFEST.is_file():
        return []
    return read_manifest(MANIFEST)


@pytest.mark.skipif(not MANIFEST.is_file(), reason="recordings/manifest.toml not present")
def test_recorded_sessions_cycle_times():
    """Every recorded LinuxCNC session (3-axis and xyzac-trt) within 1 % but dense002q0 (within 1.5 %),
    median below 0.2 %, and the exact-stop (G61) sessions not biased: without the rapid/feed stop the
    median was 0.34 %, without the G61 tangent check on unfloored speeds mix_009 was -16.5 %, without
    the half-cycle settle at every stop the G61 sessions were 0.6 % fast on average, with the block
    after a parabolic blend halved for its whole length mix5ax_023 was +1.43 %. Runs of very short
    blocks: with line pieces clamped by their untrimmed length dense002q0 was -38 % and longdense_000
    -17 %; with them clamped by what the arcs left but the look-ahead counting consumed lines
    longdense_003 was +8.2 %. dense002q0 is -1.2 % (a uniform drift of about 2 ms per 100 blocks);
    it was within 0.1 % only while a block-time floor was fitted to it."""
    errors, g61 = {}, []
    for rec in _recordings():
        res = simulate(parse_program(MANIFEST.parent / rec["program"], lenient=True), rec["profile"])
        errors[rec["name"]] = (res.cycle_time_s - rec["cycle_time_s"]) / rec["cycle_time_s"]
        if rec.get("tolerance") == "G61":
            g61.append(errors[rec["name"]])
    assert len(errors) >= 10
    assert abs(errors.get("dense002q0", 0.0)) < 0.015, errors.get("dense002q0")
    others = {k: v for k, v in errors.items() if k != "dense002q0"}
    worst = max(others, key=lambda k: abs(others[k]))
    assert abs(others[worst]) < 0.01, (worst, others[worst])
    assert sorted(abs(e) for e in errors.values())[len(errors) // 2] < 0.002
    assert len(g61) >= 5 and abs(sum(g61) / len(g61)) < 0.003


def _line_times_ms(rec) -> pd.Series:
    ln = rec.stream("line")
    t, lines = ln["t_ns"].to_numpy(), ln["line"].to_numpy()
    t0, t1 = int(rec.metadata["motion_start_ns"]), int(rec.metadata["motion_end_ns"])
    inside = (t >= t0) & (t <= t1)
    t, lines = t[inside], lines[inside]
    change = np.flatnonzero(np.diff(lines)) + 1
    starts, ends = np.concatenate([[0], change]), np.concatenate([change, [len(t) - 1]])
    return pd.Series((t[ends] - t[starts]) / 1e6, index=lines[starts]).groupby(level=0).sum()


@pytest.mark.skipif(not MANIFEST.is_file(), reason="recordings/manifest.toml not present")
@pytest.mark.parametrize("name", ["test_p001", "5ax_p001", "pocket_f1000_g61"])
def test_time_per_program_line_matches_the_recording(name):
    """Not just the total: the time LinuxCNC spends on each line (motion.program-line) within a few ms,
    including the parabolic blends of five-axis G64 and the tangent arcs of G61."""
    import numpy as np

    from feedlog.ingest import read_recording

    rec_info = next((r for r in _recordings() if r["name"] == name), None)
    if rec_info is None:
        pytest.skip(f"{name} not in the manifest")
    rec = read_recording(MANIFEST.parent / rec_info["file"])
    res = simulate(parse_program(MANIFEST.parent / rec_info["program"], lenient=True), rec_info["profile"])
    measured = _line_times_ms(rec)
    simulated = res.blocks.groupby("line")["duration_s"].sum() * 1e3
    both = measured.index.intersection(simulated.index)
    assert len(both) >= 0.8 * len(measured)
    assert float(np.mean(np.abs(measured[both] - simulated[both]))) < 5.0
