"""Differential tests against LinuxCNC's own interpreter (`rs274`, the standalone RS274/NGC interpreter
of linuxcnc-uspace): it prints the canonical motion calls (STRAIGHT_TRAVERSE, STRAIGHT_FEED, ARC_FEED)
for a program; our block table must hold the same end points, arc centres, directions and turns.
Skipped where LinuxCNC is not installed."""

from __future__ import annotations

import math
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.toolpath import load_program, parse_program

RS274 = shutil.which("rs274")
pytestmark = pytest.mark.skipif(RS274 is None, reason="LinuxCNC's rs274 interpreter is not installed "
                                                      "(apt-get install linuxcnc-uspace)")
ROOT = Path(__file__).resolve().parents[2]
SHARED = ROOT / "recordings" / "programs"  # the shared LinuxCNC programs, kept in the repo
SHARED_PROGRAMS = ("5ax_g61.ngc", "5ax_p001.ngc", "dense002q0.ngc", "test_g61.ngc", "test_p001.ngc", "test_p01.ngc")
_CALL = re.compile(r"(STRAIGHT_TRAVERSE|STRAIGHT_FEED|ARC_FEED|SELECT_PLANE|SET_FEED_RATE|"
                   r"SET_MOTION_CONTROL_MODE|SET_NAIVECAM_TOLERANCE|SET_G5X_OFFSET|SET_G92_OFFSET)\(([^)]*)\)")
_MODES = {"CANON_CONTINUOUS": "continuous", "CANON_EXACT_PATH": "exact_path", "CANON_EXACT_STOP": "exact_stop"}
# ARC_FEED(first_end, second_end, first_centre, second_centre, rotation, normal_end, a, b, c)
_PLANE_AXES = {"CANON_PLANE_XY": (0, 1, 2), "CANON_PLANE_XZ": (2, 0, 1), "CANON_PLANE_YZ": (1, 2, 0)}


def rs274_moves(path: Path) -> list[dict]:
    """One dict per canonical motion call: kind, end (x y z a b c), centre (x y z, NaN off-plane) and
    rotation of arcs, the feed rate and path-control state in force, and the work offset (the active
    G5x offset plus the G92 offset: machine = end + work; mm programs)."""
    path = path.resolve()
    out = subprocess.run([RS274, "-g", str(path)], capture_output=True, text=True, timeout=60,
                         cwd=path.parent).stdout
    moves, plane = [], _PLANE_AXES["CANON_PLANE_XY"]
    state = {"feed": 0.0, "mode": "continuous", "tol": 0.0, "merge": 0.0}
    g5x, g92 = np.zeros(6), np.zeros(6)
    for name, args in _CALL.findall(out):
        if name == "SET_G5X_OFFSET":  # printed for the active system whenever it takes effect
            g5x = np.array([float(v) for v in args.split(",")[1:]])
            continue
        if name == "SET_G92_OFFSET":
            g92 = np.array([float(v) for v in args.split(",")])
            continue
        if name == "SELECT_PLANE":
            plane = _PLANE_AXES[args.strip()]
            continue
        if name == "SET_FEED_RATE":
            state["feed"] = float(args)
            continue
        if name == "SET_MOTION_CONTROL_MODE":
            parts = [a.strip() for a in args.split(",")]
            state["mode"] = _MODES[parts[0]]
            state["tol"] = float(parts[1]) if len(parts) > 1 else 0.0
            continue
        if name == "SET_NAIVECAM_TOLERANCE":
            state["merge"] = float(args)
            continue
        vals = [float(v) for v in args.split(",")]
        move = dict(state, work=g5x + g92)
        if name != "ARC_FEED":
            move.update(kind="rapid" if name == "STRAIGHT_TRAVERSE" else "linear", end=np.array(vals[:6]),
                        centre=None, rotation=0)
        else:
            end = np.zeros(6)
            centre = np.full(3, np.nan)
            u, v, w = plane
            end[u], end[v], end[w] = vals[0], vals[1], vals[5]
            end[3:] = vals[6:9]
            centre[u], centre[v] = vals[2], vals[3]
            move.update(kind="arc", end=end, centre=centre, rotation=int(vals[4]))
        moves.append(move)
    return moves


def assert_same_as_rs274(path: Path, tol: float = 2e-4) -> int:
    ref = rs274_moves(path)
    ours = load_program(path).motion
    assert len(ours) == len(ref), f"{len(ours)} motion blocks, rs274 has {len(ref)}"
    ends = ours[["x_mm", "y_mm", "z_mm", "a_deg", "b_deg", "c_deg"]].to_numpy()
    for k, mv in enumerate(ref):
        row = ours.iloc[k]
        assert np.allclose(ends[k], mv["end"], atol=tol), (k, ends[k], mv["end"])
        work = row[["wx_mm", "wy_mm", "wz_mm", "wa_deg", "wb_deg", "wc_deg"]].to_numpy(dtype=float)
        assert np.allclose(work, mv["work"], atol=tol), (k, work, mv["work"])
        if mv["kind"] == "arc":
            sign = 1 if row.kind == "arc_ccw" else -1
            assert sign * int(row.turns) == mv["rotation"], (k, row.kind, row.turns, mv["rotation"])
            c = row[["cx_mm", "cy_mm", "cz_mm"]].to_numpy(dtype=float)
            known = ~np.isnan(mv["centre"])
            assert np.allclose(c[known], mv["centre"][known], atol=tol), (k, c, mv["centre"])
        else:
            assert row.kind == mv["kind"], (k, row.kind, mv["kind"])
        if row.kind != "rapid" and not row.inverse_time:
            assert row.feed_mm_min == pytest.approx(mv["feed"], abs=1e-4), (k, row.feed_mm_min, mv["feed"])
        assert row.path_mode == mv["mode"], (k, row.path_mode, mv["mode"])
        if mv["mode"] == "continuous":  # LinuxCNC prints 0 for G64 without P
            assert np.nan_to_num(row.tol_mm) == pytest.approx(mv["tol"], abs=1e-6), (k, row.tol_mm, mv["tol"])
            assert np.nan_to_num(row.merge_tol_mm) == pytest.approx(mv["merge"], abs=1e-4), k
    return len(ref)


# examples/fiveaxis_cl_ijk.ngc is CL data (I J K orientation on G1), which LinuxCNC does not accept
# (drill_row.ngc is a subroutine file of drill_pattern.ngc: no motion of its own)
LINUXCNC_PROGRAMS = sorted(SHARED / n for n in SHARED_PROGRAMS) + sorted(p for p in (ROOT / "examples").glob("*.ngc")
                                                          if "_cl_" not in p.name and p.name != "drill_row.ngc")
# the recorded five-axis programs that set a work offset (G10 L2 P1 ... G54)
OFFSET_PROGRAMS = sorted((ROOT / "recordings" / "programs").glob("*offset*.ngc"))


@pytest.mark.parametrize("path", LINUXCNC_PROGRAMS, ids=lambda p: p.name)
def test_programs_match_linuxcnc_interpreter(path):
    assert assert_same_as_rs274(path) > 0


@pytest.mark.parametrize("path", OFFSET_PROGRAMS, ids=lambda p: p.name)
def test_offset_programs_match_linuxcnc_interpreter(path):
    assert assert_same_as_rs274(path) > 0
    program = parse_program(path)
    assert program.motion["wx_mm"].abs().max() > 0  # the offset is really there


def test_offset_programs_are_shipped():
    assert len(OFFSET_PROGRAMS) >= 3


@st.composite
def offset_mixes(draw):
    """Moves in G90/G91 between G10 L2/L20 (P0-P9, some axes), G54-G59.3 selections, G92 and G92.1."""
    systems = ["G54", "G55", "G56", "G57", "G58", "G59", "G59.1", "G59.2", "G59.3"]
    lines = ["G21 G90 G94 F600", "G0 X1 Y2 Z3"]
    num = st.integers(-500, 500).map(lambda v: f"{v / 10:.1f}")
    for _ in range(draw(st.integers(1, 10))):
        axes = draw(st.lists(st.sampled_from("XYZAC"), min_size=1, max_size=3, unique=True))
        words = " ".join(f"{a}{draw(num)}" for a in axes)
        op = draw(st.sampled_from(["L2", "L20", "select", "G92", "G92.1", "move", "move"]))
        if op in ("L2", "L20"):
            lines.append(f"G10 {op} P{draw(st.integers(0, 9))} {words}")
        elif op == "select":
            lines.append(draw(st.sampled_from(systems)))
        elif op == "G92":
            lines.append(f"G92 {words}")
        elif op == "G92.1":
            lines.append("G92.1")
        else:
            lines.append(f"{draw(st.sampled_from(['G90', 'G91']))} {draw(st.sampled_from(['G0', 'G1']))} {words}")
    lines.append("G90 G1 X0")
    return "\n".join(lines + ["M2"]) + "\n"


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(offset_mixes())
def test_random_offset_programs_match_linuxcnc_interpreter(tmp_path, text):
    path = tmp_path / "offsets.ngc"
    path.write_text(text)
    assert_same_as_rs274(path)


@st.composite
def arc_mixes(draw):
    """A few moves mixing planes, arc formats, distance modes and arc-centre modes (mm, 4 decimals)."""
    lines = ["G21 G90 G91.1 G17 G94 F500", "G0 X0 Y0 Z0"]
    pos = np.zeros(3)
    absolute_ijk = False
    for _ in range(draw(st.integers(1, 6))):
        plane = draw(st.sampled_from([17, 18, 19]))
        u, v, w = {17: (0, 1, 2), 18: (2, 0, 1), 19: (1, 2, 0)}[plane]
        r = draw(st.integers(1, 400)) / 10
        a0 = draw(st.floats(0, 2 * math.pi))
        a1 = draw(st.floats(0, 2 * math.pi))
        centre = pos.copy()
        centre[u] -= r * math.cos(a0)
        centre[v] -= r * math.sin(a0)
        end = pos.copy()
        end[u] = round(centre[u] + r * math.cos(a1), 4)
        end[v] = round(centre[v] + r * math.sin(a1), 4)
        end[w] = round(pos[w] + draw(st.integers(-50, 50)) / 10, 4)
        g = draw(st.sampled_from(["G2", "G3"]))
        incremental = draw(st.booleans())
        target = end - pos if incremental else end
        words = [f"G{plane}", "G91" if incremental else "G90", g]
        words += [f"{'XYZ'[i]}{target[i]:.4f}" for i in range(3)]
        chord = math.hypot(end[u] - pos[u], end[v] - pos[v])
        if draw(st.booleans()) and chord > 0.5 and chord < 2 * r - 0.01:
            # radius format: the same circle; sign picks the side
            sweep = ((a1 - a0) if g == "G3" else (a0 - a1)) % (2 * math.pi)
            words.append(f"R{r if sweep <= math.pi else -r:.4f}")
        else:
            absolute_ijk = draw(st.booleans())
            words.insert(0, "G90.1" if absolute_ijk else "G91.1")
            c = centre if absolute_ijk else centre - pos
            words += [f"{'IJK'[u]}{c[u]:.4f}", f"{'IJK'[v]}{c[v]:.4f}"]
        if draw(st.booleans()):
            words.append(f"F{draw(st.integers(1, 5000))}")
        if draw(st.booleans()):  # own line: P on an arc line means turns
            lines.append(draw(st.sampled_from(["G61", "G61.1", "G64", "G64 P0.02", "G64 P0.1 Q0",
                                               "G64 P0.005 Q0.003"])))
        lines.append(" ".join(words))
        pos = end
        if draw(st.booleans()):
            lines.append(f"G90 G1 X{pos[0] + 1:.4f}")
            pos[0] += 1
    return "\n".join(lines + ["M2"]) + "\n"


@settings(max_examples=25, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(arc_mixes())
def test_random_arc_programs_match_linuxcnc_interpreter(tmp_path, text):
    path = tmp_path / "random.ngc"
    path.write_text(text)
    # rs274 prints 4 decimals; R arcs' centres are computed, so allow a little more there
    assert_same_as_rs274(path, tol=2e-3)
