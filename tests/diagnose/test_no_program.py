"""`feedlog diagnose REC` on recordings with no program: what the data alone says (diagnose/no_program.py).

Bundled LinuxCNC recordings with their program (and profile) stripped: the limits found match the
profile they were recorded with where the recording reached them, and nothing found exceeds it; a
recording slowed down in time (a machine with lower limits, hidden in the data) moves every figure
by the factor; the vendored NIST files (real data) are measured as far as they allow."""

from __future__ import annotations

import json
import tomllib
from pathlib import Path

import numpy as np
import pytest

from feedlog.cli import main
from feedlog.ingest import read_recording, write_recording
from feedlog.profile import load_profile

ROOT = Path(__file__).resolve().parents[2]
NIST = ROOT / "tests" / "fixtures" / "ingest" / "nist"


def _stripped(tmp_path: Path, name: str, *, time_scale: float = 1.0, drop: tuple[str, ...] = ()) -> Path:
    """The bundled recording without its program and profile (times stretched by `time_scale`, the
    streams `drop` left out)."""
    rec = read_recording(ROOT / "recordings" / f"{name}.mcap")
    rec.attachments = {k: v for k, v in rec.attachments.items() if k not in ("program.ngc", "profile.toml")}
    rec.streams = {k: v for k, v in rec.streams.items() if k not in drop}
    if time_scale != 1.0:
        for table in rec.streams.values():
            t = table["t_ns"].to_numpy(np.int64)
            table["t_ns"] = t[0] + np.round((t - t[0]) * time_scale).astype(np.int64)
    out = tmp_path / f"{name}.mcap"
    write_recording(out, rec)
    return out


def _json(argv: list[str], capsys) -> dict:
    capsys.readouterr()
    assert main(argv + ["--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_limits_found_match_the_profile_where_the_recordings_reached_them(tmp_path, capsys):
    recs = [_stripped(tmp_path, "circle_f3000_p001"), _stripped(tmp_path, "mix_013")]
    out = tmp_path / "dx"
    dx = _json(["diagnose", *map(str, recs), "-o", str(out)], capsys)
    truth = load_profile("linuxcnc-xyz")
    assert dx["mode"] == "no_program"
    axes = dx["axes"]
    # x: the rapid along X alone held 100 mm/s (the limit reached: a lower bound equal to it, never claimed,
    # since a speed plateau may as well be a programmed F) and X accelerating alone at 1000 mm/s^2 (claimed)
    assert axes["x"]["held_speed"]["value"] == pytest.approx(truth.axes["x"].vel_max, rel=0.005)
    assert axes["x"]["held_speed"]["alone"] and not any(k.endswith("vel_max") for k in dx["profile"])
    assert dx["profile"]["axes.x.acc_max"] == pytest.approx(truth.axes["x"].acc_max, rel=0.005)
    assert dx["profile"]["axes.z.acc_max"] == pytest.approx(truth.axes["z"].acc_max, rel=0.005)
    # y held 50 mm/s (the programmed F3000, indistinguishable from a limit without the program) and its
    # 1000 mm/s^2 only together with X: neither is claimed as a limit
    assert "axes.y.acc_max" not in dx["profile"]
    assert axes["y"]["held_speed"]["value"] == pytest.approx(50.0, rel=0.01)
    # nothing found lies above the true limit
    for a, facts in axes.items():
        assert facts["peak_speed"] <= truth.axes[a].vel_max * 1.005
        assert facts["peak_acc"] <= truth.axes[a].acc_max * 1.005
    # the envelope is what the axes travelled
    for a in "xyz":
        lo = min(read_recording(r).streams["axes"][f"{a}_mm"].min() for r in recs)
        assert axes[a]["min"] == pytest.approx(lo, abs=1e-6)
    assert axes["x"]["min"] == pytest.approx(-24.99) and axes["x"]["max"] == pytest.approx(25.0)
    # the feed plateaus: the programmed F3000 longest, the 6000 mm/min rapid too
    levels = [p["level_mm_min"] for p in dx["feed"]["plateaus"]]
    assert levels[0] == pytest.approx(3000.0, rel=0.001) and any(abs(v - 6000.0) < 6 for v in levels)
    assert dx["lines"]["distinct"] > 100 and dx["would_add"]
    # the folder: report, JSON, and the generic profile with what the data holds, loadable as a profile
    assert sorted(p.name for p in out.iterdir()) == ["diagnose.json", "profile.toml", "report.md"]
    fitted = load_profile(out / "profile.toml")
    assert fitted.axes["x"].acc_max == pytest.approx(1000.0, rel=0.005)
    assert fitted.axes["z"].acc_max == pytest.approx(1000.0, rel=0.005)
    assert fitted.axes["y"].acc_max == load_profile("generic-xyz").axes["y"].acc_max   # not constrained: the guess
    assert fitted.axes["x"].vel_max == load_profile("generic-xyz").axes["x"].vel_max   # 250 >= the 100 seen
    assert "axes.x.acc_max = 998.6: held by the data" in (out / "profile.toml").read_text()
    assert "What a program would add" in (out / "report.md").read_text()
    assert tomllib.loads((out / "profile.toml").read_text())["name"] == "fitted-from-data"


def test_a_feed_plateau_held_alone_is_not_claimed_as_a_speed_limit(tmp_path, capsys):
    # corners_f3000_p001: F3000 moves along X alone (and along Y alone) hold 50 mm/s under a 100 mm/s limit,
    # and no rapid reaches the limit: the fastest plateau, held alone, is still only the programmed feed
    dx = _json(["diagnose", str(_stripped(tmp_path, "corners_f3000_p001"))], capsys)
    for axis in "xy":
        held = dx["axes"][axis]["held_speed"]
        assert held["value"] == pytest.approx(50.0, rel=0.001) and held["alone"]
    assert not any(k.endswith("vel_max") for k in dx["profile"])
    assert dx["profile"]["axes.x.acc_max"] == pytest.approx(1000.0, rel=0.005)


def test_a_slower_machine_hidden_in_the_data_is_found(tmp_path, capsys):
    # the same session 1.25 x slower: every speed / 1.25, every acceleration / 1.5625 (without the feed
    # stream, whose recorded values would not follow: the path speed then comes from the positions)
    dx = _json(["diagnose", str(_stripped(tmp_path, "circle_f3000_p001", time_scale=1.25, drop=("feed",)))], capsys)
    assert dx["feed"]["source"] == "linear axes"
    assert dx["axes"]["x"]["held_speed"]["value"] == pytest.approx(100.0 / 1.25, rel=0.005)
    assert dx["profile"]["axes.x.acc_max"] == pytest.approx(1000.0 / 1.5625, rel=0.005)
    assert dx["axes"]["z"]["held_acc"]["value"] == pytest.approx(500.0 / 1.5625, rel=0.005)
    assert dx["feed"]["plateaus"][0]["level_mm_min"] == pytest.approx(3000.0 / 1.25, rel=0.001)


def test_a_feed_stream_that_disagrees_with_the_positions_is_a_warning(tmp_path, capsys):
    # the slowed-down copy keeps its recorded feed stream: it now reads 1.25 x what the positions move at
    dx = _json(["diagnose", str(_stripped(tmp_path, "circle_f3000_p001", time_scale=1.25))], capsys)
    assert any("the feed stream reads 1.250 x the path speed of the positions" in w for w in dx["warnings"])
    assert dx["feed"]["plateaus"][0]["level_mm_min"] == pytest.approx(3000.0)   # the stream's, and said so
    (tmp_path / "plain").mkdir()
    dx = _json(["diagnose", str(_stripped(tmp_path / "plain", "circle_f3000_p001"))], capsys)
    assert dx["warnings"] == []


def test_an_output_that_cannot_be_written_is_exit_1_and_leaves_nothing(tmp_path, capsys):
    blocker = tmp_path / "file"
    blocker.write_text("not a folder")
    rec = _stripped(tmp_path, "corners_f3000_p001")
    capsys.readouterr()
    assert main(["diagnose", str(rec), "-o", str(blocker / "dx")]) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("feedlog diagnose: error: ") and "\n" not in err and "Traceback" not in err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["corners_f3000_p001.mcap", "file"]


def test_five_axes_rotary_limits_and_no_generic_profile(tmp_path, capsys):
    out = tmp_path / "dx5"
    dx = _json(["diagnose", str(_stripped(tmp_path, "5ax_far_f2000_g61")), "-o", str(out)], capsys)
    truth = load_profile("linuxcnc-xyzac")
    assert dx["axes"]["a"]["held_speed"]["value"] == pytest.approx(truth.axes["a"].vel_max, rel=0.005)
    assert dx["axes"]["z"]["held_speed"]["value"] == pytest.approx(truth.axes["z"].vel_max, rel=0.005)
    for axis in "zac":
        assert dx["profile"][f"axes.{axis}.acc_max"] == pytest.approx(truth.axes[axis].acc_max, rel=0.005)
    # X and Y only moved with other axes (a 428 mm/s^2 plateau is a projection of a coordinated move)
    assert "axes.x.acc_max" not in dx["profile"] and "axes.y.acc_max" not in dx["profile"]
    assert dx["axes"]["a"]["unit"] == "deg" and dx["axes"]["c"]["max"] == pytest.approx(405.0)
    assert sorted(p.name for p in out.iterdir()) == ["diagnose.json", "report.md"]


def test_nist_hurco_without_positions_gives_feed_plateaus_and_the_line_stream(tmp_path, capsys):
    rec = tmp_path / "hurco.mcap"
    assert main(["import", str(NIST / "Box-OP2-Hurco02-01of20.txt"), "-o", str(rec), "-q"]) == 0
    capsys.readouterr()
    assert main(["diagnose", str(rec)]) == 0
    text = capsys.readouterr().out
    assert "no positions: axis speeds, accelerations and the working envelope are unknown" in text
    assert "the data constrains: no limit" in text and "a program would add" in text
    dx = _json(["diagnose", str(rec)], capsys)
    assert dx["axes"] == {} and dx["profile"] == {}
    levels = [p["level_mm_min"] for p in dx["feed"]["plateaus"]]
    assert any(abs(v - 30 * 25.4) < 1.0 for v in levels)          # F30. (in/min) after the tool change: 762 mm/min
    assert dx["feed"]["standstill_s"] == pytest.approx(25.89, abs=0.01)
    assert dx["lines"]["first"] == 0 and dx["lines"]["last"] == 1209
    assert {x["line"] for x in dx["lines"]["longest"][:3]} >= {1182}    # the 6.9 s tool change stands out


def test_nist_mazak_speeds_from_its_axis_feed_rates_and_its_unit_warning(tmp_path, capsys):
    rec = tmp_path / "mazak.mcap"
    assert main(["import", str(NIST / "Mazak01-20161006-head4000.txt"), "-o", str(rec), "-q"]) == 0
    dx = _json(["diagnose", str(rec)], capsys)
    assert dx["period_s"] > 1.0 and dx["profile"] == {}
    for axis in "xyz":
        assert dx["axes"][axis]["speed_from"] == "velocity stream" and dx["axes"][axis]["peak_acc"] is None
    assert dx["axes"]["z"]["peak_speed"] == pytest.approx(243.81, abs=0.01)
    assert dx["axes"]["x"]["max"] == pytest.approx(945.965, abs=1e-3)
    assert any("5.084 x the speed of the axis velocities" in w for w in dx["warnings"])


def test_nothing_to_measure_and_an_existing_output_are_one_line_errors(tmp_path, capsys):
    from feedlog.recording import Recording
    import pandas as pd

    rec = Recording(streams={"spindle": pd.DataFrame({"t_ns": np.arange(5, dtype=np.int64) * 10**8,
                                                      "spindle_rpm": np.ones(5)})}, metadata={"controller": "x"})
    path = tmp_path / "spindle.mcap"
    write_recording(path, rec)
    capsys.readouterr()
    assert main(["diagnose", str(path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("feedlog diagnose: error: spindle.mcap: no positions, feed or line stream") and "\n" not in err
    out = tmp_path / "taken"
    out.mkdir()
    (out / "x").write_text("keep")
    assert main(["diagnose", str(_stripped(tmp_path, "circle_f3000_p001")), "-o", str(out)]) == 2
    assert "exists; pass --overwrite" in capsys.readouterr().err and (out / "x").read_text() == "keep"
