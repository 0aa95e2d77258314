"""A feed hold on a real NC kernel: LinuxCNC pauses the pocket program 3 s after its start and resumes it
4 s later (the driver's `pause_at`, as an operator's feed hold), the corner program runs through. Diagnose
with the shipped profile must find the hold from the positions with its duration (within 5 % of the
pause LinuxCNC reports in motion time) and line, keep it out of the comparison (nothing named on the
unchanged machine, no cycle error from it), and still name a hidden cause (X acceleration 300 mm/s^2)
within 5 % with the hold in the data."""

from __future__ import annotations

import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

from feedlog.diagnose.engine import DiagnoseConfig, diagnose
from feedlog.ingest import read_recording
from feedlog.ingest.linuxcnc import record_linuxcnc
from feedlog.ingest.linuxcnc_session import isolation_available

pytestmark = [pytest.mark.linuxcnc, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "recordings" / "programs"
sys.path.insert(0, str(ROOT / "scripts"))
from linuxcnc_variants import derive_machine  # noqa: E402

HOLD = (3.0, 4.0)    # seconds after the start, seconds paused
MACHINES = {"control": [], "xacc300": [("AXIS_X", "MAX_ACCELERATION", 300), ("JOINT_0", "MAX_ACCELERATION", 300)]}


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> dict[str, list[Path]]:
    """Per machine: the corner program run through, then the pocket program with the hold."""
    root = tmp_path_factory.mktemp("hold")
    isolate = isolation_available() is None
    plan = [(name, derive_machine("xyz", root / name, changes=changes), program, holds)
            for name, changes in MACHINES.items()
            for program, holds in (("corners_f3000_p001", ()), ("pocket_f3000_p001", (HOLD,)))]

    def session(name, ini, program, holds):
        path = root / f"{name}_{program}.mcap"
        summary = record_linuxcnc(ini, PROGRAMS / f"{program}.ngc", path, timeout_s=120, isolate=isolate,
                                  pause_at=holds)
        assert summary["status"] == "complete", summary
        return path

    with ThreadPoolExecutor(2 if isolate else 1) as pool:
        paths = list(pool.map(lambda job: session(*job), plan))
    return {name: [p for (n, *_), p in zip(plan, paths) if n == name] for name in MACHINES}


def test_a_linuxcnc_feed_hold_is_found_and_kept_out(recorded):
    paused, resumed = (float(x) for x in read_recording(recorded["control"][1]).metadata["feed_holds"].split(":"))
    dx = diagnose(recorded["control"], "linuxcnc-xyz", config=DiagnoseConfig(learned=False))
    holds = dx.cases[1].holds
    (hold,) = holds[holds["removed"]].to_dict("records")
    # the standstill the positions show: the pause less the slowing down into it and the start after it
    assert hold["duration_s"] == pytest.approx(resumed - paused, rel=0.05)
    assert hold["kind"] == "feed hold" and hold["line"] > 0
    assert dx.cases[0].holds is None or not dx.cases[0].holds["removed"].any()
    assert dx.findings == [] and dx.changes == []
    assert abs(dx.levels["cycle"]["error_before_pct"]) < 1.0


def test_a_hidden_cause_is_named_with_a_linuxcnc_feed_hold(recorded):
    dx = diagnose(recorded["xacc300"], "linuxcnc-xyz", config=DiagnoseConfig(learned=False))
    assert [f.parameter for f in dx.findings] == ["axes.x.acc_max"]
    assert dx.findings[0].fitted_value == pytest.approx(300.0, rel=0.05)
