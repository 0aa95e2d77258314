"""Inputs taken from the part program: G64 Q, rotary moves and the axes' speed-limited block time."""

from __future__ import annotations

import numpy as np
import pytest

from feedlog.profile import load_profile
from feedlog.toolpath import block_features, parse_program
from feedlog.train.dataset import ProgramTable
from feedlog.train.features import build_inputs, limited_time, with_program_columns
from feedlog.train.model_mlp import PerAxisMLP
from feedlog.train.registry import make_config

PROGRAM = """G21 G90 G94
G64 P0.01 {q}
F600
G0 X0 Y0 Z0 A0 C0
G1 X1
G1 X2 C30
G1 X-1 A-6
M2
"""


def _table(q: str = "", profile: str | None = "linuxcnc-xyzac"):
    prof = load_profile(profile) if profile else None
    program = parse_program(PROGRAM.format(q=q))
    return with_program_columns(block_features(program, prof), program, prof)


def test_merge_tolerance_follows_q_and_defaults_to_p():
    assert build_inputs(_table("Q0"), ["merge_tol_eff_mm"])[:, 0].tolist() == [0.0] * 4
    assert build_inputs(_table(), ["merge_tol_eff_mm"])[:, 0] == pytest.approx([0.01] * 4)
    # a table without the column (hand-built) takes LinuxCNC's default Q = P
    bare = _table("Q0").drop(columns=["merge_tol_mm"])
    assert build_inputs(bare, ["merge_tol_eff_mm"])[:, 0] == pytest.approx([0.01] * 4)


def test_rotary_move_and_axis_limited_time():
    t = _table()
    assert t["rot_dist_deg"].tolist() == [0.0, 0.0, 30.0, 6.0]
    lim = limited_time(t)
    nominal = t["nominal_time_s"].to_numpy()
    # C turns 30 deg at 60 deg/s: 0.5 s, far more than 1 mm at 600 mm/min (0.1 s)
    assert lim[2] == pytest.approx(0.5) and nominal[2] == pytest.approx(0.1)
    # X 3 mm at 600 mm/min (0.3 s) outlasts A 6 deg at 60 deg/s (0.1 s)
    assert lim[3] == pytest.approx(nominal[3])
    ratio = build_inputs(t, ["limit_ratio"])[:, 0]
    assert ratio[2] == pytest.approx(5.0) and ratio[1] == pytest.approx(1.0)
    # without a profile there is no axis time: the limited time is L / F
    assert np.allclose(limited_time(_table(profile=None)), _table(profile=None)["nominal_time_s"])


def test_mlp_mirrors_blocks_to_positive_travel():
    t = _table()
    model = PerAxisMLP(make_config("mlp", base="cam"))
    x, sign = model._axis_matrix(ProgramTable("t", t), "x")
    names = model.axis_inputs("x")
    v = names.index("vx_nom_mm_min")
    assert sign.tolist() == [1.0, 1.0, 1.0, -1.0]
    assert np.all(x[:, v] >= 0) and x[3, v] == pytest.approx(-t["vx_nom_mm_min"].iloc[3])
