"""feedlog diagnose against a real NC kernel: LinuxCNC machines made from the shipped configs by changing
one thing each (an axis limit, a TRAJ limit, the feed override dial, the blend look-ahead, a first-order
lag on one joint's feedback, a five-axis rotary limit, two at once), recorded with LinuxCNC, diagnosed
with the shipped profile. Diagnose must name the changed key with a value within 15 %, remove at least
80 % of the cycle-time error (70 % of the feedback RMS for the lag, which leaves the timing alone), name
nothing on the unchanged machine, and do the same on the recordings resampled to 5 Hz as a monitoring
box would see them."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from feedlog.diagnose.engine import DiagnoseConfig, diagnose
from feedlog.ingest import read_recording

from .sessions import Job, record_all

pytestmark = [pytest.mark.linuxcnc, pytest.mark.slow]

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "recordings" / "programs"
sys.path.insert(0, str(ROOT / "scripts"))
from linuxcnc_variants import derive_machine  # noqa: E402

P3 = ("corners_f3000_p001", "pocket_f3000_p001")
DENSE = ("longdense_002", "mix_003")
P5 = ("mix5ax_011", "mix5ax_015")
# name: (base, INI changes, feedback lags, feed override, programs, expected {key: value})
MACHINES = {
    "control": ("xyz", [], None, None, P3, {}),
    "xacc300": ("xyz", [("AXIS_X", "MAX_ACCELERATION", 300), ("JOINT_0", "MAX_ACCELERATION", 300)], None, None, P3,
                {"axes.x.acc_max": 300.0}),
    "trajvel30": ("xyz", [("TRAJ", "MAX_LINEAR_VELOCITY", 30)], None, None, P3,
                  {"interpolator.path_vel_max_mm_s": 30.0}),
    "override80": ("xyz", [], None, 0.8, P3, {"sim.feed_override.override": 0.8}),
    "lookahead4": ("xyz", [("TRAJ", "ARC_BLEND_OPTIMIZATION_DEPTH", 4)], None, None, DENSE,
                   {"interpolator.lookahead_blocks": 4}),
    "lagx20ms": ("xyz", [], {0: 0.02}, None, P3, {"sim.following_lag.lag_s.x": 0.02}),
    "avel20": ("xyzac", [("AXIS_A", "MAX_VELOCITY", 20), ("JOINT_3", "MAX_VELOCITY", 20)], None, None, P5,
               {"axes.a.vel_max": 20.0}),
    "two": ("xyz", [("AXIS_X", "MAX_ACCELERATION", 400), ("JOINT_0", "MAX_ACCELERATION", 400),
                    ("AXIS_Y", "MAX_VELOCITY", 30), ("JOINT_1", "MAX_VELOCITY", 30)], None, None, P3,
            {"axes.x.acc_max": 400.0, "axes.y.vel_max": 30.0}),
}
PROFILE = {"xyz": "linuxcnc-xyz", "xyzac": "linuxcnc-xyzac"}
CONFIG = DiagnoseConfig(learned=False)


@pytest.fixture(scope="module")
def recorded(tmp_path_factory) -> dict[str, list[Path]]:
    """Every machine's programs, recorded with LinuxCNC (many sessions at once when isolation allows)."""
    root = tmp_path_factory.mktemp("machines")
    jobs, names = [], []
    for name, (base, changes, lags, override, programs, _) in MACHINES.items():
        ini = derive_machine(base, root / name, changes=changes, feedback_lag=lags)
        options = {"feed_override": override} if override is not None else {}
        jobs += [Job(ini, PROGRAMS / f"{p}.ngc", ini.parent / f"{name}_{p}.mcap", options) for p in programs]
        names += [name] * len(programs)
    record_all(jobs)
    out: dict[str, list[Path]] = {}
    for name, job in zip(names, jobs):
        out.setdefault(name, []).append(job.out)
    return out


def _check(dx, expected: dict[str, float], *, feedback: bool = False) -> None:
    found = {f.parameter: f.fitted_value for f in dx.findings}
    if not expected:
        assert found == {} and dx.unexplained == []
        return
    assert set(found) == set(expected), [f.as_dict() for f in dx.findings]
    for key, value in expected.items():
        assert found[key] == pytest.approx(value, rel=0.15), key
    if feedback:
        fb = dx.levels["feedback"]
        assert fb["rms_after_mm"] <= 0.3 * fb["rms_before_mm"]
    else:
        cyc = dx.levels["cycle"]
        assert abs(cyc["error_after_pct"]) <= 0.2 * abs(cyc["error_before_pct"])


@pytest.mark.parametrize("name", list(MACHINES))
def test_diagnose_names_what_was_changed_on_the_machine(recorded, name):
    base, _, lags, _, _, expected = MACHINES[name]
    dx = diagnose(recorded[name], PROFILE[base], config=CONFIG)
    _check(dx, expected, feedback=bool(lags))


def _at_5_hz(path: Path):
    rec = read_recording(path)
    period = int(rec.metadata.get("servo_period_ns", "1000000"))
    step = round(200_000_000 / period)  # 5 Hz: what a monitoring box sees
    rec.streams = {k: v.iloc[::step].reset_index(drop=True) for k, v in rec.streams.items()
                   if k in ("axes", "feed", "line")}
    rec.source = str(path.with_name(f"{path.stem}_5hz.mcap"))
    return rec


@pytest.mark.parametrize("name", ["control", "xacc300", "trajvel30", "override80"])
def test_diagnose_names_it_at_5_hz_too(recorded, name):
    base, _, _, _, _, expected = MACHINES[name]
    dx = diagnose([_at_5_hz(p) for p in recorded[name]], PROFILE[base], config=CONFIG)
    found = {f.parameter: f.fitted_value for f in dx.findings}
    assert set(found) == set(expected)
    for key, value in expected.items():     # measured as the samples show it: 300.02, 29.999, 0.79999
        assert found[key] == pytest.approx(value, rel=0.03)
    cycle = dx.levels["cycle"]
    if not expected:
        assert dx.unexplained == [] and abs(cycle["error_before_pct"]) < 0.3   # was +1.82 %: the logger
        # stops 50 ms after the last move, so no 5 Hz sample shows the final rest
    else:
        assert abs(cycle["error_after_pct"]) <= 0.05 * abs(cycle["error_before_pct"])
