"""Recordings with a hidden effect: a program simulated on a changed machine, measured like a logger.

`hidden(name, values=..., ...)` simulates the bundled programs on the shipped profile changed by
`values` (dotted profile keys) or `mechanisms`, measures them (noise, quantisation, rest before and
after) and attaches the *unchanged* profile, as a user who does not know about the change would.
Recordings are cached per session, so several tests share one set.
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest

from feedlog.diagnose.keys import with_values
from feedlog.ingest.recording import PROFILE_ATTACHMENT
from feedlog.profile import load_profile
from feedlog.sim import MeasurementModel, measure, simulate
from feedlog.toolpath import parse_program

ROOT = Path(__file__).resolve().parents[2]
PROGRAMS = ROOT / "recordings" / "programs"
PAIR = ("corners_f3000_p001", "pocket_f3000_p001")


def slower_after_arcs(text: str) -> str:
    """A structural effect no hypothesis covers: every arc sets the feed to 70 % (and the moves after it
    keep that feed), in one program only."""
    return re.sub(r"^(G[23] .*)$", r"\1 F2100", text, flags=re.M)


def make_hidden(name: str, *, values=None, mechanisms=None, programs=PAIR, rate_hz: float = 1000.0,
                base: str = "linuxcnc-xyz", edit=None, seed: int = 0, program_edit=None, texts=None):
    """`edit` changes what the machine ran in the last program only (the attached program stays as
    written); `program_edit` changes every program, run and attached alike; `texts` (name -> G-code)
    gives programs that are not bundled."""
    truth = with_values(load_profile(base), values) if values else load_profile(base)
    recordings = []
    for i, program in enumerate(programs):
        if isinstance(program, tuple):   # (name, G-code text) for a program made by the test
            program, text = program
        else:                            # a bundled program's name, or one `texts` gives
            text = texts[program] if texts and program in texts else (PROGRAMS / f"{program}.ngc").read_text()
        text = program_edit(text) if program_edit is not None else text
        run = edit(text) if edit is not None and i == len(programs) - 1 else text
        result = simulate(parse_program(run, name=program), truth, mechanisms=mechanisms)
        # standstill before and after: a few samples at rest at either rate (a 5 Hz logger needs seconds)
        rest = 0.5 if rate_hz >= 50 else 2.0
        model = MeasurementModel(rate_hz=rate_hz, noise_mm=0.002, quantum_mm=0.001, rest_s=rest, seed=seed + i)
        rec = measure(result, model, program_text=text)
        rec.attachments[PROFILE_ATTACHMENT] = load_profile(base).to_toml().encode()
        rec.source = f"{name}_{program}.mcap"
        recordings.append(rec)
    return recordings


def drilling(holes: int) -> str:
    """A drilling pattern of `holes` holes, four to a row 30 mm apart: XY rapids between the holes, Z
    rapids in and out, each hole at F600 (a program of many rapids: the rapid dial acts on most of it)."""
    lines = ["G21 G90 G64 P0.01", "G0 X0 Y0 Z20"]
    for i in range(holes):
        lines += [f"G0 X{30 * (i % 4)} Y{30 * (i // 4)}", "G0 Z2", "G1 Z-3 F600", "G0 Z20"]
    return "\n".join(lines + ["M2"]) + "\n"


_CACHE: dict = {}


@pytest.fixture(scope="session")
def hidden():
    def get(name: str, **kwargs):
        if name not in _CACHE:
            _CACHE[name] = make_hidden(name, **kwargs)
        return _CACHE[name]
    return get
