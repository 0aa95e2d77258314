"""`feedlog train` on align-shaped tables with a manifest, then `feedlog predict` on a real program."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from feedlog.align.tables import FORMAT_VERSION, META_KEY
from feedlog.cli import main
from feedlog.errors import ModelError
from feedlog.train import load_many, predict_program
from feedlog.train.synthetic import synthetic_set


def _write_aligned(root: Path) -> Path:
    """OUT/<recording>/blocks.parquet as feedlog align writes them, and a recordings manifest."""
    tables = synthetic_set(n_train=2, n_test=1, n_blocks=80, seed=5, sim_acc_factor=None)
    entries = []
    for t in tables:
        folder = root / "aligned" / t.name
        folder.mkdir(parents=True)
        arrow = pa.Table.from_pandas(t.blocks, preserve_index=False)
        meta = {"format_version": FORMAT_VERSION, "table": "blocks", "recording": str(root / f"{t.name}.mcap"),
                "program": "program.ngc", "cycle_time_s": t.measured_cycle_time_s}
        pq.write_table(arrow.replace_schema_metadata({META_KEY: json.dumps(meta).encode()}), folder / "blocks.parquet")
        entries.append(f'[[recording]]\nname = "{t.name}"\nsplit = "{t.split}"\nprofile = "linuxcnc-xyz"\n'
                       f'family = "fam-{t.name}"\n')
    (root / "manifest.toml").write_text("\n".join(entries))
    return root / "aligned"


def test_load_many_reads_split_and_profile_from_the_manifest(tmp_path):
    aligned = _write_aligned(tmp_path)
    tables = load_many([aligned])
    assert [(t.name, t.split) for t in tables] == [("test-2", "test"), ("train-0", "train"), ("train-1", "train")]
    assert tables[0].profile.name == "linuxcnc-xyz" and tables[0].program == "fam-test-2"
    assert [t.split for t in load_many([aligned], test=["train-0"])] == ["test", "test", "train"]
    with pytest.raises(ModelError, match="--test names no loaded recording: nope"):
        load_many([aligned], test=["nope"])
    with pytest.raises(ModelError, match="no aligned recordings"):
        load_many([tmp_path])


def test_the_manifest_is_found_from_any_folder(tmp_path, monkeypatch):
    """align ran in tmp_path with a relative recording path; training runs elsewhere."""
    (tmp_path / "data").mkdir()
    (tmp_path / "data" / "manifest.toml").write_text(
        '[[recording]]\nname = "r"\nsplit = "test"\nprofile = "linuxcnc-xyz"\n')
    table = synthetic_set(n_train=1, n_test=0, n_blocks=30, seed=2, sim_acc_factor=None)[0]
    arrow = pa.Table.from_pandas(table.blocks, preserve_index=False)
    meta = {"format_version": FORMAT_VERSION, "table": "blocks", "recording": "data/r.mcap", "program": "p.ngc",
            "cycle_time_s": table.measured_cycle_time_s}
    for with_abs in (False, True):
        folder = tmp_path / "out" / str(with_abs) / "r"
        folder.mkdir(parents=True)
        doc = meta | ({"recording_path": str(tmp_path / "data" / "r.mcap")} if with_abs else {})
        pq.write_table(arrow.replace_schema_metadata({META_KEY: json.dumps(doc).encode()}), folder / "blocks.parquet")
    monkeypatch.chdir(tmp_path / "out")
    without, found = (load_many([tmp_path / "out" / key]) for key in ("False", "True"))
    assert without[0].profile is None and without[0].split == "train"  # nothing says otherwise
    assert found[0].profile.name == "linuxcnc-xyz" and found[0].split == "test"


def test_train_then_predict(tmp_path, capsys, examples_dir, monkeypatch):
    aligned = _write_aligned(tmp_path)
    out = tmp_path / "models"
    argv = ["train", str(aligned), "-o", str(out), "--models", "mlp,bilstm-block", "--epochs", "3", "-q"]
    assert main(argv) == 0
    printed = capsys.readouterr().out
    assert "test-2" in printed and "mlp s (err)" in printed and "mean |error|" in printed
    results = pd.read_csv(out / "results.csv")
    assert list(results["recording"]) == ["test-2"]
    assert {"measured_s", "cam_s", "cam_err_pct", "mlp_s", "mlp_err_pct", "bilstm-block_err_pct"} <= set(results)
    assert results["measured_s"].iloc[0] == pytest.approx(load_many([aligned])[0].measured_cycle_time_s)
    assert main(argv) == 2  # outputs exist: refused without --overwrite
    assert "refusing to overwrite" in capsys.readouterr().err
    assert main([*argv, "--overwrite", "--json", "--models", "mlp"]) == 0
    doc = json.loads(capsys.readouterr().out)  # nothing but the JSON document on stdout
    assert [r["recording"] for r in doc["results"]] == ["test-2"] and "mlp" in doc["summary"]

    program = tmp_path / "pocket.ngc"
    program.write_text((examples_dir / "pocket.ngc").read_text())
    work = tmp_path / "work"
    work.mkdir()
    monkeypatch.chdir(work)
    assert main(["predict", str(program), "--model", str(out / "bilstm-block.pt"), "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["blocks_file"] is None and not list(work.iterdir()) and not list(tmp_path.glob("pocket.*.parquet"))
    # twice in a row works: nothing was written (issue #21); -o writes the per-block table
    assert main(["predict", str(program), "--model", str(out / "bilstm-block.pt"), "--json", "-o", "b.parquet"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["blocks_file"] == "b.parquet" and (work / "b.parquet").is_file()
    assert main(["predict", str(program), "--model", str(out / "bilstm-block.pt"), "-o", "b.parquet"]) == 2
    assert "--overwrite" in capsys.readouterr().err
    blocks = pd.read_parquet(doc["blocks_file"])
    assert doc["model"] == "bilstm-block" and doc["profile"] == "linuxcnc-xyz"
    from feedlog.toolpath import parse_program

    dwell = float(parse_program(program).blocks["dwell_s"].sum())
    assert doc["cycle_time_s"] == pytest.approx(blocks["duration_s"].sum() + dwell, rel=1e-6)
    assert dwell == 0 or any("dwell" in n for n in doc["notes"])
    assert doc["cycle_time_s"] > 0 and len(blocks) > 0

    pred = predict_program(program, out / "mlp.pt")
    again = predict_program(out / "mlp.pt", program)  # either argument order
    assert pred.cycle_time_s == pytest.approx(again.cycle_time_s) and pred.cycle_time_s > 0

    assert main(["train", str(aligned), "-o", str(tmp_path / "x"), "--models", "gpt"]) == 2
    assert "unknown model(s) gpt" in capsys.readouterr().err
    assert main(["predict", str(program), "--model", str(tmp_path / "none.pt")]) == 2
    assert "checkpoint not found" in capsys.readouterr().err


def test_a_recording_its_manifest_leaves_out_is_not_trained_on(tmp_path):
    """Aligned beside the manifest but listed neither in it nor in held_back.toml -> noted, not trained on;
    listed in held_back.toml (the simulation misses it) -> trained on like the others."""
    from feedlog.train import train_and_evaluate

    aligned = _write_aligned(tmp_path)
    extra = synthetic_set(n_train=1, n_test=0, n_blocks=80, seed=9, sim_acc_factor=None)[0]
    folder = aligned / "held-back"
    folder.mkdir()
    meta = {"format_version": FORMAT_VERSION, "table": "blocks", "recording": str(tmp_path / "held-back.mcap"),
            "program": "program.ngc", "cycle_time_s": extra.measured_cycle_time_s}
    arrow = pa.Table.from_pandas(extra.blocks, preserve_index=False)
    pq.write_table(arrow.replace_schema_metadata({META_KEY: json.dumps(meta).encode()}), folder / "blocks.parquet")
    tables = load_many([aligned])
    held = next(t for t in tables if t.name == "held-back")
    assert held.metadata["unlisted_in"] == str(tmp_path / "manifest.toml")
    assert all("unlisted_in" not in t.metadata for t in tables if t is not held)
    notes: list[str] = []
    results = train_and_evaluate(tables, out_dir=tmp_path / "models", models=["bilstm-block"], preset="quick",
                                 overrides={"bilstm-block": {"epochs": 2, "hidden": 4}}, progress=False,
                                 log=notes.append)
    assert any(n.startswith("held-back: not trained on: not listed in") for n in notes)
    assert list(results["recording"]) == ["test-2"]
    (tmp_path / "held_back.toml").write_text('[[recording]]\nname = "held-back"\nsplit = "train"\n'
                                             'sim_cycle_time_error = 0.175\n')
    held = next(t for t in load_many([aligned]) if t.name == "held-back")
    assert "unlisted_in" not in held.metadata and held.split == "train"
    assert held.metadata["sim_cycle_time_error"] == "0.175"
    (tmp_path / "held_back.toml").unlink()
    # without a manifest beside the recordings nothing is left out
    (tmp_path / "manifest.toml").unlink()
    assert all("unlisted_in" not in t.metadata for t in load_many([aligned]))
