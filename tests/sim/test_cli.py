"""`feedlog sim` end to end through the CLI registry."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from feedlog.cli import main

ROOT = Path(__file__).resolve().parents[2]
PROGRAM = "G21 G90 G61\nG1 X40 F3000\nG1 Y20\nM2\n"


def test_json_summary_and_parquet(tmp_path, capsys):
    src = tmp_path / "p.ngc"
    src.write_text(PROGRAM)
    out = tmp_path / "series.parquet"
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "--json", "--out", str(out)]) == 0
    summary = json.loads(capsys.readouterr().out)
    assert summary["cycle_time_s"] > summary["cam_time_s"] > 0
    assert summary["blocks"] >= 2
    series = pd.read_parquet(out)
    assert {"t_ns", "x_mm", "y_mm", "feed_mm_min", "block", "line"} <= set(series.columns)
    # refuses to overwrite without --force
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "--out", str(out)]) == 2
    assert "exists" in capsys.readouterr().err


def test_set_changes_the_result(tmp_path, capsys):
    src = tmp_path / "p.ngc"
    src.write_text(PROGRAM)
    main(["sim", str(src), "--profile", "linuxcnc-xyz", "--json"])
    base = json.loads(capsys.readouterr().out)["cycle_time_s"]
    main(["sim", str(src), "--profile", "linuxcnc-xyz", "--json", "--set", "feed_override.override=0.5"])
    slow = json.loads(capsys.readouterr().out)["cycle_time_s"]
    assert slow > 1.5 * base


def test_bad_input_is_one_line(tmp_path, capsys):
    src = tmp_path / "p.ngc"
    src.write_text(PROGRAM)
    assert main(["sim", str(src), "--profile", "nope"]) == 2
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "--set", "warp.x=1"]) == 2
    err = capsys.readouterr().err
    assert "unknown machine profile" in err and "unknown sim mechanism" in err
    assert "Traceback" not in err


def test_several_programs_write_one_folder_each_and_a_dataset(tmp_path, capsys):
    a, b, bad = tmp_path / "a.ngc", tmp_path / "b.ngc", tmp_path / "bad.ngc"
    a.write_text(PROGRAM)
    b.write_text(PROGRAM.replace("X40", "X80"))
    bad.write_text("G21 G90\nG5.3 X1\nM2\n")
    opts = ["--profile", "linuxcnc-xyz", "--json", "-q"]
    assert main(["sim", str(a), str(b), *opts]) == 2
    assert "need an output folder" in capsys.readouterr().err
    out = tmp_path / "out"
    assert main(["sim", str(a), str(b), str(bad), *opts, "-o", str(out), "-j", "2"]) == 2
    captured = capsys.readouterr()
    docs = json.loads(captured.out)
    assert [d["program"] for d in docs] == [str(a), str(b), str(bad)]
    assert docs[1]["cycle_time_s"] > docs[0]["cycle_time_s"] > 0 and "error" in docs[2]
    assert f"{bad}: " in captured.err and "G5.3" in captured.err
    # the same numbers as one program at a time, in the folders and the dataset
    assert main(["sim", str(a), "--profile", "linuxcnc-xyz", "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == docs[0]
    assert json.loads((out / "a" / "summary.json").read_text()) == docs[0]
    blocks = pd.read_parquet(out / "dataset" / "blocks")
    assert sorted(blocks["program"].unique()) == ["a", "b"]
    pd.testing.assert_frame_equal(blocks[blocks["program"] == "b"].drop(columns="program").reset_index(drop=True),
                                  pd.read_parquet(out / "b" / "blocks.parquet"), check_dtype=False)
    assert not (out / "bad").exists()
    assert main(["sim", str(a), *opts, "-o", str(out), "-j", "1"]) == 2   # exists: --overwrite to replace
    assert "pass --overwrite" in capsys.readouterr().err
    # -o names one thing: a folder, or (one program) the series file; several programs need the folder
    assert main(["sim", str(a), str(b), "--profile", "linuxcnc-xyz", "-o", str(tmp_path / "s.parquet")]) == 2
    assert "need an output folder" in capsys.readouterr().err
    assert main(["sim", str(a), "--profile", "linuxcnc-xyz", "-o", str(out), "--blocks-out", str(tmp_path / "b.parquet")]) == 2
    assert "--blocks-out is for one program" in capsys.readouterr().err


def _sim_tables(tmp_path, capsys, program, *extra):
    out, blocks = tmp_path / f"s{len(extra)}.parquet", tmp_path / f"b{len(extra)}.parquet"
    assert main(["sim", str(program), "--profile", "linuxcnc-xyz", "--json", "-q", "--out", str(out),
                 "--blocks-out", str(blocks), "--force", *extra]) == 0
    return json.loads(capsys.readouterr().out), pd.read_parquet(out), pd.read_parquet(blocks)


def test_streamed_run_writes_the_tables_of_the_whole_run(tmp_path, capsys):
    """--stream: windows written to Parquet as they come; the files and the summary are those of the
    whole-program run (same columns, dtypes and values)."""
    program = ROOT / "examples" / "pocket.ngc"
    whole = _sim_tables(tmp_path, capsys, program, "--no-stream")
    streamed = _sim_tables(tmp_path, capsys, program, "--stream")
    assert streamed[0] == whole[0]
    for a, b in zip(streamed[1:], whole[1:]):
        assert len(a) > 10
        pd.testing.assert_frame_equal(a, b, check_exact=True)


def test_streamed_program_without_motion_writes_the_tables_of_the_whole_run(tmp_path, capsys):
    src = tmp_path / "still.ngc"
    src.write_text("G21 G90\nM2\n")
    whole = _sim_tables(tmp_path, capsys, src, "--no-stream")
    streamed = _sim_tables(tmp_path, capsys, src, "--stream")
    assert streamed[0]["blocks"] == whole[0]["blocks"] == 0
    pd.testing.assert_frame_equal(streamed[1], whole[1], check_exact=True)   # one sample at rest
    pd.testing.assert_frame_equal(streamed[2], whole[2], check_exact=True)   # no blocks
    assert len(streamed[2]) == 0


def test_a_run_that_would_not_fit_is_refused_in_one_line(tmp_path, capsys, monkeypatch):
    import feedlog.sim.output as output

    src = tmp_path / "p.ngc"
    src.write_text(PROGRAM)
    monkeypatch.setattr(output, "available_bytes", lambda: 1000)
    out = tmp_path / "series.parquet"
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "needs about" in err and "--stream" in err and "Traceback" not in err
    assert len(err.strip().splitlines()) == 1 and not out.exists()
    # streamed, the same run needs no more than a window
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "--out", str(out), "--stream", "-q"]) == 0
    assert len(pd.read_parquet(out)) > 100


def test_stream_with_a_mechanism_without_windowed_form_is_one_clear_error(tmp_path, capsys):
    src = tmp_path / "p.ngc"
    src.write_text(PROGRAM)
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "--stream", "--enable", "jerk_filter"]) == 2
    err = capsys.readouterr().err
    assert "cannot run window by window" in err and "Traceback" not in err


def test_large_program_streams_by_default_unless_a_mechanism_cannot(tmp_path, capsys, monkeypatch):
    import feedlog.sim.cli as cli
    import feedlog.sim.output as output

    src = tmp_path / "p.ngc"
    src.write_text(PROGRAM)
    monkeypatch.setattr(cli, "STREAM_BYTES", 10)          # every file is "large"
    monkeypatch.setattr(output, "available_bytes", lambda: 1000)   # a whole-program run would not fit
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "-q", "--blocks-out", str(tmp_path / "b.parquet")]) == 0
    assert len(pd.read_parquet(tmp_path / "b.parquet")) >= 2        # streamed
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "-q", "--enable", "jerk_filter"]) == 2
    assert "needs about" in capsys.readouterr().err                 # whole-program run, refused


def test_stream_reads_rs274ngc_only(tmp_path, capsys):
    """Other dialects are translated as a whole: --stream says so; by default they run at once."""
    src = tmp_path / "part.mpf"
    src.write_text("G710 G90\nG1 X10 F1000 ; a line\nM30\n")
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "--stream", "-q"]) == 2
    err = capsys.readouterr().err
    assert "--stream reads RS274/NGC" in err and "sinumerik" in err and "Traceback" not in err
    assert main(["sim", str(src), "--profile", "linuxcnc-xyz", "--json", "-q"]) == 0
    assert json.loads(capsys.readouterr().out)["dialect"] == "sinumerik"
