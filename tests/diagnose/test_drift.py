"""Changes during a session that are not one turn of the feed dial: a machine whose feed drifts as it warms
up (a gradual change, found as a drift from A at t0 to B at t1, not as a step nor one value), a step in
a 5 Hz recording, and the rapid dial turned mid-program.

The simulation runs one value per session, so the hidden change is made by scaling the dial's mechanism
per block while these recordings are simulated (`dial_by_line`): each block runs at the value the dial
had at its middle, the way a dial that moves slowly acts on a planner that plans a block at a time.
The drift is linear in the simulated time (the block times are found by iterating the simulation)."""

from __future__ import annotations

import copy
from contextlib import contextmanager

import numpy as np
import pytest

from feedlog.diagnose.drift import Interpolated, approach_share, drift_residuals, fit_drift, ramp_share
from feedlog.diagnose.engine import DiagnoseConfig, diagnose
from feedlog.diagnose.summary import summary_lines, to_json
from feedlog.profile import load_profile
from feedlog.sim import simulate
from feedlog.sim.feed_override import FeedOverride
from feedlog.sim.rapid_override import RapidOverride
from feedlog.toolpath import parse_program

from tests.diagnose.conftest import PROGRAMS, drilling, make_hidden

FAST = DiagnoseConfig(learned=False)
DRIFT = (2.0, 6.0, 1.0, 0.8)     # the feed dial drifts from 1.0 at 2 s to 0.8 at 6 s of motion time
PROGRAM = "corners_f3000_p001"   # 6.9 s with the drift, 20 line-to-line segments


@contextmanager
def dial_by_line(cls, scale_of_lines):
    """Simulations under this run the override mechanism `cls` at its value times scale_of_lines(lines),
    per block (the hidden change)."""
    plain = cls.limit

    def limit(self, ctx):
        dial = copy.copy(self)
        dial.override = self.override * scale_of_lines(ctx.blocks.line)
        plain(dial, ctx)

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(cls, "limit", limit)
        yield


def linear(t0: float, t1: float, a: float, b: float):
    """The dial at time t (s): a until t0, linear to b at t1, b after it."""
    return lambda t: a + (b - a) * np.clip((t - t0) / (t1 - t0), 0.0, 1.0)


def drifted(name: str, program: str, drift=DRIFT, *, dial=None, **kwargs):
    """`program` recorded on a machine whose feed dial drifts linearly in time by `drift` (t0, t1, a, b),
    or follows `dial(t)` (t: seconds of motion) when given."""
    dial = dial or linear(*drift)
    text = (PROGRAMS / f"{program}.ngc").read_text()
    parsed, profile = parse_program(text, name=program), load_profile("linuxcnc-xyz")
    mid: dict[int, float] = {}

    def scale(lines):
        return dial(np.array([mid.get(int(line), 0.0) for line in lines]))

    on = {"feed_override": {"override": 1.0}}
    with dial_by_line(FeedOverride, scale):
        for _ in range(4):   # block times under the drift: a fixed point (moves < 1 ms after the fourth)
            blocks = simulate(parsed, profile, mechanisms=on).blocks
            mid = {int(r.line): (r.t_start_ns + r.t_end_ns) / 2e9 for r in blocks.itertuples()}
        return make_hidden(name, mechanisms=on, programs=(program,), **kwargs)


_CACHE: dict = {}


def cached(name, make):
    if name not in _CACHE:
        _CACHE[name] = make()
    return _CACHE[name]


def one_change(name, make, shape):
    """The diagnosis of the recordings `make` gives (cached as `name`) and its one change, a change of
    the feed dial of `shape`."""
    dx = diagnose(cached(name, make), "linuxcnc-xyz", config=FAST)
    (change,) = dx.changes
    assert change.parameter == "sim.feed_override.override" and change.shape == shape
    return dx, change


def test_a_machine_that_warms_up_is_a_drift_not_a_step_nor_one_value(tmp_path):
    from feedlog.diagnose.write import write_outputs

    dx, change = one_change("drift", lambda: drifted("drift", PROGRAM), "drift")
    t0, t1, a, b = DRIFT
    assert change.before == pytest.approx(a, rel=0.05) and change.after == pytest.approx(b, rel=0.05)
    assert change.at_s == pytest.approx(t0, abs=0.5) and change.until_s == pytest.approx(t1, abs=0.5)
    assert change.rate_per_min == pytest.approx(60 * (b - a) / (t1 - t0), rel=0.15)
    assert change.error_change_pct < 0.1 * change.error_single_pct
    assert b < change.single_value < a                               # what one value would have said
    assert "sim.feed_override.override" not in {f.parameter for f in dx.findings}
    assert dx.unexplained == []
    assert any(line.startswith("drift during") and "per minute" in line for line in summary_lines(dx))
    assert to_json(dx)["changes"][0]["shape"] == "drift"
    write_outputs(dx, tmp_path / "dx")
    assert "| drift 2." in (tmp_path / "dx" / "report.md").read_text()


def test_a_drift_too_short_to_span_segments_is_a_step():
    """The same machine whose dial moved from 1.0 to 0.8 within 0.05 s (a turn): a step, not a drift."""
    recs = cached("quick", lambda: drifted("quick", PROGRAM, drift=(3.0, 3.05, 1.0, 0.8)))
    (change,) = diagnose(recs, "linuxcnc-xyz", config=FAST).changes
    assert change.shape == "step" and change.until_s is None and change.rate_per_min is None
    assert change.before == pytest.approx(1.0, rel=0.05) and change.after == pytest.approx(0.8, rel=0.05)
    assert change.at_s == pytest.approx(3.0, abs=0.3)


RAPID_TURN_LINE = 19   # the rapid dial goes to 50 % before this line (hole 5's XY rapid of 8)


def test_the_rapid_dial_turned_mid_program_is_a_change_of_the_rapid_dial():
    text = drilling(8)

    def scale(lines):
        return np.where(np.asarray(lines) >= RAPID_TURN_LINE, 0.5, 1.0)

    def record():
        with dial_by_line(RapidOverride, scale):
            return make_hidden("rapid", mechanisms={"rapid_override": {"override": 1.0}}, programs=("drill",),
                               texts={"drill": text})
    recs = cached("rapid", record)
    dx = diagnose(recs, "linuxcnc-xyz", config=FAST)
    (change,) = dx.changes
    assert change.parameter == "sim.rapid_override.override" and change.shape == "step"
    assert change.before == pytest.approx(1.0, rel=0.05) and change.after == pytest.approx(0.5, rel=0.05)
    assert abs(change.line - RAPID_TURN_LINE) <= 1
    assert {f.parameter for f in dx.findings} & {"sim.rapid_override.override", "sim.feed_override.override"} == set()


def hidden_in_durations(n: int, seconds: float, share, a: float, b: float, dense: tuple[float, float]):
    """n segments of `seconds` each whose duration goes as 1/value, the value going from a to b by the
    progress `share` (per segment): (start, end, the interpolated model of their residuals)."""
    start = np.arange(n) * seconds
    end = start + seconds
    measured = seconds / (a + (b - a) * share(start, end))
    model = Interpolated(lambda v: seconds / v - measured, "log", 0.05, 2.0)
    model.add(np.geomspace(0.05, 2.0, 17))
    model.densify(*dense)
    return start, end, model


def test_a_drift_is_fitted_from_residuals_that_hide_it():
    """The drift fit alone, on residuals made from a known drift: 20 segments of 0.5 s whose duration
    goes as 1/value, the value 1.0 until 3 s, then linear to 0.7 at 7 s."""
    start, end, model = hidden_in_durations(
        20, 0.5, lambda s, e: ramp_share(s, e, np.array([3.0]), np.array([7.0]))[0], 1.0, 0.7, (0.95, 0.75))
    drift = fit_drift(model, start, end, np.ones(20, bool), (0.95, 0.75))
    assert drift.before == pytest.approx(1.0, rel=0.01) and drift.after == pytest.approx(0.7, rel=0.01)
    assert drift.t0_s == pytest.approx(3.0, abs=0.1) and drift.t1_s == pytest.approx(7.0, abs=0.1)
    assert np.abs(drift_residuals(model, drift, start, end)).max() < 1e-3


def approach(t0: float, tau: float, a: float, b: float):
    """The dial at time t (s): a until t0, then exponentially towards b with time constant tau."""
    return lambda t: b + (a - b) * np.exp(-np.maximum(np.asarray(t, float) - t0, 0.0) / tau)


TO_END = (2.5, 7.5, 1.0, 0.75)   # still falling when motion ends (6.8 s): never levels off in the recording


def test_a_drift_that_runs_to_the_end_of_the_recording_is_a_drift_that_did_not_level_off():
    """The feed dial falls from 1.0 at 2.5 s towards 0.75 at 7.5 s, but motion ends first: found as a
    drift still under way at the end (its end value the dial's at the end of motion), not as a step.
    Values within 5 %; the start within 0.5 s (under one long segment of this program), the end
    within 0.25 s of the end of motion (inside its last, short segment)."""
    dx, change = one_change("to_end", lambda: drifted("to_end", PROGRAM, drift=TO_END, seed=7), "drift")
    t0, t1, a, b = TO_END
    assert change.open_end and not change.open_start
    assert change.until_s == pytest.approx(change.motion_end_s, abs=0.25)      # it runs to the end
    true_end = linear(*TO_END)(change.until_s)
    assert change.before == pytest.approx(a, rel=0.05) and change.after == pytest.approx(true_end, rel=0.05)
    assert change.at_s == pytest.approx(t0, abs=0.5)
    assert change.rate_per_min == pytest.approx(60 * (b - a) / (t1 - t0), rel=0.15)
    assert change.error_change_pct < 0.1 * change.error_single_pct
    assert "did not level off within the recording" in change.text()
    assert to_json(dx)["changes"][0]["open_end"] is True


WARM = (1.0, 2.0, 1.0, 0.8)   # the feed dial from 1.0 at 1 s towards 0.8, time constant 2 s (95 % at 7 s)


def test_a_machine_that_warms_up_exponentially_is_an_approach_not_a_line():
    """Found as an approach, both values within 5 %. Times: the start within 0.5 s (a long segment of
    this program lasts 0.55-0.65 s and the start trades against the start value on the few segments
    before it), the time constant within 20 % (it rests on the five long segments of the first
    3 tau; the dial is applied per block at the block's middle, the fit averages over segments)."""
    dx, change = one_change("warm", lambda: drifted("warm", PROGRAM, dial=approach(*WARM), seed=11), "approach")
    t0, tau, a, b = WARM
    assert change.before == pytest.approx(a, rel=0.05) and change.after == pytest.approx(b, rel=0.05)
    assert change.at_s == pytest.approx(t0, abs=0.5) and change.tau_s == pytest.approx(tau, rel=0.2)
    assert change.until_s == pytest.approx(change.at_s + 3.0 * change.tau_s, rel=0.01)
    assert change.error_change_pct < 0.1 * change.error_single_pct
    assert "sim.feed_override.override" not in {f.parameter for f in dx.findings}
    text = change.text()
    assert f"approaches {change.after:.4g} from {change.before:.4g}" in text and "time constant" in text
    assert "reaches 95 % at" in text
    assert to_json(dx)["changes"][0]["tau_s"] == pytest.approx(change.tau_s)


def test_an_unchanged_machine_names_no_change():
    recs = cached("still", lambda: drifted("still", PROGRAM, dial=lambda t: np.ones_like(np.asarray(t, float)),
                                           seed=5))
    dx = diagnose(recs, "linuxcnc-xyz", config=FAST)
    assert dx.changes == [] and dx.findings == []


def test_an_exponential_approach_is_fitted_from_residuals_that_hide_it():
    """The fit alone: 30 segments of 0.4 s whose duration goes as 1/value, the value 1.0 until 2 s,
    then towards 0.75 with a time constant of 3 s. The approach is found; the best line leaves 20 times
    more."""
    start, end, model = hidden_in_durations(
        30, 0.4, lambda s, e: approach_share(s, e, np.array([2.0]), np.array([3.0]))[0], 1.0, 0.75, (0.95, 0.7))
    use = np.ones(30, bool)
    found = fit_drift(model, start, end, use, (0.95, 0.8), kind="approach")
    assert found.shape == "approach"
    assert found.before == pytest.approx(1.0, rel=0.01) and found.after == pytest.approx(0.75, rel=0.01)
    assert found.t0_s == pytest.approx(2.0, abs=0.1) and found.tau_s == pytest.approx(3.0, rel=0.05)
    line = fit_drift(model, start, end, use, (0.95, 0.8))
    assert line.loss > 20 * found.loss


def test_a_line_held_to_the_recordings_end_is_fitted_from_residuals_that_hide_it():
    """The value 1.0 until 3 s, then falling at the rate that would reach 0.7 at 12 s, in a recording
    that ends at 8 s: the line with its end held at the recording's end finds the start and the value
    at the end (0.8667)."""
    start, end, model = hidden_in_durations(
        20, 0.4, lambda s, e: ramp_share(s, e, np.array([3.0]), np.array([12.0]))[0], 1.0, 0.7, (0.95, 0.85))
    drift = fit_drift(model, start, end, np.ones(20, bool), (0.95, 0.85), fixed="t1")
    assert drift.t1_s == pytest.approx(8.0) and drift.t0_s == pytest.approx(3.0, abs=0.1)
    assert drift.before == pytest.approx(1.0, rel=0.01) and drift.after == pytest.approx(1.0 - 0.3 * 5 / 9, rel=0.01)
