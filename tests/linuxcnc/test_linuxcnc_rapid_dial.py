"""LinuxCNC's rapid dial below 100 %, throughout a program: the simulation on the shipped profile with
the same dial must give LinuxCNC's cycle time within 0.3 % and the time on every program line within
5 ms. Two programs (tests/linuxcnc/rapid_dial.py) at 50 %: rapids into and out of G1 moves in G64 and
G61, and chains of rapids blended under G64 P1. Before the LinuxCNC rule of sim/rapid_override.py
(`scale_axis_speed`) the simulation was 5.00 % and 6.94 % long (lines up to 465 ms), and with the dial
placed before the TRAJ cap but the blend arcs between rapids sized at the dialed speed, 0.21 % long with
lines up to 150 ms (docs/sim.md "The rapid dial")."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.ingest import read_recording

from .rapid_dial import PROGRAMS, compare
from .sessions import ROOT, Job, record_all

pytestmark = [pytest.mark.linuxcnc, pytest.mark.slow]

DIAL = 0.5


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> dict[str, str]:
    root = tmp_path_factory.mktemp("rapid_dial")
    jobs = []
    for name, text in PROGRAMS.items():
        (root / f"{name}.ngc").write_text(text)
        jobs.append(Job(ROOT / "recordings" / "configs" / "xyz.ini", root / f"{name}.ngc", root / f"{name}.mcap",
                        {"rapid_override_at": ((0.0, DIAL),)}))
    return {name: s["out"] for name, s in zip(PROGRAMS, record_all(jobs))}


@pytest.mark.parametrize("name", list(PROGRAMS))
def test_a_run_at_half_rapid_dial_matches_the_simulation_line_by_line(recorded, name):
    rec = read_recording(recorded[name])
    after_s, dial = (float(x) for x in rec.metadata["rapid_override_turns"].split(":"))
    assert dial == DIAL and after_s < 0.1   # turned before the first move had gone far
    cmp = compare(recorded[name], PROGRAMS[name], DIAL)
    assert abs(cmp.cycle_error_pct) < 0.3, cmp.line()
    assert len(cmp.line_errors_ms) >= 12 and np.abs(cmp.line_errors_ms).max() < 5.0, cmp.line()
    # the old rule (the dial times the capped rapid rate) is what this recording tells apart
    old = compare(recorded[name], PROGRAMS[name], DIAL, scale_axis_speed=False)
    assert old.cycle_error_pct > 1.0, old.line()


def test_the_dial_scales_an_xyz_rapid_above_the_traj_cap(recorded):
    """The speed LinuxCNC holds on `G0 X100 Y60 Z20` from X30 Y0 Z5 (axis-limited 133.4 mm/s, 100 at
    100 %): the dial times the axis-limited speed, not the dial times the cap."""
    rec = read_recording(recorded["g0_g1"])
    feed, line = rec.stream("feed"), rec.stream("line")
    held = np.searchsorted(line["t_ns"].to_numpy(), feed["t_ns"].to_numpy(), side="right") - 1
    on_line = line["line"].to_numpy()[np.clip(held, 0, None)] == 22   # the line in force at each sample
    peak = feed["feed_mm_min"].to_numpy()[on_line].max() / 60.0
    delta = np.array([70.0, 60.0, 15.0])
    axis_speed = np.linalg.norm(delta) / np.max(delta / 100.0)
    assert peak == pytest.approx(min(axis_speed * DIAL, 100.0), rel=1e-3), peak
    assert peak > 100.0 * DIAL * 1.3
