"""`feedlog view`: a recording file in, a .rrd out (checked with Rerun's reader), errors as one line."""

from __future__ import annotations

from importlib import resources

import pytest
from tests.viz import synthetic as syn
from tests.viz.conftest import rrd_content

from feedlog.cli import main
from feedlog.ingest import write_recording
from feedlog.viz.stages import availability


@pytest.fixture
def recording_file(tmp_path):
    profile = resources.files("feedlog.profiles").joinpath("linuxcnc-xyz.toml").read_bytes()
    path = tmp_path / "square.mcap"
    write_recording(path, syn.recording_with_attachments(profile, five_axis=False))
    return path


def test_view_saves_an_rrd_with_the_overlays(tmp_path, recording_file, capsys):
    out = tmp_path / "square.rrd"
    assert main(["view", str(recording_file), "--save", str(out), "--no-align", "--png", str(tmp_path / "png")]) == 0
    printed = capsys.readouterr().out
    assert f"saved {out}" in printed and f"rerun {out}" in printed
    content = rrd_content(out)
    n = len(syn.recording().streams["axes"])
    assert content["/feed/measured"]["rows"] == n
    assert content["/path/tool"]["rows"] == n
    if availability()["toolpath"] is None:
        assert content["/blocks/measured"]["rows"] == 4  # lines 10-13 -> the program's four motion blocks
        assert "/path/programmed" in content
    assert "/feed/sim" not in content  # not asked for
    assert sorted(p.name for p in (tmp_path / "png").iterdir()) == [
        "square_axes.png", "square_blocks.png", "square_feed.png", "square_path.png"]


def test_view_with_sim_overlays_the_simulation_when_sim_exists(tmp_path, recording_file, capsys):
    out = tmp_path / "sim.rrd"
    assert main(["view", str(recording_file), "--sim", "--no-align", "--save", str(out)]) == 0
    content = rrd_content(out)
    if availability()["sim"] is None:
        assert content["/feed/sim"]["rows"] > 1000
        assert content["/residual/sim"]["rows"] > 1000
    else:
        assert "/feed/sim" not in content
        assert "sim" in capsys.readouterr().out


def test_view_refuses_to_overwrite_and_reports_bad_files(tmp_path, recording_file, capsys):
    out = tmp_path / "exists.rrd"
    out.write_bytes(b"keep me")
    assert main(["view", str(recording_file), "--save", str(out)]) == 2
    assert "exists; pass --overwrite" in capsys.readouterr().err
    assert out.read_bytes() == b"keep me"
    broken = tmp_path / "broken.mcap"
    broken.write_bytes(b"not an mcap file at all")
    assert main(["view", str(broken), "--save", str(tmp_path / "b.rrd")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("feedlog view: error:") and "broken.mcap" in err and "Traceback" not in err


def test_view_without_a_display_says_how_else_to_look(recording_file, monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.setattr("sys.platform", "linux")
    assert main(["view", str(recording_file), "--no-align"]) == 2
    assert "use --save OUT.rrd" in capsys.readouterr().err
