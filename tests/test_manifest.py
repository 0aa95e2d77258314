"""The recordings manifest (`feedlog.manifest`): one schema, one reader, a clear error for each bad row."""

from __future__ import annotations

import tomllib
from pathlib import Path

import pytest
import tomli_w
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import FeedlogError
from feedlog.manifest import ManifestError, read_manifest, read_manifests, with_held_back

ROOT = Path(__file__).resolve().parents[1]
RECORDINGS = ROOT / "recordings"
FUZZ = settings(max_examples=80, derandomize=True, deadline=None, suppress_health_check=list(HealthCheck))

GOOD = """description = "two sessions"

[[recording]]
name = "a"
file = "a.mcap"
program = "programs/a.ngc"
profile = "linuxcnc-xyz"
family = "corners"
split = "train"
samples = 10
dropped_frames = 0
cycle_time_s = 1.5
tol_mm = 0.01

[[recording]]
file = "sub/b.mcap"
split = "test"
"""


def write(tmp_path: Path, text: str, name: str = "manifest.toml") -> Path:
    path = tmp_path / name
    path.write_text(text)
    return path


def test_both_spellings_give_one_schema(tmp_path):
    a, b = read_manifest(write(tmp_path, GOOD))
    assert (a.name, a.file, a.split, a.family, a.profile) == ("a", "a.mcap", "train", "corners", "linuxcnc-xyz")
    assert a.path == tmp_path / "a.mcap" and a.program_path == tmp_path / "programs" / "a.ngc"
    assert a.expected == {"samples": 10, "dropped_frames": 0, "cycle_time_s": 1.5}
    assert a["tol_mm"] == 0.01 and a.line == 3
    # name from the file's stem, defaults filled in for lookups but not in the row as written
    assert (b.name, b.split, b.program_path, b.line) == ("b", "test", None, 15)
    assert b["name"] == "b" and "name" in b and "name" not in b.fields and "samples" not in b
    keyed = write(tmp_path, '[recording.c]\ncycle_time_s = 2\n\n[recording."d e"]\nfile = "x.mcap"\n', "keyed.toml")
    c, d = read_manifest(keyed)
    assert (c.name, c.file, c.line, d.name, d.file, d.line) == ("c", "c.mcap", 1, "d e", "x.mcap", 4)


def test_the_bundled_manifests_read_with_their_counts():
    main = read_manifest(RECORDINGS / "manifest.toml")
    assert len(main) == 117 and {e.split for e in main} == {"train", "test"}
    assert all(e.path.is_file() and e.program_path.is_file() and e.profile for e in main)
    assert all(e.line is not None for e in main)
    interp = read_manifest(RECORDINGS / "interp" / "manifest.toml")
    assert {"cutter_comp", "subs_loops"} <= {e.name for e in interp}
    assert all(e.path.is_file() for e in interp)
    # held_back.toml beside it is read with it; the manifest's rows come last and win
    assert list(with_held_back(RECORDINGS / "manifest.toml")) == [e.name for e in main]


def test_a_later_manifest_replaces_an_earlier_row(tmp_path):
    write(tmp_path, '[[recording]]\nname = "a"\nsplit = "test"\n', "held_back.toml")
    manifest = write(tmp_path, '[[recording]]\nname = "a"\n\n[[recording]]\nname = "z"\n')
    assert with_held_back(manifest)["a"].split == "train"
    assert read_manifests(manifest, tmp_path / "held_back.toml")["a"].split == "test"
    assert read_manifests(tmp_path / "missing.toml") == {}


@pytest.mark.parametrize(("row", "match", "line"), [
    ('split = "validation"', r"entry 3: split must be one of train, test, got 'validation'", 19),
    ('samples = -1', r"entry 3: 'samples' must be a whole number >= 0, got -1", 19),
    ('samples = 1.5', r"'samples' must be a whole number", 19),
    ('dropped_frames = true', r"'dropped_frames' must be a whole number", 19),
    ('cycle_time_s = nan', r"'cycle_time_s' must be a finite number of seconds >= 0, got nan", 19),
    ('cycle_time_s = "7"', r"'cycle_time_s' must be a finite number", 19),
    ('program = ""', r"'program' must be non-empty text", 19),
    ('profile = 3', r"'profile' must be non-empty text, got 3", 19),
])
def test_a_wrong_row_names_file_line_and_field(tmp_path, row, match, line):
    path = write(tmp_path, GOOD + '\n[[recording]]\nname = "c"\n' + row + "\n")
    with pytest.raises(ManifestError, match=match) as info:
        read_manifest(path)
    assert str(info.value).startswith(f"{path}:{line}: recording entry")


@pytest.mark.parametrize(("text", "match"), [
    ('[[recording]]\nname = "a"\n\n[[recording]]\nfile = "a.mcap"\n', r":4: recording 'a' is listed twice \(rows 1 and 2\)"),
    ('[[recording]]\nsplit = "test"\n', r":1: recording entry 1: has neither 'name' nor 'file'"),
    ('recording = [1, 2]\n', r"recording entry 1: a table expected, got int"),
    ('recording = "x"\n', r"'recording' must be \[\[recording\]\] tables"),
    ('[[recording]\nname = "a"\n', r"not valid TOML"),
])
def test_a_broken_manifest_is_one_clear_error(tmp_path, text, match):
    with pytest.raises(ManifestError, match=match):
        read_manifest(write(tmp_path, text))


def test_unreadable_or_not_utf8(tmp_path):
    with pytest.raises(ManifestError, match="cannot read the recordings manifest"):
        read_manifest(tmp_path / "none.toml")
    (tmp_path / "bin.toml").write_bytes(b"name = '\xff'")
    with pytest.raises(ManifestError, match=r"not UTF-8 text \(byte 8\)"):
        read_manifest(tmp_path / "bin.toml")


def test_demo_and_train_read_a_wrong_row_the_same_way(tmp_path):
    """The demo's discovery and `feedlog train`'s loader both refuse the same row with the same words."""
    from feedlog.train.load import load_aligned
    from feedlog.viz.pipeline import discover

    import json

    import pandas as pd
    import pyarrow as pa
    import pyarrow.parquet as pq

    from feedlog.align.tables import FORMAT_VERSION, META_KEY

    write(tmp_path, '[[recording]]\nname = "a"\nsplit = "holdout"\n')
    aligned = tmp_path / "aligned" / "a"
    aligned.mkdir(parents=True)
    meta = {"format_version": FORMAT_VERSION, "table": "blocks", "recording": str(tmp_path / "a.mcap")}
    arrow = pa.Table.from_pandas(pd.DataFrame({"block": [0], "duration_s": [1.0]}), preserve_index=False)
    pq.write_table(arrow.replace_schema_metadata({META_KEY: json.dumps(meta).encode()}), aligned / "blocks.parquet")
    with pytest.raises(FeedlogError, match=r"manifest.toml:1: recording entry 1: split must be one of") as demo:
        discover(tmp_path)
    with pytest.raises(FeedlogError) as train:
        load_aligned(aligned)
    assert str(train.value) == str(demo.value)


NAMES = st.text(st.characters(codec="utf-8", exclude_categories=("Cs",)), min_size=0, max_size=8)
VALUES = st.one_of(NAMES, st.integers(-3, 3), st.floats(allow_nan=True, allow_infinity=True), st.booleans(),
                   st.lists(st.integers(0, 2), max_size=2))
ROWS = st.dictionaries(st.sampled_from(["name", "file", "path", "split", "program", "profile", "family",
                                        "samples", "dropped_frames", "cycle_time_s", "other"]), VALUES, max_size=6)


@FUZZ
@given(st.lists(ROWS, max_size=5), st.booleans())
def test_fuzzed_rows_read_or_fail_cleanly(tmp_path_factory, rows, keyed):
    """Any TOML manifest either reads into entries that keep the schema or raises one ManifestError
    naming the file (and the row's line when a row is wrong)."""
    folder = tmp_path_factory.mktemp("m")
    data = ({"recording": {f"k{i}": r for i, r in enumerate(rows)}} if keyed else {"recording": rows})
    try:
        text = tomli_w.dumps(data)
    except (TypeError, ValueError):
        return  # not expressible in TOML
    path = write(folder, text)
    try:
        entries = read_manifest(path)
    except ManifestError as exc:
        assert str(exc).startswith(str(path)), exc
        assert "\n" not in str(exc).strip() or "not valid TOML" in str(exc)
        if "recording entry" in str(exc) or "listed twice" in str(exc):
            assert exc.line is not None
        return
    parsed = tomllib.loads(text)["recording"]
    assert len(entries) == len(parsed)
    assert len({e.name for e in entries}) == len(entries)
    for e in entries:
        assert e.name and e.file and e.split in ("train", "test")
        for k in ("samples", "dropped_frames"):
            assert k not in e.fields or (isinstance(e[k], int) and e[k] >= 0)


def test_the_demo_refuses_a_wrong_row_before_writing_anything(tmp_path, capsys):
    from feedlog.cli import main

    write(tmp_path, '[[recording]]\nname = "a"\nsamples = -3\n')
    assert main(["demo", "--recordings", str(tmp_path), "-o", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip()
    assert err == (f"feedlog demo: error: {tmp_path / 'manifest.toml'}:1: recording entry 1: 'samples' must be "
                   "a whole number >= 0, got -3")
    assert not (tmp_path / "out").exists()
