"""viz and the demo on the bundled LinuxCNC recordings (skipped until recordings/ holds them)."""

from __future__ import annotations

import json
import time
from pathlib import Path

import pytest
from tests.viz.conftest import rrd_blueprint_labels, rrd_content, rrd_recordings

from feedlog.cli import main
from feedlog.ingest import read_recording
from feedlog.viz.pipeline import discover
from feedlog.viz.stages import availability

RECORDINGS = Path(__file__).resolve().parents[2] / "recordings"
pytestmark = pytest.mark.skipif(not (RECORDINGS / "manifest.toml").is_file(),
                                reason="recordings/manifest.toml not present")


def _entries():
    return {e.name: e for e in discover(RECORDINGS)}


def _subset_dir(tmp_path: Path, names: list[str]) -> Path:
    """A recordings folder holding a few of the bundled recordings (linked) and their manifest entries."""
    entries = _entries()
    folder = tmp_path / "recordings"
    folder.mkdir()
    lines = []
    for name in names:
        e = entries[name]
        (folder / e.path.name).symlink_to(e.path)
        lines += ["[[recording]]", f'name = "{name}"', f'file = "{e.path.name}"', f'split = "{e.split}"',
                  f'family = "{e.family}"', f'profile = "{e.profile}"']
        lines += [f"{k} = {v!r}" for k, v in e.expected.items()] + [""]
    (folder / "manifest.toml").write_text("\n".join(lines))
    return folder


def test_view_of_a_five_axis_recording(tmp_path):
    entry = next(e for e in _entries().values() if e.family.startswith("shared_5ax"))
    out = tmp_path / "5ax.rrd"
    assert main(["view", str(entry.path), "--sim", "--lenient", "--save", str(out)]) == 0
    content = rrd_content(out)
    n = len(read_recording(entry.path).streams["axes"])
    assert content["/feed/measured"]["rows"] == n
    assert content["/axes/a/measured"]["rows"] == n and content["/axes/c/measured"]["rows"] == n
    assert "/path/orientation" in content
    if availability()["sim"] is None:
        assert content["/feed/sim"]["rows"] > n // 2


def test_demo_on_a_few_bundled_recordings(tmp_path, capsys):
    names = ["test_p001", "5ax_p001", "corners_f3000_p001"]
    folder = _subset_dir(tmp_path, names)
    assert main(["demo", "--recordings", str(folder), "--out", str(tmp_path / "out"), "--no-train", "--json",
                 "--detail-plots", "1"]) == 0
    rows = {r["recording"]: r for r in json.loads(capsys.readouterr().out)}
    assert set(rows) == set(names)
    for name in names:
        expected = _entries()[name].expected["cycle_time_s"]
        # measured from align (or the line stream): the manifest's cycle time within a few servo periods
        assert rows[name]["measured_s"] == pytest.approx(expected, abs=0.01)
        if availability()["sim"] is None:
            assert rows[name]["sim_s"] == pytest.approx(expected, rel=0.05)
        assert rows[name]["cam_s"] < rows[name]["measured_s"]  # CAM ignores acceleration: always optimistic
    report = (tmp_path / "out" / "report.md").read_text()
    assert "samples and dropped frames match the manifest" in report


@pytest.mark.slow
def test_demo_end_to_end_on_all_bundled_recordings(tmp_path, capsys):
    started = time.perf_counter()
    assert main(["demo", "--out", str(tmp_path / "demo"), "--json"]) == 0
    elapsed = time.perf_counter() - started
    rows = json.loads(capsys.readouterr().out)
    entries = _entries()
    assert [r["recording"] for r in rows] == list(entries)
    for row in rows:
        assert row["measured_s"] == pytest.approx(entries[row["recording"]].expected["cycle_time_s"], abs=0.01)
    out = tmp_path / "demo"
    # one .rrd: every recording its own recording (named after it) under one blueprint
    assert [p.name for p in (out / "rerun").glob("*.rrd")] == ["demo.rrd"]
    assert sorted(rrd_recordings(out / "rerun" / "demo.rrd")) == sorted(entries)
    blueprints, labels = rrd_blueprint_labels(out / "rerun" / "demo.rrd")
    assert blueprints == 1 and {"/feed/measured", "/axes/c/measured", "/blocks/measured"} <= set(labels)
    if availability()["train"] is None:
        assert list((out / "models").glob("*.pt"))
    if (RECORDINGS / "mystery").is_dir():  # the mystery machine, diagnosed
        assert "axes.y.acc_max" in (out / "diagnose" / "report.md").read_text()
    print(f"demo on {len(rows)} recordings: {elapsed:.1f} s")
