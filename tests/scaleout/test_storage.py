"""feedlog.storage and feedlog.dataset: outputs appear whole or not at all, on disk and behind fsspec URLs."""

from __future__ import annotations

import shutil
from pathlib import Path

import fsspec
import pandas as pd
import pytest

from feedlog import storage
from feedlog.align.batch import align_many
from feedlog.dataset import read_dataset, write_partition
from feedlog.errors import FeedlogError

ROOT = Path(__file__).resolve().parents[2]


def test_absolute_and_stem():
    assert storage.absolute("file:///data/x.mcap") == "/data/x.mcap"
    assert storage.absolute("s3://b/x.mcap") == "s3://b/x.mcap"
    assert storage.absolute("rel/x.mcap") == str(Path.cwd() / "rel" / "x.mcap")
    assert storage.stem("s3://b/run/x.mcap") == storage.stem("rel/x.mcap") == "x"


def test_publish_dir_is_all_or_nothing(tmp_path):
    target = str(tmp_path / "out" / "rec")
    (tmp_path / "out").mkdir()
    with pytest.raises(RuntimeError):
        with storage.publish_dir(target, token="t1") as staging:
            (staging / "a.txt").write_text("half")
            raise RuntimeError("killed")
    assert list((tmp_path / "out").iterdir()) == []            # nothing, not even the partial
    with storage.publish_dir(target, token="t1") as staging:
        (staging / "a.txt").write_text("one")
    with storage.publish_dir(target, token="t1") as staging:    # replaces the folder whole
        (staging / "b.txt").write_text("two")
    assert sorted(p.name for p in Path(target).iterdir()) == ["b.txt"]
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["rec"]


def test_remove_partials_only_of_its_job(tmp_path):
    (tmp_path / f".a{storage.PARTIAL}job1-x").mkdir()
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / f".p.parquet{storage.PARTIAL}job1-y").write_text("")
    (tmp_path / f".b{storage.PARTIAL}job2-z").mkdir()
    assert storage.remove_partials(str(tmp_path), "job1") == 2
    assert sorted(p.name for p in tmp_path.rglob("*")) == [f".b{storage.PARTIAL}job2-z", "sub"]


def test_align_to_and_from_an_fsspec_filesystem(tmp_path):
    """memory:// stands for an object store (s3:// etc.): inputs downloaded, outputs put and moved."""
    fs = fsspec.filesystem("memory")
    names = ["test_p001", "mix5ax_000"]
    for name in names:
        fs.pipe(f"/in/{name}.mcap", (ROOT / "recordings" / f"{name}.mcap").read_bytes())
    items = align_many([f"memory://in/{n}.mcap" for n in names], "memory://out", jobs=1, progress=False)
    assert all(i.ok for i in items), [i.error for i in items]
    local = align_many([ROOT / "recordings" / f"{n}.mcap" for n in names], tmp_path / "local", jobs=1,
                       progress=False)
    for name, item, ref in zip(names, items, local):
        assert item.outdir == f"memory://out/{name}" and item.cycle_time_s == ref.cycle_time_s
        for table in ("blocks", "points"):
            with fs.open(f"/out/{name}/{table}.parquet") as f:
                remote = pd.read_parquet(f)
            pd.testing.assert_frame_equal(remote, pd.read_parquet(tmp_path / "local" / name / f"{table}.parquet"))
    blocks = read_dataset("memory://out", "blocks")
    assert sorted(blocks["recording"].unique()) == sorted(names)
    assert not [p for p in fs.find("/out", withdirs=True) if storage.PARTIAL in p]
    again = align_many([f"memory://in/{names[0]}.mcap"], "memory://out", jobs=1, progress=False)
    assert not again[0].ok and "exists; use --overwrite" in again[0].error
    fs.rm("/in", recursive=True)
    fs.rm("/out", recursive=True)


def test_dataset_partitions_one_schema_and_refusals(tmp_path):
    out = tmp_path / "aligned"
    items = align_many([ROOT / "recordings" / "test_p001.mcap", ROOT / "recordings" / "mix5ax_000.mcap"], out,
                       jobs=1, progress=False)
    assert all(i.ok for i in items)
    points = read_dataset(out, "points")
    assert {"va_meas_deg_min", "vb_meas_deg_min", "vc_meas_deg_min"} <= set(points.columns)
    assert points.groupby("recording", observed=True)["va_meas_deg_min"].count().to_dict() == {
        "mix5ax_000": (points["recording"] == "mix5ax_000").sum(), "test_p001": 0}
    # a folder deleted by hand: its partition still refuses a second run without --overwrite
    shutil.rmtree(out / "test_p001")
    again = align_many([ROOT / "recordings" / "test_p001.mcap"], out, jobs=1, progress=False)
    assert not again[0].ok and "partition recording=test_p001" in again[0].error
    assert align_many([ROOT / "recordings" / "test_p001.mcap"], out, jobs=1, progress=False, overwrite=True)[0].ok
    frame = pd.DataFrame({"v": [1.0], "recording": ["x"]})
    target = write_partition(str(tmp_path / "ds"), "t", "recording", "a b/c", frame)
    assert "recording=a%20b%2Fc" in target
    assert read_dataset(tmp_path / "ds", "t")["recording"].tolist() == ["a b/c"]


def test_unknown_url_scheme_says_what_to_install():
    with pytest.raises(FeedlogError, match="no filesystem for this URL"):
        storage.exists("nosuchscheme://bucket/x")
