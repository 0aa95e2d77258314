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
