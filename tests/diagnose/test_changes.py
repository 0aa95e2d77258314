"""Changes during a session: the feed dial turned mid-program (simulated: the corner program's feed drops
to 70 % from one line on, as the dial would on its lines; a programmed arc's centripetal speed would not
follow an F word, so the arcs' pocket is not the place for it) must be found as a change (when, from what, to what), not
averaged into one override; a machine whose dial stayed put gives no change."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st

from feedlog.diagnose.changes import _best_split, _turn_time
from feedlog.diagnose.engine import DiagnoseConfig, diagnose
from feedlog.diagnose.summary import summary_lines, to_json

FAST = DiagnoseConfig(learned=False)
TURN_LINE = 15   # corners_f3000_p001: the dial goes to 70 % before this line's move (the ninth)
PROGRAMS = ("pocket_f3000_p001", "corners_f3000_p001")   # the last one is edited


def dial_turned(text: str) -> str:
    lines = text.splitlines()
    lines[TURN_LINE - 1] += " F2100"
    return "\n".join(lines) + "\n"


def test_a_dial_turned_mid_program_is_a_change_not_one_value(hidden, tmp_path):
    from feedlog.diagnose.write import write_outputs

    recs = hidden("turned", edit=dial_turned, programs=PROGRAMS)
    dx = diagnose(recs, "linuxcnc-xyz", config=FAST)
    (change,) = dx.changes
    assert change.parameter == "sim.feed_override.override" and change.shape == "step"
    assert change.recording == recs[-1].source.split(".")[0]
    assert change.before == pytest.approx(1.0, rel=0.05) and change.after == pytest.approx(0.7, rel=0.05)
    assert abs(change.line - TURN_LINE) <= 1                 # the block where the feed changed
    assert change.between_s[0] <= change.at_s <= change.between_s[1]
    assert change.error_change_pct < 0.25 * change.error_single_pct
    assert 0.75 < change.single_value < 0.95                 # what one value would have said
    assert "sim.feed_override.override" not in {f.parameter for f in dx.findings}
    assert dx.unexplained == []                              # what the change explains is not unexplained
    assert any(line.startswith("change during") for line in summary_lines(dx))
    assert to_json(dx)["changes"][0]["after"] == pytest.approx(0.7, rel=0.05)
    write_outputs(dx, tmp_path / "dx")
    assert "## Changes during a session" in (tmp_path / "dx" / "report.md").read_text()


SPARSE_PROGRAM, SPARSE_LINE = "corners_f1000_p01", 15   # 16.4 s: ten segments of at least 1 s at 5 Hz


def test_a_dial_turned_mid_program_in_a_5_hz_recording_is_a_change(hidden):
    """At 5 Hz a segment lasts at least five sampling periods (1 s), so a step needs a program of ten
    seconds or more (six segments); the 16 s corner program, dial to 70 % from line 15 on. Tolerances:
    both values within 5 % (as at 1 kHz: the step's values rest on whole segments, whose ends the sim
    mirrors at the recording's sample instants) and the time within one sampling period (0.2 s) of the
    turn: the turn's segment spans 2 s here, and where in it the dial turned is read from the two speeds."""
    from feedlog.profile import load_profile
    from feedlog.sim import simulate
    from feedlog.toolpath import parse_program
    from tests.diagnose.conftest import PROGRAMS as BUNDLED

    def turned(text: str) -> str:
        lines = text.splitlines()
        lines[SPARSE_LINE - 1] += " F700"
        return "\n".join(lines) + "\n"

    text = (BUNDLED / f"{SPARSE_PROGRAM}.ngc").read_text()
    blocks = simulate(parse_program(text), load_profile("linuxcnc-xyz")).blocks
    turn_s = float(blocks.loc[blocks["line"] == SPARSE_LINE, "t_start_ns"].iloc[0]) / 1e9   # 6.487 s
    recs = hidden("turned_5hz", edit=turned, programs=(SPARSE_PROGRAM,), rate_hz=5.0)
    dx = diagnose(recs, "linuxcnc-xyz", config=FAST)
    (change,) = dx.changes
    assert change.parameter == "sim.feed_override.override" and change.shape == "step"
    assert change.before == pytest.approx(1.0, rel=0.05) and change.after == pytest.approx(0.7, rel=0.05)
    assert change.at_s == pytest.approx(turn_s, abs=0.2)
    assert change.between_s[0] - 0.2 <= turn_s <= change.between_s[1] + 0.2   # segment ends are sample instants
    assert change.error_change_pct < 0.25 * change.error_single_pct
    assert dx.findings == [] and dx.unexplained == []


def test_an_unchanged_machine_gives_no_change(hidden):
    assert diagnose(hidden("control"), "linuxcnc-xyz", config=FAST).changes == []


def test_a_dial_that_stayed_put_is_one_value_not_a_change(hidden):
    dx = diagnose(hidden("override", values={"sim.feed_override.override": 0.8}), "linuxcnc-xyz", config=FAST)
    assert dx.changes == [] and [f.parameter for f in dx.findings] == ["sim.feed_override.override"]


def test_the_best_boundary_is_where_the_residuals_switch():
    # two grid values; segments 0-5 fit value 0, 7-12 value 1, segment 6 (the change happened in it) neither
    sq = np.array([[0.0] * 6 + [0.25] + [1.0] * 6, [1.0] * 6 + [0.25] + [0.0] * 6])
    k, loss, single = _best_split(sq, np.ones(13, bool), np.ones(13, bool))
    assert (k, loss, single) == (6, 0.0, 6.25)


def test_the_time_of_a_change_within_its_segment():
    # a 2 s segment: 1 s at the first value's speed, then the rest at 70 % of it (a 2 s move takes
    # 1 + 1 / 0.7 s at the second speed alone): the measured 2.4286 s puts the change at 1 s
    d1, d2 = 2.0, 2.0 / 0.7
    measured = 1.0 + 1.0 / 0.7
    assert _turn_time(d1 - measured, d2 - measured, measured) == pytest.approx(1.0)
    assert _turn_time(0.0, 0.5, 1.0) == 1.0 and _turn_time(-0.5, 0.0, 1.0) == 0.0


def test_the_dial_turn_option_says_what_it_needs():
    import argparse

    from feedlog.ingest.linuxcnc import dial_turn

    assert dial_turn("3.5:0.7") == (3.5, 0.7)
    for bad in ("3.5", "x:0.7", "3:0", "-1:0.5", "3:11"):
        with pytest.raises(argparse.ArgumentTypeError, match="S:SCALE|SCALE <= 10"):
            dial_turn(bad)


def test_the_rapid_dial_turn_option_stops_at_100_percent():
    import argparse

    from feedlog.ingest.linuxcnc import rapid_dial_turn

    assert rapid_dial_turn("5:0.5") == (5.0, 0.5) and rapid_dial_turn("0:1") == (0.0, 1.0)
    for bad in ("5:1.5", "5:0", "5", "-1:0.5"):
        with pytest.raises(argparse.ArgumentTypeError, match="S:SCALE|SCALE <= 1,"):
            rapid_dial_turn(bad)


@settings(max_examples=200, derandomize=True, deadline=None)
@given(st.one_of(st.text(max_size=20), st.tuples(st.floats(allow_nan=True), st.floats(allow_nan=True)).map(
    lambda p: f"{p[0]}:{p[1]}")))
@example("inf:0.5")
@example("3.5:0.7")
def test_any_dial_turn_text_parses_to_a_valid_turn_or_says_what_it_needs(text):
    import argparse

    from feedlog.ingest.linuxcnc import dial_turn

    from feedlog.ingest.linuxcnc import rapid_dial_turn

    for parse, top in ((dial_turn, 10), (rapid_dial_turn, 1)):
        try:
            at, scale = parse(text)
        except argparse.ArgumentTypeError as exc:
            assert "S:SCALE" in str(exc) or f"SCALE <= {top}," in str(exc)
        else:
            assert at >= 0 and 0 < scale <= top and np.isfinite(at)


def test_a_dial_that_moves_one_segment_either_side_is_not_a_change():
    """The bundled long_dense family (six LinuxCNC recordings, nothing changed): a rapid dial of 0.36
    'before' once fitted longdense_000's one approach rapid, 1.0 after, and halved its timing error."""
    import tomllib
    from pathlib import Path

    root = Path(__file__).resolve().parents[2] / "recordings"
    entries = tomllib.loads((root / "manifest.toml").read_text())["recording"]
    files = [root / e["file"] for e in entries if e["family"] == "long_dense"]
    assert len(files) == 6
    dx = diagnose(files, "linuxcnc-xyz", config=DiagnoseConfig(learned=False, families=("overrides",)))
    assert dx.changes == [] and dx.findings == []
