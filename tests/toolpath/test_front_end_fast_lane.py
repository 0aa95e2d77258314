"""The Fanuc and Sinumerik front-ends' fast lane (plain G0/G1 blocks straight to the machine model) gives
exactly the rows (or the error) of their general path: random programs of both fuzz grammars and the
bundled real programs, run both ways."""

from __future__ import annotations

from pathlib import Path

import pandas as pd
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from feedlog.errors import ProgramError
from feedlog.toolpath.interp import InterpOptions
from feedlog.toolpath.interp.fanuc import FanucInterpreter, interpret_fanuc
from feedlog.toolpath.interp.sinumerik import SinumerikInterpreter, interpret_sinumerik

from .test_fanuc_macro import _STATEMENTS
from .test_sinumerik import _FUZZ_SUBS, _programs

ROOT = Path(__file__).resolve().parents[2]
MOVES = ["G0 X1 Y2", "G1 X[#1 * 2] F200", "X3 Y-1", "G1 Z#2", "G0 A10", "F50", "Y#1", "G91 X1", "G90 G1 X0"]


def _both(run, cls, monkeypatch):
    """(table or error text) with the fast lane, then without it."""
    out = []
    for fast in (True, False):
        with monkeypatch.context() as mp:
            if not fast:
                mp.setattr(cls, "_fast", lambda self, *a: False)
            try:
                p = run()
                out.append((p.blocks, list(p.warnings)))
            except ProgramError as exc:
                out.append(str(exc))
    return out


def _assert_same(a, b):
    if isinstance(a, str) or isinstance(b, str):
        assert a == b
        return
    pd.testing.assert_frame_equal(a[0], b[0])
    assert a[1] == b[1]


@settings(max_examples=120, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(st.lists(st.sampled_from(_STATEMENTS + MOVES * 2), max_size=16))
def test_fanuc_fast_lane_is_the_general_path(monkeypatch, main):
    text = "\n".join(["G21 F100", "#1 = 1", "#2 = -2"] + main + ["M30", "O200", "G1 X5", "M99", "O300",
                                                                 "G0 X#1", "M99"]) + "\n"
    fast, slow = _both(lambda: interpret_fanuc(text, name="p.nc", options=InterpOptions(max_blocks=2000)),
                       FanucInterpreter, monkeypatch)
    _assert_same(fast, slow)


@settings(max_examples=120, deadline=None, derandomize=True,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much,
                                 HealthCheck.function_scoped_fixture])
@given(_programs())
def test_sinumerik_fast_lane_is_the_general_path(monkeypatch, lines):
    text = "G1 F100\nG0 X1 Y2\nG1 X=R1*2 Y=IC(1)\nX=AC(3)\n" + "\n".join(lines) + "\n"
    fast, slow = _both(lambda: interpret_sinumerik(text, name="main.mpf", max_blocks=2000,
                                                   subprograms=_FUZZ_SUBS), SinumerikInterpreter, monkeypatch)
    _assert_same(fast, slow)


@pytest.mark.parametrize("path", sorted((ROOT / "tests" / "fixtures" / "ingest").rglob("*.nc"))
                         + sorted((ROOT / "tests" / "fixtures" / "ingest").rglob("*.NC"))
                         + sorted((ROOT / "tests" / "fixtures" / "ingest").rglob("*.mpf")), ids=lambda p: p.name)
def test_real_programs_run_alike_both_ways(monkeypatch, path):
    if path.suffix == ".mpf":
        fast, slow = _both(lambda: interpret_sinumerik(path), SinumerikInterpreter, monkeypatch)
    else:
        fast, slow = _both(lambda: interpret_fanuc(path), FanucInterpreter, monkeypatch)
    _assert_same(fast, slow)
    assert not isinstance(fast, str) or "line" in fast
