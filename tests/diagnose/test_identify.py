"""Hide an effect in simulated recordings and require `feedlog diagnose` to find it (or to refuse to
name one): one changed parameter, two at once, a structural effect no hypothesis covers, a control,
and the same at 5 Hz. Recordings carry measurement noise and quantisation."""

from __future__ import annotations

import pytest

from feedlog.diagnose.engine import DiagnoseConfig, diagnose
from tests.diagnose.conftest import slower_after_arcs

FAST = DiagnoseConfig(learned=False)

SINGLE = [
    ("xacc", {"axes.x.acc_max": 300.0}, "axes.x.acc_max", 300.0),
    ("override", {"sim.feed_override.override": 0.8}, "sim.feed_override.override", 0.8),
    ("pathvel", {"interpolator.path_vel_max_mm_s": 30.0}, "interpolator.path_vel_max_mm_s", 30.0),
    ("dwell", {"sim.reversal_dwell.dwell_s": 0.02}, "sim.reversal_dwell.dwell_s", 0.02),
]


def _cycle_error_removed(dx) -> float:
    cyc = dx.levels["cycle"]
    return 1.0 - abs(cyc["error_after_pct"]) / abs(cyc["error_before_pct"])


@pytest.mark.parametrize(("name", "values", "key", "truth"), SINGLE, ids=[s[0] for s in SINGLE])
def test_one_hidden_change_is_named_with_its_value(hidden, name, values, key, truth):
    dx = diagnose(hidden(name, values=values), "linuxcnc-xyz", config=FAST)
    assert [f.parameter for f in dx.findings] == [key]
    finding = dx.findings[0]
    assert finding.fitted_value == pytest.approx(truth, rel=0.15)
    assert finding.interval[0] <= finding.fitted_value <= finding.interval[1]
    assert _cycle_error_removed(dx) >= 0.8
    assert all(r["error_after_pct"] is not None and abs(r["error_after_pct"]) < 1.0 for r in dx.held_out["recordings"])
    assert dx.unexplained == []


def test_a_feedback_lag_is_found_on_the_feedback_and_leaves_the_timing_alone(hidden):
    dx = diagnose(hidden("lag", values={"sim.following_lag.lag_s.x": 0.02}), "linuxcnc-xyz", config=FAST)
    assert [f.parameter for f in dx.findings] == ["sim.following_lag.lag_s.x"]
    assert dx.findings[0].fitted_value == pytest.approx(0.02, rel=0.15)
    fb = dx.levels["feedback"]
    assert fb["rms_after_mm"] <= 0.3 * fb["rms_before_mm"]
    assert abs(dx.levels["cycle"]["error_before_pct"]) < 0.2  # nothing for the timing to find


def test_two_simultaneous_changes_are_both_found(hidden):
    dx = diagnose(hidden("two", values={"axes.y.acc_max": 400.0, "sim.feed_override.override": 0.85}),
                  "linuxcnc-xyz", config=FAST)
    found = {f.parameter: f.fitted_value for f in dx.findings}
    assert set(found) == {"axes.y.acc_max", "sim.feed_override.override"}
    assert found["axes.y.acc_max"] == pytest.approx(400.0, rel=0.15)
    assert found["sim.feed_override.override"] == pytest.approx(0.85, rel=0.15)
    assert _cycle_error_removed(dx) >= 0.8


def test_a_structural_effect_is_unexplained_not_a_wrong_parameter(hidden):
    recs = hidden("arcs", edit=slower_after_arcs)
    dx = diagnose(recs, "linuxcnc-xyz", config=FAST)
    assert dx.findings == []
    assert len(dx.unexplained) == 1
    where = dx.unexplained[0]["where"]
    assert "after an arc" in where or recs[-1].source.split(".")[0] in where


def test_the_unchanged_machine_gives_no_finding(hidden):
    dx = diagnose(hidden("control"), "linuxcnc-xyz", config=FAST)
    assert dx.findings == [] and dx.unexplained == []
    assert dx.extended.to_dict()["axes"] == dx.profile.to_dict()["axes"]
    assert dx.diff == []


@pytest.mark.parametrize(("name", "values", "key", "truth"), SINGLE, ids=[s[0] for s in SINGLE])
def test_at_5_hz_a_hidden_change_is_still_named(hidden, name, values, key, truth):
    dx = diagnose(hidden(f"{name}_5hz", values=values, rate_hz=5.0), "linuxcnc-xyz", config=FAST)
    assert [f.parameter for f in dx.findings] == [key]
    # compared as the samples show it, the fit is as good as at 1 kHz (300.01, 0.7999, 29.999, 0.020)
    assert dx.findings[0].fitted_value == pytest.approx(truth, rel=0.03)
    assert _cycle_error_removed(dx) >= 0.95


def test_the_unchanged_machine_at_5_hz_gives_no_finding(hidden):
    dx = diagnose(hidden("control_5hz", rate_hz=5.0), "linuxcnc-xyz", config=FAST)
    assert dx.findings == [] and dx.unexplained == []


def test_a_recording_without_a_level_leaves_that_level_to_the_others(hidden):
    recs = hidden("xacc", values={"axes.x.acc_max": 300.0})
    stripped = recs[0].__class__(streams={k: v for k, v in recs[0].streams.items() if k not in ("line", "joints")},
                                 metadata=dict(recs[0].metadata), attachments=dict(recs[0].attachments),
                                 source="no_line_stream.mcap")
    dx = diagnose([stripped, recs[1]], "linuxcnc-xyz", config=FAST)
    assert [f.parameter for f in dx.findings] == ["axes.x.acc_max"]
    assert {dx.cases[u.case].name for u in dx.scorers["line"].units} == {recs[1].source.split(".")[0]}


def test_an_unexplained_residual_gets_a_learned_correction_judged_on_held_out_recordings(hidden, tmp_path):
    from feedlog.diagnose.write import write_outputs

    recs = hidden("arcs", edit=slower_after_arcs)
    dx = diagnose(recs, "linuxcnc-xyz", config=DiagnoseConfig(learned=True))
    (entry,) = dx.unexplained
    lc = entry["learned_correction"]
    assert lc["model"] == "hybrid" and [r["name"] for r in lc["held_out"]] == [c.name for c in dx.cases]
    assert all(abs(r["error_before_pct"]) >= 0 and abs(r["error_after_pct"]) < 1e3 for r in lc["held_out"])
    files = write_outputs(dx, tmp_path / "dx")
    assert ("learned.pt" in files) == (lc["gain_pct"] > 0)   # kept only when it generalises
    assert "Learned correction" in (tmp_path / "dx" / "report.md").read_text()


def test_a_five_axis_fir_machine_has_its_filter_time_found(hidden):
    recs = hidden("fir", values={"interpolator.fir_t1_s": 0.1}, programs=("mix5ax_011", "mix5ax_015"), base="chien-ac")
    dx = diagnose(recs, "chien-ac", config=FAST)
    assert [f.parameter for f in dx.findings] == ["interpolator.fir_t1_s"]
    assert dx.findings[0].fitted_value == pytest.approx(0.1, rel=0.15)
    assert _cycle_error_removed(dx) >= 0.8
    control = diagnose(hidden("fir_control", programs=("mix5ax_011", "mix5ax_015"), base="chien-ac"), "chien-ac",
                       config=FAST)
    assert control.findings == [] and control.unexplained == []


def test_a_small_change_between_search_grid_points_is_found(hidden):
    """A 7 % feed override lies between the screen's grid points (0.78 and 1.0): the screen refines
    around its best point, and the data's own cruise ratio joins the grid."""
    dx = diagnose(hidden("override93", values={"sim.feed_override.override": 0.93}), "linuxcnc-xyz", config=FAST)
    assert [f.parameter for f in dx.findings] == ["sim.feed_override.override"]
    assert dx.findings[0].fitted_value == pytest.approx(0.93, rel=0.02)
    assert _cycle_error_removed(dx) >= 0.8


def test_a_limit_that_binds_on_few_moves_is_found(hidden):
    """A Y velocity limit of 37 mm/s on programs at 50 mm/s that move along Y little: it binds in a band
    narrower than the grid's step; the Y speed ceiling the data shows is where to look."""
    recs = hidden("yvel37", values={"axes.y.vel_max": 37.0}, programs=("longdense_000", "pocket_f3000_p001"))
    dx = diagnose(recs, "linuxcnc-xyz", config=FAST)
    assert [f.parameter for f in dx.findings] == ["axes.y.vel_max"]
    assert dx.findings[0].fitted_value == pytest.approx(37.0, rel=0.05)


TWO_CAUSES = [
    # override 0.78 with a slow Z: before the Z limit is in the model a path speed cap (which also slows
    # the short Z rapids) explains more than the override; with it, the override is as good or better,
    # and of equals the operator's dial is named first (each step's choice made again)
    ("override_zacc", {"sim.feed_override.override": 0.78, "axes.z.acc_max": 306.0}, ("mix_010", "pocket_f2000_p01")),
    # a path speed cap of 34 with Z accelerating at 609: the cap alone, fitted on the program at F1000
    # (which meets it only in rapids that the Z limit slows), comes out far too low for the program at
    # F2500 and fails held out; put in provisionally, the Z limit found given it, both then held out
    # given each other (one step of look-ahead; LinuxCNC machine m02 of bench_diagnose_blind seed 2)
    ("pathvel_zacc", {"interpolator.path_vel_max_mm_s": 34.0, "axes.z.acc_max": 609.0}, ("longdense_005", "mix_035")),
]


@pytest.mark.parametrize("name, values, programs", TWO_CAUSES, ids=[t[0] for t in TWO_CAUSES])
def test_two_causes_that_hide_each_other_are_found_together(hidden, name, values, programs):
    dx = diagnose(hidden(name, values=values, programs=programs), "linuxcnc-xyz", config=FAST)
    found = {f.parameter: f.fitted_value for f in dx.findings}
    assert set(found) == set(values)
    for key, true in values.items():
        assert found[key] == pytest.approx(true, rel=0.05 if "acc_max" not in key else 0.15), key
    assert _cycle_error_removed(dx) >= 0.8


def test_a_faithful_five_axis_recording_with_a_work_offset_gives_no_finding():
    """A bundled LinuxCNC recording of a five-axis program with a G54: the simulated recording the line
    level compares with is not in the program's frame; align must not guess an offset for it (a few um
    off, it moved every modelled block end and named a 11 ms 'logger latency')."""
    from pathlib import Path

    rec = Path(__file__).resolve().parents[2] / "recordings" / "mix5ax_004.mcap"
    dx = diagnose([rec], "linuxcnc-xyzac", config=FAST)
    assert dx.findings == [] and dx.unexplained == []


FOUR = {"axes.x.acc_max": 400.0, "axes.y.vel_max": 30.0, "axes.z.acc_max": 300.0, "sim.feed_override.override": 0.85}


@pytest.mark.slow
def test_three_changed_limits_and_an_override_are_all_named_within_5_percent(hidden):
    """Four simultaneous changes: greedy steps take the feed override too low (0.80) and a rapid override
    of 0.15 for the two acceleration limits; the joint refit and one cause split into two (fitted with
    all the others, each of the two then held out given the rest) name all four."""
    recs = hidden("four", values=FOUR, programs=("corners_f3000_p001", "pocket_f3000_p001", "mix_010"))
    dx = diagnose(recs, "linuxcnc-xyz", config=FAST)
    found = {f.parameter: f.fitted_value for f in dx.findings}
    assert set(found) == set(FOUR)
    for key, true in FOUR.items():
        assert found[key] == pytest.approx(true, rel=0.05), key
    assert abs(dx.levels["cycle"]["error_after_pct"]) < 0.5


def with_tool_changes(text: str) -> str:
    """Two tool changes between moves: after the program's 4th and 10th feed moves."""
    lines = text.splitlines(keepends=True)
    feeds = [i for i, line in enumerate(lines) if line.startswith(("G1 ", "G2 ", "G3 "))]
    for i, tool in ((feeds[9], 1), (feeds[3], 2)):
        lines.insert(i + 1, f"T{tool} M6\n")
    return "".join(lines)


def test_a_tool_change_time_is_named_from_the_standstills_at_m6(hidden):
    dx = diagnose(hidden("toolchange", values={"sim.tool_change.time_s": 2.5}, program_edit=with_tool_changes),
                  "linuxcnc-xyz", config=FAST)
    assert [f.parameter for f in dx.findings] == ["sim.tool_change.time_s"]
    assert dx.findings[0].fitted_value == pytest.approx(2.5, rel=0.05)
    assert _cycle_error_removed(dx) >= 0.9


def test_tool_changes_on_an_unchanged_machine_give_no_finding(hidden):
    dx = diagnose(hidden("toolchange_none", program_edit=with_tool_changes), "linuxcnc-xyz", config=FAST)
    assert dx.findings == []
