"""`viz.bundle`: many recordings in one .rrd (a recording id each, one blueprint), all or nothing."""

from __future__ import annotations

import sys

import pytest
from rerun.chunk import RrdReader
from tests.viz import synthetic as syn
from tests.viz.conftest import rrd_blueprint_labels, rrd_content, rrd_recordings

from feedlog.errors import OutputError
from feedlog.viz import bundle as bundle_module
from feedlog.viz.bundle import rrd_bundle
from feedlog.viz.prepare import ViewInputs, prepare_view


@pytest.fixture(scope="module")
def views():
    series, blocks = syn.sim_result()
    flat = prepare_view(ViewInputs(syn.recording(), name="flat", program_blocks=syn.program_blocks(),
                                   sim_series=series, sim_blocks=blocks))
    five = prepare_view(ViewInputs(syn.recording(five_axis=True, rate_hz=500.0), name="five",
                                   program_blocks=syn.program_blocks()))
    return flat, five


def _origins(path):
    reader = RrdReader(path)
    origins = []
    for chunk in reader.stream(store=reader.blueprints()[0]):
        batch = chunk.to_record_batch()
        if "ViewBlueprint:space_origin" in batch.schema.names:
            origins += [o[0] if isinstance(o, list) else o for o in batch.column("ViewBlueprint:space_origin").to_pylist()]
    return origins


def test_every_recording_is_its_own_recording_under_one_blueprint(tmp_path, views):
    flat, five = views
    path = tmp_path / "all.rrd"
    with rrd_bundle(path) as bundle:
        counts = [bundle.add(flat, columns=200), bundle.add(five)]
    assert sorted(rrd_recordings(path)) == ["five", "flat"]
    blueprints, labels = rrd_blueprint_labels(path)
    assert blueprints == 1
    # the five-axis recording's rotary axes have their tabs although the first recording had none
    assert {"/axes/x", "/axes/a", "/axes/c", "/feed", "/blocks", "/path"} <= set(_origins(path))
    assert labels["/axes/c/measured"] == ["c measured (deg/min)"] and labels["/feed/sim"] == ["simulated"]
    # each recording holds its own series, as many rows as log_view sent (flat downsampled, five at full rate)
    flat_rrd, five_rrd = rrd_content(path, "flat"), rrd_content(path, "five")
    assert flat_rrd["/feed/measured"]["rows"] == counts[0]["feed/measured"] < len(flat.measured)
    assert five_rrd["/feed/measured"]["rows"] == counts[1]["feed/measured"] == len(five.measured)
    assert "/axes/a/measured" in five_rrd and "/axes/a/measured" not in flat_rrd
    assert "/feed/sim" in flat_rrd and "/feed/sim" not in five_rrd
    assert [p.name for p in tmp_path.iterdir()] == ["all.rrd"]


def test_a_failing_merge_leaves_nothing_and_says_why(tmp_path, views, monkeypatch):
    fails = (sys.executable, "-c", "import sys; sys.stdin.buffer.read(); print('No space left on device', "
             "file=sys.stderr); sys.exit(3)")
    monkeypatch.setattr(bundle_module, "MERGE_COMMAND", fails)
    path = tmp_path / "all.rrd"
    with pytest.raises(OutputError, match="No space left on device.*nothing was written"):
        with rrd_bundle(path) as bundle:
            bundle.add(views[0], columns=200)
    assert list(tmp_path.iterdir()) == []


def test_an_error_while_adding_leaves_nothing(tmp_path, views):
    path = tmp_path / "all.rrd"
    with pytest.raises(RuntimeError, match="stage failed"):
        with rrd_bundle(path) as bundle:
            bundle.add(views[0], columns=200)
            raise RuntimeError("stage failed")
    assert list(tmp_path.iterdir()) == []


def test_a_missing_folder_is_one_error_before_any_work(tmp_path):
    with pytest.raises(OutputError, match="cannot create the output"):
        with rrd_bundle(tmp_path / "missing" / "all.rrd"):
            pytest.fail("the bundle opened in a folder that does not exist")
