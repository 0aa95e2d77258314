"""The bundled mystery machine (recordings/mystery/, scripts/make_mystery.py): diagnose finds the one
change LinuxCNC was recorded with, and the demo shows it first."""

from __future__ import annotations

import sys
import tomllib
from pathlib import Path

import pytest

from feedlog.cli import main
from feedlog.diagnose.engine import DiagnoseConfig, diagnose

ROOT = Path(__file__).resolve().parents[2]
MYSTERY = ROOT / "recordings" / "mystery"
sys.path.insert(0, str(ROOT / "scripts"))
import make_mystery  # noqa: E402

pytestmark = pytest.mark.skipif(not (MYSTERY / "mystery.toml").is_file(), reason="recordings/mystery not present")


def test_the_mystery_recordings_are_what_the_script_makes():
    manifest = tomllib.loads((MYSTERY / "mystery.toml").read_text())
    assert [r["name"] for r in manifest["recording"]] == [f"mystery_{p}" for p in make_mystery.PROGRAMS]
    assert all((MYSTERY / r["file"]).is_file() for r in manifest["recording"])


INI_TO_PROFILE = {"MAX_ACCELERATION": "acc_max", "MAX_VELOCITY": "vel_max"}


def test_diagnose_finds_the_undisclosed_change():
    (section, key, value), = [c for c in make_mystery.CHANGES if c[0].startswith("AXIS_")]
    expected = f"axes.{section.split('_')[1].lower()}.{INI_TO_PROFILE[key]}"
    dx = diagnose(sorted(MYSTERY.glob("*.mcap")), "linuxcnc-xyz", config=DiagnoseConfig(learned=False))
    assert [f.parameter for f in dx.findings] == [expected]
    assert dx.findings[0].fitted_value == pytest.approx(value, rel=0.15)
    cyc = dx.levels["cycle"]
    assert abs(cyc["error_after_pct"]) <= 0.2 * abs(cyc["error_before_pct"])


def test_the_demo_shows_the_mystery_machine_first(tmp_path, capsys):
    folder = tmp_path / "recordings"
    (folder / "mystery").mkdir(parents=True)
    for f in MYSTERY.iterdir():
        (folder / "mystery" / f.name).symlink_to(f)
    src = ROOT / "recordings" / "test_p001.mcap"
    (folder / src.name).symlink_to(src)
    (folder / "manifest.toml").write_text('[[recording]]\nname = "test_p001"\nfile = "test_p001.mcap"\n'
                                          'split = "test"\nprofile = "linuxcnc-xyz"\n')
    out = tmp_path / "out"
    assert main(["demo", "--recordings", str(folder), "--out", str(out), "--no-train", "--detail-plots", "0"]) == 0
    console = capsys.readouterr().out
    assert "The mystery machine" in console and "cause 1: axes.y.acc_max" in console
    report = (out / "report.md").read_text()
    assert report.index("The mystery machine") < report.index("test_p001 (test)")
    assert (out / "diagnose" / "report.md").is_file() and (out / "diagnose" / "profile.toml").is_file()
    # the answer first, in plain sentences with the controller's own name for the key
    answer = report[report.index("## The answer"):report.index("## Summary")]
    assert "The machine took longer than simulated" in answer and "short of the measured time" in answer
    assert "Y-axis maximum acceleration" in answer and "`[AXIS_Y] MAX_ACCELERATION`" in answer
    assert console.index("The machine took longer than simulated") < console.index("report (Markdown")
    # the diagnosis' own report: no raw Python objects, its terms explained where they are used
    dx_report = (out / "diagnose" / "report.md").read_text()
    assert "{'" not in dx_report and "Noise floor: segment timing" in dx_report
    assert "*held-out gain*:" in dx_report and "*misplaced time*:" in dx_report
    assert dx_report.index("## The answer") < dx_report.index("## Findings")


def _cut(source: Path, out: Path, start_s: float, seconds: float) -> Path:
    """`seconds` of a recording from `start_s` after its first sample, every stream alike."""
    from feedlog.ingest import read_recording
    from feedlog.ingest.writer import write_recording

    rec = read_recording(source)
    t0 = min(int(s["t_ns"].iloc[0]) for s in rec.streams.values() if len(s))
    lo, hi = t0 + int(start_s * 1e9), t0 + int((start_s + seconds) * 1e9)
    rec.streams = {name: s[(s["t_ns"] >= lo) & (s["t_ns"] < hi)].reset_index(drop=True)
                   for name, s in rec.streams.items()}
    write_recording(out, rec)
    return out


@pytest.mark.parametrize(("start_s", "seconds"), [(6.0, 0.5), (5.0, 1.0)])
def test_a_short_cut_is_too_little_data_not_a_cause(tmp_path, capsys, start_s, seconds):
    """Issue #30: a 0.5 s cut of a mystery recording once gave "cause 1: sim.feed_override.override = 2"
    (and a 1 s cut of 15 segments a blend tolerance): a second of motion cannot carry a cause."""
    from feedlog.diagnose.hypothesis import MIN_DATA, MIN_SECONDS

    cut = _cut(MYSTERY / "mystery_mix_001.mcap", tmp_path / "cut.mcap", start_s, seconds)
    assert main(["diagnose", str(cut), "--profile", "linuxcnc-xyz", "-o", str(tmp_path / "dx"), "-q"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("feedlog diagnose: error: too little data: "), err
    motion_s = float(err[0].split(" segments (")[1].split(" s of motion")[0])
    assert 0 < motion_s <= seconds < MIN_SECONDS and f"needs {MIN_DATA['timing']} segments and 5 s" in err[0]
    assert not (tmp_path / "dx").exists()

