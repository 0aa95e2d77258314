"""Property tests over random polylines: limits, end point, cycle time bounds (hypothesis)."""

from __future__ import annotations

import numpy as np
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pandas as pd

from feedlog.profile import MachineProfile
from feedlog.sim import simulate
from feedlog.toolpath import schema

PROFILE = MachineProfile.from_dict({
    "name": "prop", "controller": "test rig", "rapid_mm_min": 3000.0,
    "axes": {"x": {"vel_max": 50.0, "acc_max": 1000.0}, "y": {"vel_max": 40.0, "acc_max": 800.0},
             "z": {"vel_max": 20.0, "acc_max": 500.0}},
})

def block_table(pts: np.ndarray, *, feed_mm_min: float, tol_mm: float) -> pd.DataFrame:
    """A block table (toolpath/schema.py) of G1 moves through pts, built by hand: no parser needed."""
    n = len(pts)
    start = np.vstack([[0.0, 0.0, 0.0], pts[:-1]])
    data = {"file": "prop.ngc", "line": np.arange(3, n + 3, dtype=np.int32), "block": np.arange(n, dtype=np.int32),
            "kind": pd.Categorical([schema.LINEAR] * n, categories=schema.KINDS)}
    for i, axis in enumerate(schema.AXES):
        unit = schema.AXIS_UNITS[axis]
        data[f"{axis}0_{unit}"] = start[:, i] if i < 3 else np.zeros(n)
        data[f"{axis}_{unit}"] = pts[:, i] if i < 3 else np.zeros(n)
    data.update({"plane": np.full(n, 17, np.int8), "cx_mm": np.nan, "cy_mm": np.nan, "cz_mm": np.nan,
                 "turns": np.zeros(n, np.int16), "feed_mm_min": float(feed_mm_min), "inverse_time": False,
                 "dwell_s": 0.0, "path_mode": pd.Categorical([schema.CONTINUOUS] * n, categories=schema.PATH_MODES),
                 "tol_mm": float(tol_mm), "merge_tol_mm": float(tol_mm), "ori_i": np.nan, "ori_j": np.nan,
                 "ori_k": np.nan, "units": "mm", "spindle_rpm": 0.0, "mcodes": "", "comment": ""})
    table = pd.DataFrame(data)
    assert set(schema.BLOCK_COLUMNS) <= set(table.columns)
    return table


polylines = st.lists(st.tuples(st.floats(-5, 5), st.floats(-5, 5), st.floats(-1, 1)), min_size=2, max_size=25)


@settings(max_examples=30, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(steps=polylines, tol=st.sampled_from([0.001, 0.01, 0.1, 0.5]), feed=st.sampled_from([300, 1500, 6000]),
       law=st.sampled_from(["blend_arc", "junction_deviation"]))
def test_random_polylines_respect_limits_and_end_where_programmed(steps, tol, feed, law):
    pts = np.cumsum(np.array(steps), axis=0)
    prog = block_table(pts, feed_mm_min=feed, tol_mm=tol)
    res = simulate(prog, PROFILE, mechanisms=["lookahead", law])
    s = res.series
    pos = s[["x_mm", "y_mm", "z_mm"]].to_numpy()
    assert np.allclose(pos[-1], pts[-1], atol=1e-6)
    vel = np.abs(np.diff(pos, axis=0)) / 0.001
    assert (vel <= np.array([50.0, 40.0, 20.0]) * 1.001 + 1e-9).all()
    if law == "blend_arc":
        # acceleration from sampled positions: exact on lines, O(v^2 dt / R) extra on blend arcs;
        # junction deviation (grbl) turns corners with a velocity jump by design, so it is not checked
        acc = np.abs(np.diff(vel, axis=0)) / 0.001
        assert (acc <= np.array([1000.0, 800.0, 500.0]) * 1.10 + 1e-6).all()
    # no faster than every block at its feed (or axis limit) without acceleration
    assert res.cycle_time_s >= res.cam_time_s * (1 - 1e-9) or res.cycle_time_s >= _shortcut_bound(pts)
    assert len(res.blocks) <= len(prog)


def _shortcut_bound(pts: np.ndarray) -> float:
    """Blend arcs shorten the path, so the time bound is the straight end-to-end distance at the
    fastest axis speed."""
    return float(np.linalg.norm(pts[-1])) / 50.0


@settings(max_examples=20, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(steps=polylines, tol=st.sampled_from([0.001, 0.01, 0.1]), feed=st.sampled_from([300, 1500, 6000]))
def test_fir_keeps_axis_speeds_and_ends_where_programmed(steps, tol, feed):
    pts = np.cumsum(np.array(steps), axis=0)
    res = simulate(block_table(pts, feed_mm_min=feed, tol_mm=tol), PROFILE,
                   mechanisms={"fir": {"t1_s": 0.05, "t2_s": 0.01}})
    pos = res.series[["x_mm", "y_mm", "z_mm"]].to_numpy()
    assert np.allclose(pos[-1], pts[-1], atol=1e-6)
    vel = np.abs(np.diff(pos, axis=0)) / 0.001
    assert (vel <= np.array([50.0, 40.0, 20.0]) * 1.001 + 1e-9).all()  # averages of bounded pulses
