"""`feedlog demo` end to end on a folder of synthetic recordings, and on the bundled recordings/."""

from __future__ import annotations

import json
import re
from importlib import resources
from pathlib import Path

import pytest
from tests.viz import synthetic as syn
from tests.viz.conftest import column_values, rrd_blueprint_labels, rrd_content, rrd_recordings

import numpy as np

from feedlog.cli import main
from feedlog.viz.decimate import SCREEN_COLUMNS
from feedlog.viz.overlay import TIMELINE_TIME
from feedlog.viz.prepare import ViewInputs, prepare_view
from feedlog.ingest import write_recording
from feedlog.viz.stages import availability

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def recordings_dir(tmp_path_factory):
    folder = tmp_path_factory.mktemp("recordings")
    profile = resources.files("feedlog.profiles").joinpath("linuxcnc-xyz.toml").read_bytes()
    write_recording(folder / "square_a.mcap", syn.recording_with_attachments(profile))
    write_recording(folder / "square_b.mcap", syn.recording_with_attachments(profile, lead_s=0.5))
    (folder / "broken.mcap").write_bytes(b"\x89MCAP0\r\n truncated")
    (folder / "manifest.toml").write_text(
        '[[recording]]\nfile = "square_a.mcap"\nprogram = "square.ngc"\nsplit = "train"\n\n'
        '[[recording]]\nfile = "square_b.mcap"\nprogram = "square.ngc"\nsplit = "test"\n\n'
        '[[recording]]\nfile = "broken.mcap"\nprogram = "broken.ngc"\nsplit = "test"\n')
    return folder


@pytest.fixture(scope="module")
def demo_run(recordings_dir, tmp_path_factory):
    out = tmp_path_factory.mktemp("demo") / "out"
    code = main(["demo", "--recordings", str(recordings_dir), "--out", str(out), "--no-train"])
    return code, out


def test_demo_table_has_one_row_per_recording_with_real_numbers(demo_run):
    code, out = demo_run
    assert code == 0
    rows = json.loads((out / "cycle_times.json").read_text())
    assert [r["recording"] for r in rows] == ["square_a", "square_b", "broken"]
    assert [r["split"] for r in rows] == ["train", "test", "test"]
    for row in rows[:2]:
        assert row["program"] == "square"
        assert row["measured_s"] == pytest.approx(syn.cycle_time_s(), abs=0.01)
        if availability()["toolpath"] is None or availability()["sim"] is None:
            # CAM: every block at F1200 -> 60 mm at 20 mm/s
            assert row["cam_s"] == pytest.approx(3.0, abs=1e-6)
        if availability()["sim"] is None:
            # exact stop, 1000 mm/s^2 > the recording's 500: the simulation is a little faster
            assert 3.0 < row["sim_s"] < row["measured_s"]
            assert row["sim_err_pct"] == pytest.approx((row["sim_s"] / row["measured_s"] - 1) * 100, abs=1e-3)
        else:
            assert row["sim_s"] is None
    broken = rows[2]
    assert broken["measured_s"] is None and broken["cam_s"] is None and broken["sim_s"] is None


def test_demo_report_names_missing_stages_and_errors(demo_run):
    _, out = demo_run
    report = (out / "report.md").read_text()
    assert "| square | square_a | train |" in report
    assert "cannot read" in report and "broken.mcap" in report
    for stage, reason in availability().items():
        if reason is not None:
            assert f"- {stage}: **not available**" in report
        else:
            assert f"- {stage}: available" in report
    assert "training skipped (--no-train)" in report
    # every image the report links exists
    for line in report.splitlines():
        if line.startswith("!["):
            assert (out / line.split("](")[1].rstrip(")")).is_file(), line


def test_demo_writes_one_rrd_with_every_readable_recording_and_one_blueprint(demo_run):
    _, out = demo_run
    rrd = out / "rerun" / "demo.rrd"
    assert sorted(p.name for p in (out / "rerun").iterdir()) == ["demo.rrd"]
    recordings = rrd_recordings(rrd)
    assert sorted(recordings) == ["square_a", "square_b"]   # broken.mcap has none
    assert {s.application_id for s in recordings.values()} == {"feedlog-demo"}
    blueprints, labels = rrd_blueprint_labels(rrd)
    assert blueprints == 1
    for name in recordings:
        content = rrd_content(rrd, recording=name)
        series = [e for e, c in content.items() if c["rows"] and e.split("/")[1] in ("feed", "axes", "residual", "blocks")]
        assert {"/feed/measured", "/feed/sim", "/axes/x/measured", "/blocks/measured"} <= set(series)
        # every series is labelled once, by the blueprint, not by a styling chunk in each recording
        assert all(labels.get(e) for e in series), [e for e in series if not labels.get(e)]
        assert not any("SeriesLines:names" in c["static"] for c in content.values())
    assert labels["/feed/measured"] == ["measured"] and labels["/axes/y/sim"] == ["y simulated"]
    content = rrd_content(rrd, recording="square_b")
    # downsampled to what the blueprint's series views show (viz.decimate): fewer rows than samples, every
    # row a real sample, the series' highest and lowest feed among them
    full = prepare_view(ViewInputs(syn.recording(lead_s=0.5))).measured
    rows = content["/feed/measured"]["rows"]
    assert rows <= 4 * SCREEN_COLUMNS < len(full)
    t = column_values(content["/feed/measured"], TIMELINE_TIME)
    feed = column_values(content["/feed/measured"], "Scalars:scalars")
    finite = full.dropna(subset=["feed_mm_min"])
    by_time = finite.set_index(finite["t_rel_ns"] - finite["t_rel_ns"].iloc[0])["feed_mm_min"]
    np.testing.assert_allclose(feed, by_time.loc[t - t[0]].to_numpy())
    assert feed.max() == pytest.approx(by_time.max()) and feed.min() == pytest.approx(by_time.min())


def test_demo_json_prints_only_the_table_and_reruns_into_its_own_folder(demo_run, recordings_dir, capsys):
    _, out = demo_run
    capsys.readouterr()
    assert main(["demo", "--recordings", str(recordings_dir), "--out", str(out), "--no-train", "--json",
                 "--detail-plots", "0"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert {"program", "measured_s", "cam_s", "sim_s"} <= set(rows[0])
    assert len(rows) == 3
    # the rerun replaced the earlier outputs: only feed plots now
    assert sorted(p.name for p in (out / "plots").iterdir()) == [
        "cycle_times.png", "square_a_feed.png", "square_b_feed.png"]


def test_demo_refuses_a_folder_it_did_not_write(recordings_dir, tmp_path, capsys):
    (tmp_path / "precious.txt").write_text("mine")
    assert main(["demo", "--recordings", str(recordings_dir), "--out", str(tmp_path), "--no-train"]) == 2
    assert "was not written by feedlog demo" in capsys.readouterr().err
    assert (tmp_path / "precious.txt").read_text() == "mine"


def test_demo_without_recordings_is_an_error(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert main(["demo", "--recordings", str(tmp_path / "empty"), "--out", str(tmp_path / "o")]) == 2
    assert "no recordings" in capsys.readouterr().err


@pytest.mark.skipif(availability()["train"] is not None or availability()["align"] is not None,
                    reason="train/ or align/ not available in this installation")
def test_demo_trains_keeps_the_models_and_predicts_every_recording(recordings_dir, tmp_path, capsys):
    from feedlog.toolpath import parse_program
    from feedlog.train import predict_program

    out = tmp_path / "demo"
    assert main(["demo", "--recordings", str(recordings_dir), "--out", str(out), "--models", "mlp",
                 "--detail-plots", "0", "--json"]) == 0
    rows = {r["recording"]: r for r in json.loads(capsys.readouterr().out)}
    checkpoint = out / "models" / "mlp.pt"
    assert checkpoint.is_file()
    expected = predict_program(parse_program(syn.program_text()), checkpoint, "linuxcnc-xyz").cycle_time_s
    for name in ("square_a", "square_b"):
        assert rows[name]["mlp_s"] == pytest.approx(expected, abs=1e-6)  # JSON keeps 6 decimals
        assert rows[name]["mlp_err_pct"] == pytest.approx((expected / rows[name]["measured_s"] - 1) * 100, abs=1e-3)
    assert rows["broken"]["mlp_s"] is None
    report = (out / "report.md").read_text()
    assert "trained models: `models/mlp.pt`" in report
    assert "trained with the quick preset" in report and "--preset full" in report
    # the block-time overlay carries the model's per-block prediction
    content = rrd_content(out / "rerun" / "demo.rrd", recording="square_b")
    assert content["/blocks/mlp"]["rows"] == 4


def test_demo_without_align_measures_from_the_line_stream_and_says_so(recordings_dir, tmp_path, monkeypatch,
                                                                      capsys):
    from feedlog.viz import stages

    monkeypatch.setattr(stages, "STAGE_FUNCTIONS",
                        stages.STAGE_FUNCTIONS.copy({"align_recording": "feedlog.align:no_such_function"}))
    out = tmp_path / "demo"
    assert main(["demo", "--recordings", str(recordings_dir), "--out", str(out), "--detail-plots", "0",
                 "--json"]) == 0
    rows = {r["recording"]: r for r in json.loads(capsys.readouterr().out)}
    for name in ("square_a", "square_b"):
        # first to last sample of the motion blocks: within one sample period of the true span
        assert rows[name]["measured_s"] == pytest.approx(syn.cycle_time_s(), abs=2e-3)
    report = (out / "report.md").read_text()
    assert "- align: **not available** — feedlog.align.no_such_function is not available" in report
    assert "measured cycle time taken from the program-line stream" in report and "square_a, square_b" in report
    # training needs aligned tables: it says so instead of training on something else
    assert "training skipped: no recording could be aligned" in report
    assert not (out / "models").exists() or not list((out / "models").glob("*.pt"))


def test_demo_simulates_with_the_manifests_profile_over_an_attached_one(recordings_dir, demo_run, tmp_path):
    """An attached profile is the recording day's; the manifest's names today's model (its [sim]
    tables: the bundled recordings carry a block-time floor the LinuxCNC profiles have since dropped)."""
    if availability()["sim"] is not None:
        pytest.skip("no simulation stage")
    folder = tmp_path / "recordings"
    folder.mkdir()
    (folder / "square_a.mcap").write_bytes((recordings_dir / "square_a.mcap").read_bytes())
    text = resources.files("feedlog.profiles").joinpath("linuxcnc-xyz.toml").read_text()
    (folder / "slow.toml").write_text(text + "\n[sim.feed_override]\nenabled = true\noverride = 0.5\n")
    (folder / "manifest.toml").write_text('[[recording]]\nfile = "square_a.mcap"\nprogram = "square.ngc"\n'
                                          'split = "train"\nprofile = "' + str(folder / "slow.toml") + '"\n')
    out = tmp_path / "out"
    assert main(["demo", "--recordings", str(folder), "--out", str(out), "--no-train"]) == 0
    slow = json.loads((out / "cycle_times.json").read_text())[0]["sim_s"]
    attached = json.loads((demo_run[1] / "cycle_times.json").read_text())[0]["sim_s"]
    assert slow > 1.3 * attached


def test_demo_answers_first_counts_recordings_and_can_skip_rrd(recordings_dir, tmp_path, capsys):
    out = tmp_path / "norrd"
    assert main(["demo", "--recordings", str(recordings_dir), "--out", str(out), "--no-train", "--no-rrd",
                 "--detail-plots", "0"]) == 0
    printed = capsys.readouterr().out
    # one line per recording as it finishes (in the order they finish), counted 1..3
    counted = re.findall(r"^\[(\d)/3\] (\w+): verify, align, simulate", printed, flags=re.M)
    assert sorted(k for k, _ in counted) == ["1", "2", "3"]
    assert sorted(name for _, name in counted) == ["broken", "square_a", "square_b"]
    assert not (out / "rerun").exists() and (out / "plots" / "square_b_feed.png").is_file()
    finished = printed[printed.index("feedlog demo finished"):]
    assert finished.splitlines()[1].startswith("3 recordings, 2 with a measured cycle time (2 held out")
    assert "- cam: " in finished
    # one run time: the console's equals the report's (to the printed digit)
    seconds = re.search(r"feedlog demo finished in ([\d.]+) s", finished).group(1)
    text = (out / "report.md").read_text()
    assert f"The demo ran for {seconds} s." in text and f"Run time {seconds} s" in text
    # the long table is not printed: the console ends by saying where it is
    assert "| program |" not in finished and finished.rstrip().endswith("cycle_times.json.")
    report = text.splitlines()
    assert report[2] == "## The answer" and report[4].startswith("3 recordings, 2 with a measured cycle time")
    # the answer comes before the long table and the per-recording sections
    assert text.index("## The answer") < text.index("## Cycle times") < text.index("## square_a")
