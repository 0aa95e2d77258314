"""Registry, parameters from outside, profile switches, and every extra effect measurably changing a
synthetic recording."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.errors import SimulationError
from feedlog.sim import REGISTRY, MeasurementModel, Mechanism, mechanism_class, measure, resolve_mechanisms, simulate

ZIGZAG = "G21 G90 G64 P0.02\nF2400\nG0 X0 Y0\n" + "\n".join(
    f"G1 X{2 * i + 2} Y{5 if i % 2 == 0 else 0}" for i in range(12)) + "\nG0 X0 Y0\n"


def test_every_registered_mechanism_is_a_documented_unit_named_dataclass(plain):
    for name in REGISTRY:
        cls = mechanism_class(name)
        assert issubclass(cls, Mechanism) and cls.name == name
        assert cls.__doc__ and len(cls.__module__.split(".")) == 3
        assert "Source" in __import__(cls.__module__, fromlist=["x"]).__doc__ or "source" in cls.__doc__.lower()
        mech = cls.from_params(plain, {})
        assert isinstance(mech.params(), dict)


def test_unknown_mechanism_and_parameter_are_rejected(plain):
    with pytest.raises(SimulationError, match="unknown sim mechanism 'warp'"):
        resolve_mechanisms(plain, ["warp"])
    with pytest.raises(SimulationError, match="unknown parameter"):
        resolve_mechanisms(plain, {"feed_override": {"speed": 2}})
    with pytest.raises(SimulationError, match=r"override must be from 0.001 to 10 \(0.1 % to 1000 %\), got 0"):
        resolve_mechanisms(plain, {"feed_override": {"override": 0}})
    with pytest.raises(SimulationError, match="parameter lookahead_blocks must be a whole number, got 'abc'"):
        resolve_mechanisms(plain, {"lookahead": {"lookahead_blocks": "abc"}})
    with pytest.raises(SimulationError, match=r"parameter stop_settle_s must be a time from 0 to 3600 s, got nan"):
        resolve_mechanisms(plain, {"lookahead": {"stop_settle_s": float("nan")}})
    with pytest.raises(SimulationError, match="exactly one interpolator"):
        resolve_mechanisms(plain, {"lookahead": False})
    with pytest.raises(SimulationError, match="exactly one interpolator"):
        resolve_mechanisms(plain, ["fir", "cam"])


def test_switching_on_an_interpolator_or_corner_law_replaces_the_default(plain):
    names = {m.name for m in resolve_mechanisms(plain, {"fir": True})}
    assert "fir" in names and "lookahead" not in names
    names = {m.name for m in resolve_mechanisms(plain, {"junction_deviation": {"default_deviation_mm": 0.02}})}
    assert "junction_deviation" in names and "blend_arc" not in names


def test_profile_sim_tables_switch_and_parameterise(plain):
    prof = plain.replace(sim={"feed_override": {"enabled": True, "override": 0.5}, "blend_arc": {"enabled": False}})
    names = [m.name for m in resolve_mechanisms(prof)]
    assert "feed_override" in names and "blend_arc" not in names
    fo = next(m for m in resolve_mechanisms(prof) if m.name == "feed_override")
    assert fo.override == 0.5
    # outside overrides win over the profile
    fo = next(m for m in resolve_mechanisms(prof, {"feed_override": {"override": 0.8}}) if m.name == "feed_override")
    assert fo.override == 0.8


def test_linuxcnc_profiles_switch_on_their_measured_mechanisms(plain):
    from feedlog.profile import load_profile

    lcnc = {m.name: m for m in resolve_mechanisms(load_profile("linuxcnc-xyz"))}
    assert "block_time" not in lcnc  # LinuxCNC's dense-run speed comes from its segment clamp
    assert lcnc["lookahead"].min_piece_cycles == pytest.approx(1.02)  # TP_MIN_SEGMENT_CYCLES
    assert "naive_cam" in lcnc
    assert lcnc["lookahead"].stop_settle_s == pytest.approx(0.0005)  # half a 1 ms servo period per stop
    five = {m.name: m for m in resolve_mechanisms(load_profile("linuxcnc-xyzac"))}
    assert five["trunnion"].limit_joints is False
    assert five["lookahead"].stop_settle_s == pytest.approx(0.0005)
    assert "block_time" not in {m.name for m in resolve_mechanisms(plain)}


def _recording(prog, prof, mechanisms):
    res = simulate(prog, prof, mechanisms=mechanisms)
    return res, measure(res, MeasurementModel(rate_hz=200, seed=1))


BASE = {"blend_arc": True}
EFFECTS = [
    ("feed_override", {"override": 0.5}),
    ("rapid_override", {"override": 0.25}),
    ("block_time", {"min_block_time_s": 0.3}),
    ("reversal_dwell", {"dwell_s": 0.05}),
    ("following_lag", {"lag_s": {"x": 0.03, "y": 0.03, "z": 0.03}}),
]


@pytest.mark.parametrize(("name", "params"), EFFECTS, ids=[e[0] for e in EFFECTS])
def test_each_effect_changes_a_synthetic_recording(plain, gcode, name, params):
    prog = gcode(ZIGZAG)
    base_res, base = _recording(prog, plain, BASE)
    on_res, on = _recording(prog, plain, {**BASE, name: params})
    if name == "following_lag":  # the feedback trails the command; the command is unchanged
        assert on_res.cycle_time_s == pytest.approx(base_res.cycle_time_s)
        assert "joints" not in base.streams
        joints = on.stream("joints")
        cmd, fb = joints[["j0_pos", "j1_pos"]].to_numpy(), joints[["j0_pos_fb", "j1_pos_fb"]].to_numpy()
        n = min(len(cmd), len(base.stream("axes")))
        assert np.array_equal(cmd[:n], base.stream("axes")[["x_mm", "y_mm"]].to_numpy()[:n])
        lag = np.abs(fb[:, 0] - cmd[:, 0]).max()
        v_max = np.abs(np.diff(cmd[:, 0])).max() * 200  # 200 Hz samples
        assert 0.1 < lag <= v_max * 0.03 * 1.05 + 1e-6  # at most v * T
        return
    a, b = base.stream("axes"), on.stream("axes")
    n = min(len(a), len(b))
    diff = np.abs(a[["x_mm", "y_mm"]].to_numpy()[:n] - b[["x_mm", "y_mm"]].to_numpy()[:n]).max()
    assert diff > 0.1, f"{name} left the recorded positions unchanged"
    assert on_res.cycle_time_s > base_res.cycle_time_s * 1.02


def test_feed_override_scales_a_long_cruise(plain, gcode):
    prog = gcode("G21 G90 G61\nG1 X200 F1200\n")
    assert simulate(prog, plain).cycle_time_s == pytest.approx(200 / 20 + 20 / 1000, abs=1e-6)
    half = simulate(prog, plain, mechanisms={"feed_override": {"override": 0.5}}).cycle_time_s
    assert half == pytest.approx(200 / 10 + 10 / 1000, abs=1e-6)


def test_reversal_dwell_counts_reversals(plain, gcode):
    res = simulate(gcode(ZIGZAG), plain, mechanisms={"reversal_dwell": {"dwell_s": 0.01}})
    stop_only = simulate(gcode(ZIGZAG), plain, mechanisms={"reversal_dwell": {"dwell_s": 0.0}})
    # y reverses at each of the 11 inner zig-zag corners, x once more at the final rapid back
    assert res.cycle_time_s == pytest.approx(stop_only.cycle_time_s + 12 * 0.01, abs=1e-6)


def test_block_time_floor_caps_short_blocks(plain, gcode):
    prog = gcode("G21 G90 G64 P0.01\nF3000\n" + "\n".join(f"G1 X{0.05 * i:.2f}" for i in range(1, 401)) + "\n")
    res = simulate(prog, plain, mechanisms={"block_time": {"min_block_time_s": 0.004}})
    assert res.cycle_time_s >= 400 * 0.004 - 1e-6
    assert res.series["feed_mm_min"].max() <= 0.05 / 0.004 * 60 * 1.001


def test_naive_cam_merges_collinear_lines_within_q(plain, gcode):
    # 0.1 mm steps on a straight line with +-0.004 mm wiggle: merged with Q0.01, kept with Q0.001
    pts = [(0.1 * i, 0.004 * (-1) ** i) for i in range(1, 301)]
    body = "\n".join(f"G1 X{x:.4f} Y{y:.4f}" for x, y in pts) + "\n"
    merged = simulate(gcode("G21 G90 G64 P0.01 Q0.01\nF3000\n" + body), plain, mechanisms={"naive_cam": True})
    kept_prog = gcode("G21 G90 G64 P0.01 Q0.001\nF3000\n" + body)
    kept = simulate(kept_prog, plain, mechanisms={"naive_cam": True})
    assert len(merged.blocks) <= 300 / 100 + 2  # chains of at most 101 points
    # kept: every line is a block of its own; a line a blend arc consumes runs in the arc's queue entry,
    # under the next line (as LinuxCNC's line stream shows it), so the first line, consumed by the first
    # arc and with no arc before it, has no time of its own
    assert len(kept.blocks) == 299
    first = int(kept_prog.blocks.query("kind == 'linear'")["line"].iloc[0])
    assert kept.blocks["line"].iloc[0] == first + 1
    assert merged.cycle_time_s < kept.cycle_time_s
    end = merged.series[["x_mm", "y_mm"]].iloc[-1].to_numpy()
    assert np.allclose(end, pts[-1], atol=1e-9)


def test_feed_override_scales_a_programmed_arcs_centripetal_speed_not_a_blend_arcs(plain, gcode):
    # LinuxCNC at 80 %: a G2/G3 arc runs at 0.8 x its centripetal speed; blend arcs keep theirs
    arc = gcode("G21 G90 G64 P0.01\nF3000\nG0 X0 Y0\nG1 X10\nG3 X10 Y2.5 R1.25\nG1 X0\n")
    full = simulate(arc, plain)
    slow = simulate(arc, plain, mechanisms={"feed_override": {"override": 0.8}})
    v_arc = slow.series.query("line == 5")["feed_mm_min"].max() / 60
    v_arc_full = full.series.query("line == 5")["feed_mm_min"].max() / 60
    assert v_arc_full < 50 * 0.8          # the centripetal limit, not the feed, sets the arc's speed
    assert v_arc == pytest.approx(0.8 * v_arc_full, rel=0.02)
    corner = gcode("G21 G90 G64 P0.05\nF3000\nG0 X0 Y0\nG1 X20\nG1 X20 Y20\nG1 X0 Y20\n")
    runs = [simulate(corner, plain, mechanisms={"feed_override": {"override": k}}) for k in (1.0, 0.8)]
    v_blend = [r.series.query("line == 5")["feed_mm_min"].min() / 60 for r in runs]
    assert all(r.notes["blend_arcs"] == 2 for r in runs)
    assert v_blend[0] < 0.8 * 50 and v_blend[1] == pytest.approx(v_blend[0], rel=1e-6)  # a cap, not scaled
    assert runs[1].series["feed_mm_min"].max() == pytest.approx(0.8 * 3000)


def test_feed_override_scales_a_blend_arc_that_runs_at_the_requested_feed(plain, gcode):
    # a gently curving polyline: its blend arcs are planned up to the programmed feed, and at 50 %
    # LinuxCNC runs them at half of it (an arc's reqvel times the dial), not at their planned speed
    pts = [(20 * np.sin(k * 0.01), 20 * (1 - np.cos(k * 0.01))) for k in range(1, 200)]
    prog = gcode("G21 G90 G64 P0.05\nF1200\nG0 X0 Y0\n" + "\n".join(f"G1 X{x:.4f} Y{y:.4f}" for x, y in pts) + "\n")
    full = simulate(prog, plain)
    half = simulate(prog, plain, mechanisms={"feed_override": {"override": 0.5}})
    assert full.notes["blend_arcs"] > 100 and half.notes["blend_arcs"] == full.notes["blend_arcs"]
    assert full.series["feed_mm_min"].max() == pytest.approx(1200, rel=1e-3)
    assert half.series["feed_mm_min"].max() <= 600 * 1.001
    assert half.cycle_time_s == pytest.approx(2 * full.cycle_time_s, rel=0.02)
